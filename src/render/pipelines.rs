//! The renderer's three pipelines, in the order a pass binds them: opaque surfaces (depth
//! written), translucent membranes and smoke (alpha blended, depth tested, not written, so
//! what lies behind them still shows and nothing in front of them is drawn over).

use super::{DEPTH_FORMAT, RenderError, Vertex};
use std::num::NonZeroU32;

/// The frame's uniform, prepended to each shader.
const FRAME: &str = include_str!("../../shaders/frame.wgsl");
const TISSUE: &str = include_str!("../../shaders/tissue.wgsl");
const SMOKE: &str = include_str!("../../shaders/smoke.wgsl");
const OVERLAY: &str = include_str!("../../shaders/overlay.wgsl");

/// The byte size of one smoke particle's instance data (centre, then radius, alpha, grey).
pub(super) const PARTICLE_BYTES: u64 = 24;

pub(super) struct Pipelines {
    pub opaque: wgpu::RenderPipeline,
    pub membrane: wgpu::RenderPipeline,
    pub smoke: wgpu::RenderPipeline,
    /// The headset's text panel, over everything (`overlay`).
    pub overlay: wgpu::RenderPipeline,
    /// The frame uniform and the material table (the smoke reads only the frame).
    pub layout: wgpu::BindGroupLayout,
    /// The panel's placement, texture and sampler (group 1 of the overlay pipeline).
    pub overlay_layout: wgpu::BindGroupLayout,
}

/// A shader's source for a multiview pass (the eye is the view index) or for one eye a pass
/// (eye 0 of the frame uniform, which the renderer fills with that pass's eye).
fn specialise(source: &str, multiview: bool) -> String {
    if multiview {
        source
            .replace("/*VIEW_INDEX*/", ", @builtin(view_index) view: u32")
            .replace("let eye = VIEW;", "let eye = view;")
    } else {
        source.replace("let eye = VIEW;", "let eye = 0u;")
    }
}

/// Compiles the WGSL `source` of file `file`, a compile error naming the file (left to the
/// device's error handler it would only leave every frame empty).
pub(super) fn compile(
    device: &wgpu::Device,
    file: &str,
    source: String,
) -> Result<wgpu::ShaderModule, RenderError> {
    crate::gpu::compute::compile(device, file, &source)
}

/// Standard "over" blending of straight alpha; the target's alpha stays 1 where it was.
const OVER: wgpu::BlendState = wgpu::BlendState::ALPHA_BLENDING;

impl Pipelines {
    /// The pipelines for targets of `format`; an error names a shader that does not compile
    /// or a pipeline the device refuses.
    pub fn new(
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        multiview: bool,
    ) -> Result<Self, RenderError> {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("frame"),
            entries: &[0, 1].map(|binding| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }),
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("frame"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = |file: &str, source: &str| {
            compile(
                device,
                file,
                specialise(&format!("{FRAME}\n{source}"), multiview),
            )
        };
        let overlay_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("panel"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let overlay_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("panel"),
                bind_group_layouts: &[Some(&layout), Some(&overlay_layout)],
                immediate_size: 0,
            });
        let tissue = module("shaders/tissue.wgsl", TISSUE)?;
        let overlay_module = module("shaders/overlay.wgsl", OVERLAY)?;
        let smoke = module("shaders/smoke.wgsl", SMOKE)?;
        let surface_attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Uint32];
        let surface_buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &surface_attributes,
        })];
        let particle_attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3];
        let particle_buffers = [Some(wgpu::VertexBufferLayout {
            array_stride: PARTICLE_BYTES,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &particle_attributes,
        })];
        let make_with = |label: &str,
                         layout: &wgpu::PipelineLayout,
                         module: &wgpu::ShaderModule,
                         buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
                         fragment: &str,
                         blend: Option<wgpu::BlendState>,
                         depth_compare: wgpu::CompareFunction| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers,
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    // Only opaque surfaces write depth: a blended one that did would hide what
                    // lies behind it and is drawn after it.
                    depth_write_enabled: Some(blend.is_none()),
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: if multiview {
                    NonZeroU32::new(0b11)
                } else {
                    None
                },
                cache: None,
            })
        };
        let make = |label: &str,
                    module: &wgpu::ShaderModule,
                    buffers: &[Option<wgpu::VertexBufferLayout<'_>>],
                    fragment: &str,
                    blend: Option<wgpu::BlendState>| {
            make_with(
                label,
                &pipeline_layout,
                module,
                buffers,
                fragment,
                blend,
                wgpu::CompareFunction::Less,
            )
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = Pipelines {
            overlay: make_with(
                "panel",
                &overlay_pipeline_layout,
                &overlay_module,
                &[],
                "fs_main",
                Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                wgpu::CompareFunction::Always,
            ),
            opaque: make("tissue", &tissue, &surface_buffers, "fs_main", None),
            membrane: make(
                "membrane",
                &tissue,
                &surface_buffers,
                "fs_membrane",
                Some(OVER),
            ),
            smoke: make("smoke", &smoke, &particle_buffers, "fs_main", Some(OVER)),
            layout,
            overlay_layout,
        };
        match pollster::block_on(scope.pop()) {
            Some(e) => Err(RenderError::Validation(format!(
                "the render pipelines: {e}"
            ))),
            None => Ok(pipelines),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_shaders_name_the_eye_the_same_way() {
        // The rewrite must find its marks in each shader, or one of them would fail to
        // compile on one of the paths (only the device would say so).
        for source in [TISSUE, SMOKE, OVERLAY] {
            assert_eq!(source.matches("let eye = VIEW;").count(), 1);
            assert_eq!(source.matches("/*VIEW_INDEX*/").count(), 1);
            let both = specialise(source, true);
            assert!(
                both.contains("@builtin(view_index) view: u32") && both.contains("eye = view;")
            );
            let one = specialise(source, false);
            assert!(one.contains("let eye = 0u;") && !one.contains("view_index) view"));
        }
    }

    #[test]
    fn a_shader_that_does_not_compile_is_an_error_naming_its_file() {
        let gpu = crate::render::Gpu::headless(true)
            .expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)");
        // `patch` is a reserved word in WGSL: this once left every frame empty, silently.
        let bad = "fn patch() -> f32 { return 1.0; }".to_string();
        match compile(&gpu.device, "shaders/bad.wgsl", bad) {
            Err(RenderError::Shader { file, message }) => {
                assert_eq!(file, "shaders/bad.wgsl");
                assert!(message.contains("patch"), "{message}");
            }
            other => panic!("expected a shader error, got {:?}", other.map(|_| ())),
        }
        // The real shaders compile on both paths, and nothing was left for the device's
        // error handler.
        for multiview in [false, gpu.multiview] {
            let p = Pipelines::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb, multiview);
            assert!(p.is_ok(), "{:?}", p.err());
        }
        assert!(gpu.check().is_ok());
    }
}
