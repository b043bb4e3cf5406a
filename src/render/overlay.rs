//! Words in the scene: a small panel of text the headset shows in front of the trainee's eyes
//! (the dynamic assessment's instructions), head-locked, over everything else.
//!
//! The text is laid out and painted by egui into a texture of its own only when the words
//! change; each frame draws that texture as one quad in the eyes' pass, placed from the eyes'
//! pose (0.6 m ahead, below the line of sight), depth test off, blended.

use super::camera::EyeView;
use super::meshes::tracked_buffer;
use crate::profiler::{Category, FrameCounters, Ledger, Tracked};
use glam::Vec3;
use std::sync::Arc;

/// The panel's texture, pixels: 4 to 1, three lines of 84-pixel letters.
pub const PANEL_PX: (u32, u32) = (1536, 384);
/// The panel's width in the world, metres, and its distance ahead of the eyes.
/// At 0.6 m, 0.5 m spans about 45 degrees: a third of a Vive's view (its 84-pixel letters
/// about 20 of the Vive's eye pixels tall).
pub const PANEL_WIDTH_M: f32 = 0.5;
pub const PANEL_DISTANCE_M: f32 = 0.6;
/// How far below the line of sight its centre sits, metres (about 17 degrees: out of the way
/// of the field, where the eyes glance down to read).
pub const PANEL_DROP_M: f32 = 0.18;
/// Instructions shown at most (the newest; a sentence wraps to at most three lines).
pub const PANEL_LINES: usize = 1;
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// The panel's place: centre, and half its width and height along the eyes' right and up.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct Placement {
    pub centre: [f32; 4],
    pub right: [f32; 4],
    pub up: [f32; 4],
}

pub(super) struct Overlay {
    lines: Vec<String>,
    ctx: egui::Context,
    painter: egui_wgpu::Renderer,
    _texture: Tracked<wgpu::Texture>,
    view: wgpu::TextureView,
    placement: Tracked<wgpu::Buffer>,
    bind_group: wgpu::BindGroup,
}

impl Overlay {
    pub(super) fn new(
        device: &wgpu::Device,
        ledger: &Arc<Ledger>,
        layout: &wgpu::BindGroupLayout,
    ) -> Self {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("panel"),
            size: wgpu::Extent3d {
                width: PANEL_PX.0,
                height: PANEL_PX.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let bytes = u64::from(PANEL_PX.0 * PANEL_PX.1 * 4);
        let texture = Tracked::new(texture, bytes, Category::Texture, ledger);
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let (placement, bind_group) = quad_binding(device, ledger, layout, "panel", &view);
        Overlay {
            lines: Vec::new(),
            ctx: egui::Context::default(),
            painter: egui_wgpu::Renderer::new(
                device,
                FORMAT,
                egui_wgpu::RendererOptions::default(),
            ),
            _texture: texture,
            view,
            placement,
            bind_group,
        }
    }

    pub(super) fn visible(&self) -> bool {
        !self.lines.is_empty()
    }

    /// Shows `lines` (the first [`PANEL_LINES`]); paints the texture again only when they
    /// changed.
    pub(super) fn set_lines(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        lines: &[String],
    ) {
        let lines = &lines[..lines.len().min(PANEL_LINES)];
        if self.lines == lines {
            return;
        }
        self.lines = lines.to_vec();
        if !self.lines.is_empty() {
            self.paint(device, queue);
        }
    }

    fn paint(&mut self, device: &wgpu::Device, queue: &wgpu::Queue) {
        let size = egui::vec2(PANEL_PX.0 as f32, PANEL_PX.1 as f32);
        let input = egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(egui::Pos2::ZERO, size)),
            max_texture_side: Some(device.limits().max_texture_dimension_2d as usize),
            ..Default::default()
        };
        let lines = self.lines.clone();
        let out = self.ctx.run_ui(input, |ui| {
            egui::Frame::new()
                .fill(egui::Color32::from_black_alpha(200))
                .corner_radius(32)
                .inner_margin(32)
                .show(ui, |ui| {
                    ui.set_min_size(size - egui::vec2(64.0, 64.0));
                    for (k, line) in lines.iter().enumerate() {
                        // The newest brightest.
                        let colour = if k == 0 {
                            egui::Color32::from_rgb(255, 236, 160)
                        } else {
                            egui::Color32::from_gray(200)
                        };
                        ui.label(egui::RichText::new(line).size(84.0).color(colour));
                    }
                });
        });
        let jobs = self.ctx.tessellate(out.shapes, out.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [PANEL_PX.0, PANEL_PX.1],
            pixels_per_point: out.pixels_per_point,
        };
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                self.painter.update_texture(device, queue, *id, delta);
            }
        }
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("panel"),
        });
        let extra = self
            .painter
            .update_buffers(device, queue, &mut encoder, &jobs, &screen);
        {
            let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("panel"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &self.view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            let mut pass = pass.forget_lifetime();
            self.painter.render(&mut pass, &jobs, &screen);
        }
        queue.submit(extra.into_iter().chain([encoder.finish()]));
        for id in &out.textures_delta.free {
            self.painter.free_texture(id);
        }
    }

    /// Places the panel before the eyes (their midpoint and the first eye's orientation).
    pub(super) fn place(&self, queue: &wgpu::Queue, eyes: &[EyeView; 2]) {
        let p = placement(eyes);
        queue.write_buffer(&self.placement, 0, bytemuck::bytes_of(&p));
    }

    /// Draws the quad (the pipeline's group 0, the frame, is bound by the caller).
    pub(super) fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipeline: &wgpu::RenderPipeline,
        frame: &wgpu::BindGroup,
        c: &mut FrameCounters,
    ) {
        draw_quad(pass, (pipeline, frame, &self.bind_group), c);
    }
}

