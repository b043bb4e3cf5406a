//! The operating room's monitor in the headset: for a procedure whose scenario says the
//! trainee watches a monitor (`[headset] view = "monitor"`), the scene is drawn from the
//! laparoscope into a picture of its own, with the scope's light, narrow view and image
//! circle, and the headset shows that picture on a screen standing across the table in a dim
//! room. The hands still work in the field, which the eyes do not see directly: the
//! laparoscopic surgeon's hand-eye split.

use super::RenderError;
use super::camera::EyeView;
use super::gpu::tracked_texture;
use super::optics::{Optics, scope_eyes};
use super::overlay::Placement;
use super::pipelines::Pipelines;
use crate::profiler::{FrameCounters, Ledger, Tracked};
use crate::sim::ScopeView;
use crate::sim::Viewpoint;
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// The room around the monitor: dim, neutral (linear sRGB), so that the screen's black
/// surround still reads as a screen.
pub const ROOM: [f64; 3] = [0.035, 0.038, 0.045];

/// Where a monitor stands and what it shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MonitorSpec {
    /// The screen's centre, metres (field frame).
    pub centre: Vec3,
    /// Half the screen's width along its rightward edge, and half its height upward.
    pub half_width: Vec3,
    pub half_height: Vec3,
    /// The picture's size, pixels.
    pub pixels: (u32, u32),
    /// The laparoscope's place when the procedure gives none of its own in a snapshot.
    pub view: Viewpoint,
    /// The scope's angle of view across the image circle, degrees.
    pub fov_deg: f32,
}

impl MonitorSpec {
    /// An upright screen `width_m` wide at `centre`, its picture facing `viewer`, showing a
    /// picture of `pixels` (its height follows their proportion).
    pub fn facing(
        centre: Vec3,
        viewer: Vec3,
        width_m: f32,
        pixels: (u32, u32),
        view: Viewpoint,
        fov_deg: f32,
    ) -> Self {
        let normal = (viewer - centre).with_y(0.0).normalize_or(Vec3::Z);
        let right = Vec3::Y.cross(normal).normalize_or(Vec3::X);
        let aspect = pixels.1.max(1) as f32 / pixels.0.max(1) as f32;
        MonitorSpec {
            centre,
            half_width: right * (0.5 * width_m),
            half_height: Vec3::Y * (0.5 * width_m * aspect),
            pixels,
            view,
            fov_deg,
        }
    }

    /// Where pixel `px` of the picture (x right, y down from the top left corner) lies on the
    /// screen in the world.
    pub fn world_of(&self, px: Vec2) -> Vec3 {
        let u = 2.0 * px.x / self.pixels.0.max(1) as f32 - 1.0;
        let v = 1.0 - 2.0 * px.y / self.pixels.1.max(1) as f32;
        self.centre + self.half_width * u + self.half_height * v
    }

    /// The picture's eyes (one point of view, the scope's, in both) and its optics, seen from
    /// the snapshot's laparoscope or, without one, the procedure's view.
    pub fn scope(&self, scope: Option<ScopeView>) -> ([EyeView; 2], Optics) {
        let view = scope.map_or(self.view, |s| Viewpoint {
            eye: s.eye,
            target: s.target,
        });
        (
            scope_eyes(&view, self.fov_deg, self.pixels, 0.0),
            Optics::monitor(&view),
        )
    }

    fn placement(&self) -> Placement {
        Placement {
            centre: self.centre.extend(1.0).to_array(),
            right: self.half_width.extend(0.0).to_array(),
            up: self.half_height.extend(0.0).to_array(),
        }
    }
}

/// The monitor's GPU side: its picture, drawn once a frame in one view by pipelines of its
/// own (a multiview renderer's would draw it once per layer), a depth buffer, the picture's
/// frame uniform and the screen's quad.
pub(super) struct Monitor {
    pub spec: MonitorSpec,
    pub pipelines: Pipelines,
    pub texture: Tracked<wgpu::Texture>,
    pub view: wgpu::TextureView,
    _depth: Tracked<wgpu::Texture>,
    pub depth: wgpu::TextureView,
    pub frame_buffers: Vec<Tracked<wgpu::Buffer>>,
    pub bind_groups: Vec<wgpu::BindGroup>,
    _placement: Tracked<wgpu::Buffer>,
    quad: wgpu::BindGroup,
}

