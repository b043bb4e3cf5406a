//! Stereo rendering of simulation snapshots with wgpu on Vulkan.
//!
//! The renderer draws into whatever target it is handed: a 2-layer texture array (the XR
//! swapchain image, a headless test texture) in one multiview pass, or, where the adapter lacks
//! multiview, one view per eye in two passes. Organ vertex buffers are rewritten from each
//! snapshot in place and grow only when a cut adds render vertices beyond their headroom.
//! Each pass draws the opaque surfaces first, then the translucent ones: membranes, then
//! smoke (`pipelines`, `smoke`).

mod blood;
pub mod camera;
mod draw;
/// The operative field is described in the core ([`crate::sim::field`]); drawn here.
pub use crate::sim::field;
pub mod frames;
/// The one wgpu device, a leaf below the renderer (models may share it for compute).
pub use crate::gpu;
mod meshes;
pub mod monitor;
pub mod optics;
pub mod overlay;
mod pipelines;
pub mod smoke;

use meshes::{empty_mesh, ensure_capacity, tracked_buffer, upload};

pub use crate::gpu::{EyeTarget, Gpu, RenderError, RenderTarget};
pub use camera::{EyeView, Fov};

use crate::profiler::{Category, Ledger, Tracked};
use crate::sim::{Emission, ScopeView, Snapshot, SurfaceRole, ToolSnapshot};
use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use std::sync::Arc;

/// 16-bit depth: at 0.2 m from the eye with the near plane at 1 cm it resolves 0.06 mm, and it
/// halves the depth buffer of a 2 x 1080 x 1200 target (5.2 MB).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth16Unorm;
/// Background: the dim, warm cavity a laparoscope sees.
pub const BACKGROUND: [f64; 3] = [0.02, 0.012, 0.01];
/// Alpha of membrane surfaces ([`SurfaceRole::Membrane`]). Papers that draw membranes
/// see-through give no value. At 0.5 one membrane shows what lies behind it at half strength
/// and stays plainly a surface; two over each other let a quarter through, enough to see an
/// organ and an instrument behind them.
pub const MEMBRANE_ALPHA: f32 = 0.5;

/// A laser beam's radius over its distance from the eyes (0.4 degrees across, all along: 4
/// pixels of a Vive's eye, where a constant 0.4 mm radius made a cone 4.6 degrees wide at the
/// 1 cm the desktop laser leaves below the eye), and the least radius it is drawn with, metres.
const BEAM_WIDTH_RAD: f32 = 0.0035;
const BEAM_MIN_RADIUS_M: f32 = 0.0001;