/// A world quad's placement uniform and its bind group (placement, `view` filtered linearly).
pub(super) fn quad_binding(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    view: &wgpu::TextureView,
) -> (Tracked<wgpu::Buffer>, wgpu::BindGroup) {
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some(label),
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        ..Default::default()
    });
    let placement = tracked_buffer(
        device,
        ledger,
        label,
        std::mem::size_of::<Placement>() as u64,
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        Category::Material,
    );
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: placement.inner.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(view),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::Sampler(&sampler),
            },
        ],
    });
    (placement, bind_group)
}

/// Draws one textured quad placed in the world (the panel, a monitor's screen): `pipeline`
/// with the eyes' `frame` and the quad's placement, texture and sampler.
pub(super) fn draw_quad(
    pass: &mut wgpu::RenderPass<'_>,
    (pipeline, frame, quad): (&wgpu::RenderPipeline, &wgpu::BindGroup, &wgpu::BindGroup),
    c: &mut FrameCounters,
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, frame, &[]);
    pass.set_bind_group(1, quad, &[]);
    pass.draw(0..6, 0..1);
    c.setpass_calls += 1;
    c.draw_calls += 1;
    c.triangles += 2;
    c.vertices += 6;
}

fn placement(eyes: &[EyeView; 2]) -> Placement {
    let mid = 0.5 * (eyes[0].position + eyes[1].position);
    let o = eyes[0].orientation;
    let (forward, right, up) = (o * Vec3::NEG_Z, o * Vec3::X, o * Vec3::Y);
    let centre = mid + forward * PANEL_DISTANCE_M - up * PANEL_DROP_M;
    let half_w = 0.5 * PANEL_WIDTH_M;
    let half_h = half_w * PANEL_PX.1 as f32 / PANEL_PX.0 as f32;
    Placement {
        centre: centre.extend(1.0).to_array(),
        right: (right * half_w).extend(0.0).to_array(),
        up: (up * half_h).extend(0.0).to_array(),
    }
}

/// Where the panel's centre lands in an eye's image of `size` (for tests).
pub fn panel_centre_in(eyes: &[EyeView; 2], eye: usize, size: (u32, u32)) -> Option<glam::Vec2> {
    let p = placement(eyes);
    let centre = Vec3::new(p.centre[0], p.centre[1], p.centre[2]);
    eyes[eye.min(1)].project(centre, size)
}