/// What a monitor needs of its renderer.
pub(super) struct Parts<'a> {
    pub device: &'a wgpu::Device,
    pub queue: &'a wgpu::Queue,
    pub ledger: &'a Arc<Ledger>,
    pub format: wgpu::TextureFormat,
    /// The material table the picture's frame binds.
    pub materials: &'a wgpu::Buffer,
    /// The layout of the quad the eyes' pass draws the screen with.
    pub quad_layout: &'a wgpu::BindGroupLayout,
}

impl Monitor {
    /// An error names a shader that does not compile.
    pub fn new(parts: Parts<'_>, spec: MonitorSpec) -> Result<Self, RenderError> {
        let Parts {
            device,
            queue,
            ledger,
            format,
            materials,
            quad_layout,
        } = parts;
        let pipelines = Pipelines::new(device, format, false)?;
        let (frame_buffers, bind_groups) =
            super::frame_bind_groups(device, ledger, &pipelines.layout, materials, 1);
        let size = (spec.pixels.0.max(1), spec.pixels.1.max(1));
        let texture = tracked_texture(
            device,
            ledger,
            "monitor",
            size,
            1,
            format,
            // Drawn, shown on the screen, copied to a desktop mirror.
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
        );
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let depth_texture = tracked_texture(
            device,
            ledger,
            "monitor depth",
            size,
            1,
            super::DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let depth = depth_texture.create_view(&wgpu::TextureViewDescriptor::default());
        let (placement, quad) =
            super::overlay::quad_binding(device, ledger, quad_layout, "monitor", &view);
        queue.write_buffer(&placement, 0, bytemuck::bytes_of(&spec.placement()));
        let spec = MonitorSpec {
            pixels: size,
            ..spec
        };
        Ok(Monitor {
            spec,
            pipelines,
            texture,
            view,
            _depth: depth_texture,
            depth,
            frame_buffers,
            bind_groups,
            _placement: placement,
            quad,
        })
    }

    /// Draws the screen with its picture (the quad pipeline and the eyes' frame bound by the
    /// caller's arguments).
    pub fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipeline: &wgpu::RenderPipeline,
        frame: &wgpu::BindGroup,
        c: &mut FrameCounters,
    ) {
        super::overlay::draw_quad(pass, (pipeline, frame, &self.quad), c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_screen_faces_its_viewer_upright_in_the_pictures_proportion() {
        let view = Viewpoint {
            eye: Vec3::new(0.0, 0.1, 0.2),
            target: Vec3::ZERO,
        };
        let m = MonitorSpec::facing(
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(0.0, 0.3, 0.0),
            0.8,
            (960, 540),
            view,
            70.0,
        );
        // Its picture faces +z (toward the viewer), right is +x, up is +y.
        assert!((m.half_width - Vec3::new(0.4, 0.0, 0.0)).length() < 1e-6);
        assert!((m.half_height - Vec3::new(0.0, 0.225, 0.0)).length() < 1e-6);
        // The top left pixel corner is up and to the left; the centre pixel is the centre.
        let tl = m.world_of(Vec2::ZERO);
        assert!((tl - Vec3::new(-0.4, 0.225, -1.0)).length() < 1e-6, "{tl}");
        let mid = m.world_of(Vec2::new(480.0, 270.0));
        assert!((mid - m.centre).length() < 1e-6);
        // Without a scope of its own the picture is the procedure's view, in its light and
        // circle; a snapshot's scope moves it.
        let (eyes, optics) = m.scope(None);
        assert_eq!(eyes[0].position, view.eye);
        assert_eq!(eyes[0].position, eyes[1].position);
        assert_eq!(optics, Optics::monitor(&view));
        let moved = ScopeView {
            eye: Vec3::new(0.05, 0.1, 0.2),
            target: Vec3::ZERO,
        };
        assert_eq!(m.scope(Some(moved)).0[0].position, moved.eye);
    }
}