/// Material slots (the shader's table; it holds up to 16).
pub mod material {
    pub const TISSUE: u32 = 0;
    pub const TARGET: u32 = 1;
    pub const ARTERY: u32 = 2;
    pub const VEIN: u32 = 3;
    pub const DUCT: u32 = 4;
    pub const INSTRUMENT: u32 = 5;
    pub const LASER_ON: u32 = 6;
    pub const LASER_IDLE: u32 = 7;
    pub const FAT: u32 = 8;
    pub const MEMBRANE: u32 = 9;
    pub const WALL: u32 = 10;
    pub const VISCUS: u32 = 11;
    pub const SAC: u32 = 12;
    /// Set on vertices at the edge of a cut.
    pub const CUT_FLAG: u32 = 256;
    /// Set on vertices an energy instrument seared (drawn charred).
    pub const SEAR_FLAG: u32 = 512;
    pub const COUNT: usize = 13;
    /// The shader's table length.
    pub const SLOTS: usize = 16;
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    material: u32,
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct EyeUniform {
    view_proj: [[f32; 4]; 4],
    position: [f32; 4],
    /// The eye's line of sight (the scope light's axis).
    forward: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    eyes: [EyeUniform; 2],
    flags: [f32; 4],
    /// [`optics::Optics::uniform`].
    optics: [f32; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct MaterialUniform {
    albedo: [f32; 4],
    shading: [f32; 4],
    surface: [f32; 4],
}

fn material_table() -> [MaterialUniform; material::SLOTS] {
    // Colour as it looks on screen (sRGB), shaded in linear light; specular strength,
    // shininess, emissive, rim (wet sheen at grazing angles); mottle (albedo variation),
    // vessels (a fine red network), bump (relief of the normal), scale (noise features per
    // metre).
    let linear = |c: f32| {
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let m = |[r, g, b]: [f32; 3], [spec, shin, emit, rim]: [f32; 4], surface: [f32; 4]| {
        MaterialUniform {
            albedo: [linear(r), linear(g), linear(b), 1.0],
            shading: [spec, shin, emit, rim],
            surface,
        }
    };
    let none = [0.0, 0.0, 0.0, 1.0];
    let unused = m([0.0; 3], [0.0, 1.0, 0.0, 0.0], none);
    [
        // tissue (parenchyma)
        m(
            [0.58, 0.18, 0.14],
            [0.35, 60.0, 0.0, 0.10],
            [0.30, 0.25, 0.35, 250.0],
        ),
        // target (a pale, firm mass)
        m(
            [0.86, 0.72, 0.50],
            [0.30, 50.0, 0.0, 0.08],
            [0.35, 0.15, 0.60, 300.0],
        ),
        m(
            [0.74, 0.13, 0.10],
            [0.50, 80.0, 0.0, 0.12],
            [0.15, 0.0, 0.10, 400.0],
        ), // artery
        m(
            [0.30, 0.23, 0.52],
            [0.50, 80.0, 0.0, 0.12],
            [0.15, 0.0, 0.10, 400.0],
        ), // vein
        m(
            [0.88, 0.78, 0.64],
            [0.35, 60.0, 0.0, 0.08],
            [0.15, 0.20, 0.15, 400.0],
        ), // duct
        m([0.66, 0.68, 0.71], [0.90, 90.0, 0.0, 0.20], none), // instrument steel
        m([0.50, 1.00, 0.58], [0.00, 1.0, 2.0, 0.00], none),  // laser, cutting
        m([0.35, 0.74, 0.42], [0.00, 1.0, 0.8, 0.00], none),  // laser, aiming
        // fat: lobules
        m(
            [0.94, 0.80, 0.42],
            [0.30, 40.0, 0.0, 0.06],
            [0.30, 0.10, 0.70, 350.0],
        ),
        // membrane (thin, glossy)
        m(
            [0.90, 0.78, 0.74],
            [0.60, 70.0, 0.0, 0.25],
            [0.20, 0.30, 0.15, 300.0],
        ),
        // wall: peritoneum over the body wall, pale pink with fine vessels
        m(
            [0.82, 0.55, 0.52],
            [0.45, 60.0, 0.0, 0.15],
            [0.35, 0.45, 0.30, 200.0],
        ),
        // viscus: serosa of bowel or stomach, salmon pink, glossy
        m(
            [0.88, 0.58, 0.50],
            [0.55, 70.0, 0.0, 0.18],
            [0.25, 0.40, 0.25, 160.0],
        ),
        // sac: a thin, glossy wall over dark green-grey contents, fine vessels on it
        m(
            [0.47, 0.55, 0.36],
            [0.60, 80.0, 0.0, 0.22],
            [0.20, 0.30, 0.10, 300.0],
        ),
        unused,
        unused,
        unused,
    ]
}

/// The role of triangle `t` of a model (a region without a role is tissue).
fn triangle_role(m: &crate::sim::ModelSnapshot, t: usize) -> SurfaceRole {
    let region = m.regions.get(t).copied().unwrap_or(0) as usize;
    m.roles.get(region).copied().unwrap_or_default()
}

/// The material of a surface role.
fn role_material(role: SurfaceRole) -> u32 {
    match role {
        SurfaceRole::Tissue => material::TISSUE,
        SurfaceRole::Target => material::TARGET,
        SurfaceRole::Artery => material::ARTERY,
        SurfaceRole::Vein => material::VEIN,
        SurfaceRole::Duct => material::DUCT,
        SurfaceRole::Fat => material::FAT,
        SurfaceRole::Membrane => material::MEMBRANE,
        SurfaceRole::Wall => material::WALL,
        SurfaceRole::Viscus => material::VISCUS,
        SurfaceRole::Sac => material::SAC,
    }
}

/// Each vertex's material: that of the role of a triangle it belongs to (the last one).
fn vertex_materials(m: &crate::sim::ModelSnapshot) -> Vec<u32> {
    let mut out = vec![material::TISSUE; m.positions.len()];
    for (t, tri) in m.indices.chunks_exact(3).enumerate() {
        let base = role_material(triangle_role(m, t));
        for &i in tri {
            if let Some(v) = out.get_mut(i as usize) {
                *v = base;
            }
        }
    }
    out
}

struct GpuMesh {
    vertex: Tracked<wgpu::Buffer>,
    index: Tracked<wgpu::Buffer>,
    vertex_count: u32,
    index_count: u32,
    /// Indices before this draw opaque triangles; from it on, membranes (translucent).
    opaque_count: u32,
}

struct Depth {
    size: (u32, u32),
    _texture: Tracked<wgpu::Texture>,
    array: wgpu::TextureView,
    layers: [wgpu::TextureView; 2],
}

pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    ledger: Arc<Ledger>,
    multiview: bool,
    pipelines: pipelines::Pipelines,
    frame_buffers: Vec<Tracked<wgpu::Buffer>>,
    bind_groups: Vec<wgpu::BindGroup>,
    materials: Tracked<wgpu::Buffer>,
    meshes: Vec<GpuMesh>,
    /// The operative field around the models: static, drawn first.
    field: Option<GpuMesh>,
    optics: optics::Optics,
    /// The headset's text panel, made when first asked to show words.
    overlay: Option<overlay::Overlay>,
    /// The operating room's monitor, where the headset shows one: the scene is drawn into
    /// its picture, and the eyes see the screen.
    monitor: Option<monitor::Monitor>,
    /// The snapshot's laparoscope, where a hand drives it (the monitor's picture follows).
    scope: Option<ScopeView>,
    /// The procedure's own picture in the snapshot (a fluoroscope's): a monitor shows it.
    picture: Option<Arc<crate::imaging::fluoro::Picture>>,
    instruments: GpuMesh,
    depth: Option<Depth>,
    format: wgpu::TextureFormat,
    frame: u64,
    scratch: Vec<Vertex>,
    scratch_idx: Vec<u32>,
    tools: [ToolSnapshot; 2],
    /// The snapshot's emissions and time, drawn as smoke once the eyes are known.
    emissions: Vec<Emission>,
    /// The snapshot's bleeding sources, drawn as blood with the smoke.
    bleeds: Vec<crate::sim::Bleed>,
    time_s: f64,
    smoke: smoke::SmokeBuffer,
    objects: u64,
    flags: [f32; 4],
}

fn uniform_bytes() -> u64 {
    std::mem::size_of::<FrameUniform>() as u64
}

/// `passes` frame uniforms, each bound with the material table.
fn frame_bind_groups(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    layout: &wgpu::BindGroupLayout,
    materials: &wgpu::Buffer,
    passes: usize,
) -> (Vec<Tracked<wgpu::Buffer>>, Vec<wgpu::BindGroup>) {
    let buffers: Vec<Tracked<wgpu::Buffer>> = (0..passes)
        .map(|_| {
            tracked_buffer(
                device,
                ledger,
                "frame",
                uniform_bytes(),
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                Category::Material,
            )
        })
        .collect();
    let groups = buffers
        .iter()
        .map(|fb| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("frame"),
                layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: fb.inner.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: materials.as_entire_binding(),
                    },
                ],
            })
        })
        .collect();
    (buffers, groups)
}

