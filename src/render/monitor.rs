//! The operating room's monitor in the headset: for a procedure whose scenario says the
//! trainee watches a monitor (`[headset] view = "monitor"`), the scene is drawn from the
//! laparoscope into a picture of its own, with the scope's light, narrow view and image
//! circle, and the headset shows that picture on a screen standing across the table in a dim
//! room. The hands still work in the field, which the eyes do not see directly: the
//! laparoscopic surgeon's hand-eye split.
//!
//! A procedure with a picture of its own (a fluoroscope's grey X-ray image, in
//! `Snapshot::picture`) shows that picture on the monitor instead, whole and centred on a
//! black screen, as the suite's monitor does; no scene is drawn for the monitor then.

use super::RenderError;
use super::camera::EyeView;
use super::gpu::tracked_texture;
use super::optics::{Optics, scope_eyes};
use super::overlay::Placement;
use super::pipelines::Pipelines;
use crate::imaging::fluoro::Picture;
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
    /// The procedure's picture the texture holds now, if it holds one (not the scene).
    shown: Option<Arc<Picture>>,
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
                | wgpu::TextureUsages::COPY_SRC
                // A procedure's own picture is written in.
                | wgpu::TextureUsages::COPY_DST,
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
            shown: None,
        })
    }

    /// Puts a procedure's own picture on the screen (written into the monitor's texture when
    /// it is a new one). False where the texture's format cannot take it (not 8-bit RGBA or
    /// BGRA): the scene is drawn then, as without a picture.
    pub fn show_picture(&mut self, queue: &wgpu::Queue, picture: &Arc<Picture>) -> bool {
        let encoding = match self.texture.format() {
            wgpu::TextureFormat::Rgba8UnormSrgb | wgpu::TextureFormat::Bgra8UnormSrgb => {
                Encoding::Srgb
            }
            wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Bgra8Unorm => Encoding::Linear,
            _ => return false,
        };
        if self.shown.as_ref().is_some_and(|s| Arc::ptr_eq(s, picture)) {
            return true;
        }
        let (w, h) = self.spec.pixels;
        let bytes = letterbox(picture, (w, h), encoding);
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * w),
                rows_per_image: Some(h),
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        self.shown = Some(picture.clone());
        true
    }

    /// From the next picture on the monitor shows the scene again.
    pub fn forget_picture(&mut self) {
        self.shown = None;
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

/// How a texture stores its bytes: sRGB-encoded (the picture's display values as they are)
/// or linear (the display values decoded).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    Srgb,
    Linear,
}

/// A grey picture as the RGBA bytes of a `pixels` screen: scaled (bilinear, keeping its
/// proportion) to the largest size that fits, centred, on black. The grey is the same in
/// every colour channel, so RGBA and BGRA textures take the same bytes.
pub fn letterbox(picture: &Picture, pixels: (u32, u32), encoding: Encoding) -> Vec<u8> {
    let (w, h) = (pixels.0.max(1) as usize, pixels.1.max(1) as usize);
    let mut out = vec![0u8; 4 * w * h];
    for px in out.chunks_exact_mut(4) {
        px[3] = 255;
    }
    let (pw, ph) = (picture.width, picture.height);
    if pw == 0 || ph == 0 || picture.grey.len() < pw * ph {
        return out;
    }
    let scale = (w as f64 / pw as f64).min(h as f64 / ph as f64);
    let (fw, fh) = (
        ((pw as f64 * scale).round() as usize).clamp(1, w),
        ((ph as f64 * scale).round() as usize).clamp(1, h),
    );
    let (x0, y0) = ((w - fw) / 2, (h - fh) / 2);
    // The display value's byte for each grey (decoded for a linear texture).
    let lut: Vec<u8> = (0..=255u8)
        .map(|g| match encoding {
            Encoding::Srgb => g,
            Encoding::Linear => (srgb_to_linear(f64::from(g) / 255.0) * 255.0).round() as u8,
        })
        .collect();
    let grey = |x: usize, y: usize| f64::from(picture.grey[y * pw + x]);
    for y in 0..fh {
        // The source place of this pixel's centre, clamped to the picture's pixel centres.
        let sy = ((y as f64 + 0.5) / scale - 0.5).clamp(0.0, (ph - 1) as f64);
        let (ya, ty) = (sy.floor() as usize, sy.fract());
        let yb = (ya + 1).min(ph - 1);
        for x in 0..fw {
            let sx = ((x as f64 + 0.5) / scale - 0.5).clamp(0.0, (pw - 1) as f64);
            let (xa, tx) = (sx.floor() as usize, sx.fract());
            let xb = (xa + 1).min(pw - 1);
            let top = grey(xa, ya) * (1.0 - tx) + grey(xb, ya) * tx;
            let bottom = grey(xa, yb) * (1.0 - tx) + grey(xb, yb) * tx;
            let g = lut[(top * (1.0 - ty) + bottom * ty).round().clamp(0.0, 255.0) as usize];
            let i = 4 * ((y0 + y) * w + x0 + x);
            out[i..i + 3].fill(g);
        }
    }
    out
}

/// An sRGB display value's linear light (both 0-1).
fn srgb_to_linear(s: f64) -> f64 {
    if s <= 0.04045 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
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

    #[test]
    fn a_square_picture_fills_the_screens_height_centred_on_black() {
        // A 4 x 4 picture: its left half 40, its right half 200.
        let grey: Vec<u8> = (0..16).map(|i| if i % 4 < 2 { 40 } else { 200 }).collect();
        let p = Picture {
            width: 4,
            height: 4,
            grey,
        };
        let out = letterbox(&p, (16, 8), Encoding::Srgb);
        assert_eq!(out.len(), 16 * 8 * 4);
        let at = |x: usize, y: usize| &out[4 * (y * 16 + x)..4 * (y * 16 + x) + 4];
        // 8 x 8 in the middle (columns 4-11); black at the sides, opaque everywhere.
        for y in 0..8 {
            for x in (0..4).chain(12..16) {
                assert_eq!(at(x, y), [0, 0, 0, 255], "side pixel {x},{y}");
            }
        }
        // Each quarter of the picture is two pixels wide; inside its halves the grey is kept.
        assert_eq!(at(4, 3), [40, 40, 40, 255]);
        assert_eq!(at(11, 3), [200, 200, 200, 255]);
        // Across the middle the grey rises through the two in between.
        let mid = at(7, 3)[0];
        assert!(mid > 40 && mid < 200, "{mid}");
        assert!(at(8, 3)[0] > mid);
        // A linear texture gets the display values decoded: sRGB 200 is linear 0.578.
        let lin = letterbox(&p, (16, 8), Encoding::Linear);
        assert_eq!(lin[4 * (3 * 16 + 11)], 147);
        assert_eq!(lin[4 * (3 * 16 + 4)], 5);
    }
}
