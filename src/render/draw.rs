//! A frame: the instruments built for the eyes, the uniforms written, and the passes encoded
//! and submitted. The scene is drawn straight into the eyes' target, or, where the headset
//! shows a monitor, into the monitor's picture first and then the eyes see the screen.

use super::meshes::{clip_to_eyes, cone, draw_range, instrument_parts, upload};
use super::pipelines::Pipelines;
use super::{
    BACKGROUND, BEAM_MIN_RADIUS_M, BEAM_WIDTH_RAD, DEPTH_FORMAT, Depth, EyeUniform, EyeView,
    FrameUniform, RenderTarget, Renderer, gpu, material,
};
use crate::profiler::{Category, FrameCounters};
use glam::Vec3;
use std::num::NonZeroU32;
use std::time::Instant;

impl Renderer {
    /// Instruments and laser beams as cylinders (a few hundred vertices), each cut where it
    /// passes behind the eyes' near plane. The GPU would clip those triangles too, but Mesa's
    /// lavapipe (22.3) draws near-plane-clipped triangles of the second view into the first
    /// layer of a multiview pass; a shaft held close to the face showed in the wrong eye.
    fn build_instruments(&mut self, eyes: &[EyeView; 2]) {
        self.scratch.clear();
        self.scratch_idx.clear();
        for t in &self.tools {
            if t.direction.length_squared() < 0.5 {
                continue;
            }
            let mut parts = Vec::with_capacity(6);
            instrument_parts(t, &mut parts);
            for (a, b, radii, m) in parts {
                let widest = radii[0].max(radii[1]);
                if let Some((ca, cb)) = clip_to_eyes(a, b, widest, eyes) {
                    // Clipped, the radii follow the cone.
                    let length = a.distance(b).max(1e-9);
                    let at = |p: Vec3| {
                        let u = (a.distance(p) / length).clamp(0.0, 1.0);
                        radii[0] + (radii[1] - radii[0]) * u
                    };
                    cone(
                        ca,
                        cb,
                        [at(ca), at(cb)],
                        m,
                        &mut self.scratch,
                        &mut self.scratch_idx,
                    );
                }
            }
            // The beam to what it hits, or to its range: a thin line of about the same width
            // on screen all along (its radius grows with the distance from the eyes).
            if let Some(end) = t.beam_end.or(t.beam_reach) {
                let m = if t.active {
                    material::LASER_ON
                } else {
                    material::LASER_IDLE
                };
                let mid = 0.5 * (eyes[0].position + eyes[1].position);
                let width = |p: Vec3| (BEAM_WIDTH_RAD * p.distance(mid)).max(BEAM_MIN_RADIUS_M);
                if let Some((a, b)) = clip_to_eyes(t.tip, end, BEAM_MIN_RADIUS_M, eyes) {
                    let radii = [width(a), width(b)];
                    cone(a, b, radii, m, &mut self.scratch, &mut self.scratch_idx);
                }
            }
        }
        let (verts, idx) = (
            std::mem::take(&mut self.scratch),
            std::mem::take(&mut self.scratch_idx),
        );
        upload(
            &self.device,
            &self.queue,
            &self.ledger,
            &mut self.instruments,
            &verts,
            &idx,
        );
        (self.scratch, self.scratch_idx) = (verts, idx);
    }