impl Renderer {
    /// A renderer for targets of `format` on `gpu`'s device; multiview when the device has it.
    /// An error names a shader that does not compile.
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat) -> Result<Self, RenderError> {
        Self::with_multiview(gpu, format, gpu.multiview)
    }

    /// A renderer that draws one view per pass even on a multiview device (a desktop view
    /// beside the headset's), or both eyes in one pass where `multiview` and the device allow.
    pub fn with_multiview(
        gpu: &Gpu,
        format: wgpu::TextureFormat,
        multiview: bool,
    ) -> Result<Self, RenderError> {
        let device = gpu.device.clone();
        let multiview = multiview && gpu.multiview;
        let pipelines = pipelines::Pipelines::new(&device, format, multiview)?;
        let ledger = gpu.ledger.clone();
        let table = material_table();
        let materials = tracked_buffer(
            &device,
            &ledger,
            "materials",
            std::mem::size_of_val(&table) as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            Category::Material,
        );
        gpu.queue
            .write_buffer(&materials, 0, bytemuck::cast_slice(&table));
        let passes = if multiview { 1 } else { 2 };
        let (frame_buffers, bind_groups) =
            frame_bind_groups(&device, &ledger, &pipelines.layout, &materials, passes);
        let instruments = empty_mesh(&device, &ledger, 512, 1024);
        let smoke = smoke::SmokeBuffer::new(&device, &ledger);
        Ok(Renderer {
            device,
            queue: gpu.queue.clone(),
            ledger,
            multiview,
            pipelines,
            frame_buffers,
            bind_groups,
            materials,
            meshes: Vec::new(),
            field: None,
            optics: optics::Optics::default(),
            overlay: None,
            monitor: None,
            scope: None,
            picture: None,
            instruments,
            depth: None,
            format,
            frame: 0,
            scratch: Vec::new(),
            scratch_idx: Vec::new(),
            tools: Default::default(),
            emissions: Vec::new(),
            bleeds: Vec::new(),
            time_s: 0.0,
            smoke,
            objects: 0,
            flags: [0.0; 4],
        })
    }

    pub fn multiview(&self) -> bool {
        self.multiview
    }

    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// The static operative field drawn around the snapshot's models (`None`: none), uploaded
    /// once; only its opaque triangles are drawn.
    pub fn set_field(&mut self, field: Option<&crate::sim::ModelSnapshot>) {
        self.field = field.map(|m| {
            let mut mesh = empty_mesh(&self.device, &self.ledger, 0, 0);
            let materials = vertex_materials(m);
            let verts: Vec<Vertex> = m
                .positions
                .iter()
                .zip(materials)
                .enumerate()
                .map(|(i, (p, material))| Vertex {
                    position: p.to_array(),
                    normal: m.normals.get(i).copied().unwrap_or(Vec3::Y).to_array(),
                    material,
                })
                .collect();
            upload(
                &self.device,
                &self.queue,
                &self.ledger,
                &mut mesh,
                &verts,
                &m.indices,
            );
            mesh
        });
    }

    /// How the picture is formed from the next frame on: the light and the image circle.
    pub fn set_optics(&mut self, optics: optics::Optics) {
        self.optics = optics;
    }

    pub fn optics(&self) -> optics::Optics {
        self.optics
    }

    /// The monitor's picture and its size, where
    /// the eyes see a monitor: what a desktop mirror shows instead of an eye.
    pub fn monitor_picture(&self) -> Option<(&wgpu::Texture, (u32, u32))> {
        self.monitor.as_ref().map(|m| (&*m.texture, m.spec.pixels))
    }

    /// From the next frame on, the eyes see a monitor showing the scope's picture (`None`:
    /// the scene itself, as before). An error names a shader that does not compile.
    pub fn set_monitor(&mut self, spec: Option<monitor::MonitorSpec>) -> Result<(), RenderError> {
        self.monitor = match spec {
            None => None,
            Some(spec) => {
                let parts = monitor::Parts {
                    device: &self.device,
                    queue: &self.queue,
                    ledger: &self.ledger,
                    format: self.format,
                    materials: &self.materials,
                    quad_layout: &self.pipelines.overlay_layout,
                };
                Some(monitor::Monitor::new(parts, spec)?)
            }
        };
        Ok(())
    }

    /// Words to show in a panel before the eyes from the next frame on (the newest first;
    /// none: no panel). The panel is painted again only when they change.
    pub fn show_lines(&mut self, lines: &[String]) {
        if lines.is_empty() && self.overlay.is_none() {
            return;
        }
        let (device, ledger) = (&self.device, &self.ledger);
        let layout = &self.pipelines.overlay_layout;
        self.overlay
            .get_or_insert_with(|| overlay::Overlay::new(device, ledger, layout))
            .set_lines(&self.device, &self.queue, lines);
    }

    /// Copies a snapshot's geometry into the GPU buffers (in place while it fits).
    pub fn update(&mut self, snap: &Snapshot) {
        while self.meshes.len() < snap.models.len() {
            self.meshes
                .push(empty_mesh(&self.device, &self.ledger, 0, 0));
        }
        self.meshes.truncate(snap.models.len());
        for (k, m) in snap.models.iter().enumerate() {
            let vertex_material = vertex_materials(m);
            // Vertices go straight into wgpu's staging memory: no CPU copy of the mesh is kept.
            let mesh = &mut self.meshes[k];
            let vsize = (m.positions.len() * std::mem::size_of::<Vertex>()) as u64;
            let isize = std::mem::size_of_val(&m.indices[..]) as u64;
            ensure_capacity(&self.device, &self.ledger, mesh, vsize, isize);
            if let Some(size) = wgpu::BufferSize::new(vsize)
                && let Some(mut view) = self.queue.write_buffer_with(&mesh.vertex, 0, size)
            {
                // Built 512 vertices at a time in a small reused buffer.
                const CHUNK: usize = 512;
                let stride = std::mem::size_of::<Vertex>();
                for start in (0..m.positions.len()).step_by(CHUNK) {
                    let end = (start + CHUNK).min(m.positions.len());
                    self.scratch.clear();
                    for i in start..end {
                        let cut = m.cut_edge.get(i).copied().unwrap_or(false);
                        let seared = m.seared.get(i).copied().unwrap_or(false);
                        self.scratch.push(Vertex {
                            position: m.positions[i].to_array(),
                            normal: m.normals.get(i).copied().unwrap_or(Vec3::Y).to_array(),
                            material: vertex_material[i]
                                | if cut { material::CUT_FLAG } else { 0 }
                                | if seared { material::SEAR_FLAG } else { 0 },
                        });
                    }
                    view.slice(start * stride..end * stride)
                        .copy_from_slice(bytemuck::cast_slice(&self.scratch));
                }
            }
            // Membranes' triangles go after the opaque ones, to be drawn in the translucent
            // part of the pass; a model with none is written as it comes.
            let translucent = |t: usize| triangle_role(m, t) == SurfaceRole::Membrane;
            let triangles = m.indices.len() / 3;
            let indices: &[u32] =
                if m.roles.contains(&SurfaceRole::Membrane) && (0..triangles).any(translucent) {
                    self.scratch_idx.clear();
                    for pass in [false, true] {
                        for (t, tri) in m.indices.chunks_exact(3).enumerate() {
                            if translucent(t) == pass {
                                self.scratch_idx.extend_from_slice(tri);
                            }
                        }
                        if !pass {
                            mesh.opaque_count = self.scratch_idx.len() as u32;
                        }
                    }
                    &self.scratch_idx
                } else {
                    mesh.opaque_count = m.indices.len() as u32;
                    &m.indices
                };
            if !indices.is_empty() {
                self.queue
                    .write_buffer(&mesh.index, 0, bytemuck::cast_slice(indices));
            }
            mesh.vertex_count = m.positions.len() as u32;
            mesh.index_count = indices.len() as u32;
        }
        self.emissions.clone_from(&snap.emissions);
        self.bleeds.clone_from(&snap.bleeding);
        self.time_s = snap.time_s;
        self.scope = snap.scope;
        self.picture.clone_from(&snap.picture);
        // Instruments and beams are built per frame, clipped to the eyes (see `render`).
        self.tools = snap.tools;
        let tools = snap
            .tools
            .iter()
            .filter(|t| t.direction.length_squared() >= 0.5)
            .count() as u64;
        let beams = snap
            .tools
            .iter()
            .filter(|t| {
                t.direction.length_squared() >= 0.5 && (t.beam_end.or(t.beam_reach)).is_some()
            })
            .count() as u64;
        // Organs, instruments, beams, the headlight and the eye rig (and the smoke, counted
        // when it is drawn).
        self.objects = snap.models.len() as u64
            + u64::from(self.field.is_some())
            + u64::from(self.monitor.is_some())
            + tools
            + beams
            + 2;
        let flags = [
            if snap.target_found { 1.0 } else { 0.0 },
            snap.time_s as f32,
            MEMBRANE_ALPHA,
            0.0,
        ];
        self.flags = flags;
    }
}

/// The view-projection a renderer uses for an eye (for tests that project known points).
pub fn view_proj(e: &EyeView) -> Mat4 {
    e.view_proj()
}
