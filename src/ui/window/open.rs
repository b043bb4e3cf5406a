//! Opening the window: its own Vulkan device, or the headset session's, and the egui
//! renderer on it.

use super::*;

impl App {
    pub(super) fn open(&mut self, el: &ActiveEventLoop) -> Result<View, WindowError> {
        let (w, h) = self.opts.size;
        let attrs = Window::default_attributes()
            .with_title(format!("Vesalius: {}", self.opts.procedure))
            .with_inner_size(winit::dpi::LogicalSize::new(w, h))
            .with_min_inner_size(winit::dpi::LogicalSize::new(800, 500));
        let window = Arc::new(el.create_window(attrs)?);
        let (gpu, surface) = match &self.xr {
            Some(x) => {
                // The headset's device draws the window too: its frames are copied, not sent
                // across devices.
                let surface = x.gpu.instance.create_surface(window.clone())?;
                (x.gpu.clone(), surface)
            }
            None => own_gpu(el, &window)?,
        };
        let mut view = finish_open(window, gpu, surface)?;
        // The monitor of a laparoscopic tower: the operative field in the scope's light, in
        // its image circle.
        let info = self.dashboard.info;
        view.renderer.set_field(Some(&(info.field)().mesh()));
        view.renderer
            .set_optics(crate::render::optics::Optics::monitor(&info.view));
        Ok(view)
    }
}

/// A Vulkan device of the window's own (no headset).
fn own_gpu(
    el: &ActiveEventLoop,
    window: &Arc<Window>,
) -> Result<(Gpu, wgpu::Surface<'static>), WindowError> {
    let mut desc =
        wgpu::InstanceDescriptor::new_with_display_handle(Box::new(el.owned_display_handle()));
    desc.backends = wgpu::Backends::VULKAN;
    let instance = wgpu::Instance::new(desc);
    let surface = instance.create_surface(window.clone())?;
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: Some(&surface),
        apply_limit_buckets: false,
    }))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("vesalius window"),
        required_limits: wgpu::Limits::default().using_resolution(adapter.limits()),
        ..Default::default()
    }))?;
    // One view, no headset: no multiview.
    Ok((
        Gpu::from_parts(instance, adapter, device, queue, false),
        surface,
    ))
}

fn finish_open(
    window: Arc<Window>,
    gpu: Gpu,
    surface: wgpu::Surface<'static>,
) -> Result<View, WindowError> {
    let caps = surface.get_capabilities(&gpu.adapter);
    if caps.formats.is_empty() {
        return Err(WindowError::SurfaceUnsupported);
    }
    // egui blends in gamma space: it prefers a plain (non-sRGB) 8-bit target.
    let format = [
        wgpu::TextureFormat::Bgra8Unorm,
        wgpu::TextureFormat::Rgba8Unorm,
    ]
    .into_iter()
    .find(|f| caps.formats.contains(f))
    .or_else(|| caps.formats.first().copied())
    .ok_or(WindowError::NoSurfaceFormat)?;
    let size = window.inner_size();
    let config = wgpu::SurfaceConfiguration {
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        format,
        width: size.width.max(1),
        height: size.height.max(1),
        present_mode: wgpu::PresentMode::AutoVsync,
        desired_maximum_frame_latency: 2,
        alpha_mode: caps
            .alpha_modes
            .first()
            .copied()
            .unwrap_or(wgpu::CompositeAlphaMode::Auto),
        view_formats: vec![],
        color_space: wgpu::SurfaceColorSpace::Auto,
    };
    surface.configure(&gpu.device, &config);
    // One view a pass (the device may have multiview for the headset).
    let renderer = Renderer::with_multiview(&gpu, EYE_FORMAT, false)?;
    let ctx = egui::Context::default();
    let egui = egui_winit::State::new(
        ctx,
        egui::ViewportId::ROOT,
        &window,
        Some(window.scale_factor() as f32),
        None,
        Some(gpu.device.limits().max_texture_dimension_2d as usize),
    );
    let painter =
        egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
    Ok(View {
        window,
        gpu,
        surface,
        config,
        renderer,
        egui,
        painter,
        scene: None,
        last_step: None,
    })
}