    fn ensure_depth(&mut self, size: (u32, u32)) {
        if self.depth.as_ref().is_some_and(|d| d.size == size) {
            return;
        }
        let (texture, array, layers) = gpu::eye_texture(
            &self.device,
            &self.ledger,
            "depth",
            size,
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        self.depth = Some(Depth {
            size,
            _texture: texture,
            array,
            layers,
        });
    }

    /// Draws the last updated snapshot for both eyes into `target` (each eye `size` pixels)
    /// and submits; with a monitor, the scene goes into the monitor's picture and the eyes
    /// see the screen. Returns the frame's counters (memory and CPU stage times filled in by
    /// the caller where it measures them).
    pub fn render(
        &mut self,
        target: RenderTarget<'_>,
        size: (u32, u32),
        eyes: &[EyeView; 2],
    ) -> FrameCounters {
        let _span = tracing::debug_span!("render_frame", width = size.0, height = size.1).entered();
        let t0 = Instant::now();
        self.ensure_depth(size);
        // A procedure's own picture goes on the monitor in place of the scope's scene.
        let own_picture = match (self.monitor.as_mut(), &self.picture) {
            (Some(m), Some(p)) => m.show_picture(&self.queue, p),
            (Some(m), None) => {
                m.forget_picture();
                false
            }
            _ => false,
        };
        // Where the scene is seen from: the eyes, or the scope whose picture the monitor shows.
        let (scene_eyes, scene_size, optics) = match &self.monitor {
            Some(m) => {
                let (e, o) = m.spec.scope(self.scope);
                (e, m.spec.pixels, o)
            }
            None => (*eyes, size, self.optics),
        };
        self.build_instruments(&scene_eyes);
        self.smoke.update(
            (&self.device, &self.queue, &self.ledger),
            (&self.emissions, &self.bleeds, self.time_s),
            &scene_eyes,
        );
        match &self.monitor {
            Some(m) => {
                // The picture in one view; the room's pass sees the eyes, with no light or
                // circle of its own.
                self.write_frame(
                    &m.frame_buffers,
                    false,
                    &scene_eyes,
                    optics.uniform(scene_size),
                );
                let room = [0.0, 0.0, size.0 as f32, size.1 as f32];
                self.write_frame(&self.frame_buffers, self.multiview, eyes, room);
            }
            None => self.write_frame(
                &self.frame_buffers,
                self.multiview,
                &scene_eyes,
                optics.uniform(scene_size),
            ),
        }
        let overlay = self.overlay.as_ref().filter(|o| o.visible());
        if let Some(o) = overlay {
            o.place(&self.queue, eyes);
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        let mut c = FrameCounters {
            frame: self.frame,
            multiview: self.multiview,
            ..Default::default()
        };
        let Some(depth) = self.depth.as_ref() else {
            return c;
        };
        let passes = eye_passes(&target, self.multiview, depth);
        let frame = |k: usize| &self.bind_groups[k.min(self.bind_groups.len() - 1)];
        match &self.monitor {
            Some(m) => {
                // Outside the image circle the monitor's picture is black. A procedure's own
                // picture is on the screen already (written in before the frame).
                if !own_picture {
                    let picture = (&m.view, &m.depth, None);
                    let scene = (&m.pipelines, &m.bind_groups[0]);
                    self.scene_pass(&mut encoder, picture, scene, [0.0; 3], &mut c);
                }
                for (k, p) in passes.into_iter().enumerate() {
                    let mut pass = begin(&mut encoder, p, super::monitor::ROOM, "room");
                    c.passes += 1;
                    m.draw(&mut pass, &self.pipelines.overlay, frame(k), &mut c);
                    if let Some(o) = overlay {
                        o.draw(&mut pass, &self.pipelines.overlay, frame(k), &mut c);
                    }
                }
            }
            None => {
                // Outside a monitor image's circle the picture is black; without a circle the
                // void shows the cavity's dim colour (scenes with no field).
                let clear = if self.optics.circle.is_some() {
                    [0.0; 3]
                } else {
                    BACKGROUND
                };
                for (k, p) in passes.into_iter().enumerate() {
                    let scene = (&self.pipelines, frame(k));
                    let mut pass = self.scene_pass(&mut encoder, p, scene, clear, &mut c);
                    if let Some(o) = overlay {
                        o.draw(&mut pass, &self.pipelines.overlay, frame(k), &mut c);
                    }
                }
            }
        }
        c.batches = c.draw_calls;
        let t1 = Instant::now();
        self.queue.submit([encoder.finish()]);
        let t2 = Instant::now();
        c.cpu.render_encode_ms = (t1 - t0).as_secs_f64() * 1e3;
        c.cpu.submit_ms = (t2 - t1).as_secs_f64() * 1e3;
        c.textures = self.ledger.live(Category::Texture);
        c.meshes = self.ledger.live(Category::Mesh);
        c.materials = self.ledger.live(Category::Material);
        c.materials.count = material::COUNT as u64;
        c.vram_bytes = self.ledger.total_bytes();
        c.total_memory_bytes = crate::profiler::heap_bytes() + c.vram_bytes;
        c.objects = self.objects + u64::from(self.smoke.count() > 0);
        self.frame += 1;
        c
    }

    /// A frame's counters when nothing is drawn (a procedure's own picture covers the view):
    /// what the renderer holds on the device and in memory, no draw calls.
    pub fn idle_counters(&self) -> FrameCounters {
        let vram_bytes = self.ledger.total_bytes();
        let mut materials = self.ledger.live(Category::Material);
        materials.count = material::COUNT as u64;
        FrameCounters {
            textures: self.ledger.live(Category::Texture),
            meshes: self.ledger.live(Category::Mesh),
            materials,
            vram_bytes,
            total_memory_bytes: crate::profiler::heap_bytes() + vram_bytes,
            ..FrameCounters::default()
        }
    }

    /// Writes the frame uniform of each pass: both eyes in one (`multiview`), or one buffer
    /// per eye's pass with that eye first.
    fn write_frame(
        &self,
        buffers: &[crate::profiler::Tracked<wgpu::Buffer>],
        multiview: bool,
        eyes: &[EyeView; 2],
        optics: [f32; 4],
    ) {
        let eye_uniform = |e: &EyeView| EyeUniform {
            view_proj: e.view_proj().to_cols_array_2d(),
            position: e.position.extend(1.0).to_array(),
            forward: (e.orientation * Vec3::NEG_Z).extend(0.0).to_array(),
        };
        let both = [eye_uniform(&eyes[0]), eye_uniform(&eyes[1])];
        for (k, fb) in buffers.iter().enumerate() {
            let u = FrameUniform {
                eyes: if multiview {
                    both
                } else {
                    [both[k.min(1)], both[k.min(1)]]
                },
                flags: self.flags,
                optics,
            };
            self.queue.write_buffer(fb, 0, bytemuck::bytes_of(&u));
        }
    }

    /// One pass of the scene with `pipelines` and their frame bind group: opaque surfaces,
    /// then membranes and smoke blended over them. The pass is handed back for anything to be
    /// drawn over it.
    fn scene_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        target: Pass<'_>,
        (pipelines, frame): (&Pipelines, &wgpu::BindGroup),
        clear: [f64; 3],
        c: &mut FrameCounters,
    ) -> wgpu::RenderPass<'e> {
        let mut pass = begin(encoder, target, clear, "eyes");
        pass.set_pipeline(&pipelines.opaque);
        pass.set_bind_group(0, frame, &[]);
        c.setpass_calls += 1;
        c.passes += 1;
        // Opaque surfaces write depth; then membranes and smoke blend over them, tested
        // against that depth and writing none.
        let meshes = || {
            self.field
                .iter()
                .chain(self.meshes.iter())
                .chain(std::iter::once(&self.instruments))
        };
        for mesh in meshes() {
            draw_range(&mut pass, mesh, 0..mesh.opaque_count, true, c);
        }
        if meshes().any(|m| m.index_count > m.opaque_count) {
            pass.set_pipeline(&pipelines.membrane);
            c.setpass_calls += 1;
            for mesh in meshes() {
                // A mesh's vertices count once, with its first draw.
                let first = mesh.opaque_count == 0;
                let range = mesh.opaque_count..mesh.index_count;
                draw_range(&mut pass, mesh, range, first, c);
            }
        }
        self.smoke.draw(&mut pass, &pipelines.smoke, c);
        pass
    }
}

/// A pass's colour view, depth view and multiview mask.
type Pass<'a> = (
    &'a wgpu::TextureView,
    &'a wgpu::TextureView,
    Option<NonZeroU32>,
);

/// The passes that draw `target`: both eyes in one (multiview), or one per eye's view.
fn eye_passes<'a>(target: &RenderTarget<'a>, multiview: bool, depth: &'a Depth) -> Vec<Pass<'a>> {
    match (target, multiview) {
        (RenderTarget::Array(v), true) => vec![(*v, &depth.array, NonZeroU32::new(0b11))],
        (RenderTarget::PerEye(v), _) => vec![
            (v[0], &depth.layers[0], None),
            (v[1], &depth.layers[1], None),
        ],
        (RenderTarget::Single(v), false) => vec![(*v, &depth.layers[0], None)],
        (RenderTarget::Array(_), false) | (RenderTarget::Single(_), true) => Vec::new(),
    }
}

/// Begins a pass that clears its colour to `clear` and its depth to far.
fn begin<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    (colour, depth, mask): Pass<'_>,
    clear: [f64; 3],
    label: &str,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: colour,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color {
                    r: clear[0],
                    g: clear[1],
                    b: clear[2],
                    a: 1.0,
                }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(1.0),
                store: wgpu::StoreOp::Discard,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: mask,
    })
}
