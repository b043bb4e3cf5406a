//! The desktop window (winit + egui on the renderer's own wgpu device): the 3D view in the
//! middle, the supervisor's panels around it. The simulation steps on its own thread in real
//! time; each frame the window draws its newest snapshot into an offscreen texture that the
//! central panel shows, then paints the panels over the swapchain. A screenshot paints the same
//! frame into a texture that is read back, so it is exactly what the window shows.

use super::dashboard::{Dashboard, FrameTimes, Summary};
use super::desktop::{DesktopHands, OrbitCamera, Pointer};
use super::runner::{SimThread, Source};
use crate::assess::alarms::AlarmRules;
use crate::profiler::Tracked;
use crate::render::gpu::{EYE_FORMAT, colour_texture, tracked_texture};
use crate::render::{Gpu, RenderTarget, Renderer};
use crate::session::Outcome;
use crate::sim::{Hand, InputFrame, Pacing};
use crate::xr::{MirrorEye, Tick, XrLoop, XrOptions};
use arc_swap::ArcSwap;
use glam::Vec2;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// What the window runs.
pub struct WindowOptions {
    pub procedure: String,
    pub scenario_text: String,
    pub scenario_file: String,
    /// A trace to play instead of the desktop controls, and its name for the title bar.
    pub trace: Option<(crate::trace::KeyTrace, String)>,
    /// Where the session's files go when it ends.
    pub out: Option<PathBuf>,
    /// Save the whole window here (PNG) at the end of the session, or at `screenshot_at_s`
    /// of simulated time; the window then closes itself when the session ends.
    pub screenshot: Option<PathBuf>,
    pub screenshot_at_s: Option<f64>,
    /// Inner size at start, logical pixels.
    pub size: (u32, u32),
    /// Where "Save to scenario file" writes the tuned scenario.
    pub save_tuning_to: PathBuf,
    /// Mirror an XR session (the headset drives; the window shows an eye or a free camera)
    /// instead of running a desktop session.
    pub xr: Option<XrOptions>,
}

/// What the 3D view shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ViewMode {
    /// The headset's left or right eye, copied from the frame the headset got.
    Eye(MirrorEye),
    /// The window's own orbiting camera (drawn for the window).
    Free,
}

/// Writes `text` to `path` through a temporary file and a rename: never half a file.
fn write_atomic(path: &std::path::Path, text: &str) -> Result<(), String> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// What a window session did.
pub struct WindowRun {
    pub outcome: Outcome,
    /// Window frames drawn, and how many of them drew the scene (not a mirrored eye).
    pub frames: u64,
    pub scene_renders: u64,
    /// The XR session's figures, when the window mirrored one.
    pub xr: Option<(String, u64, u32, (u32, u32))>,
    pub screenshot: Option<((u32, u32), PathBuf)>,
    pub device: String,
}

/// Runs the window until the session ends and its screenshot is taken, or the user closes it.
pub fn run(opts: WindowOptions) -> Result<WindowRun, String> {
    let info = crate::procedures::find(&opts.procedure)
        .ok_or_else(|| format!("unknown procedure '{}'", opts.procedure))?;
    let hands = DesktopHands::parked(info);
    let desk = Arc::new(ArcSwap::from_pointee(hands.frame));
    let source = match &opts.trace {
        Some((t, _)) => Source::Trace(t.clone()),
        None => Source::Live(desk.clone()),
    };
    // The procedure is built (and a bad scenario reported) before any window opens; under XR
    // the runtime and its Vulkan device are opened first, and the window shares that device.
    let (sim, xr) = match opts.xr {
        Some(x) => {
            let mut l = XrLoop::open(
                &opts.scenario_text,
                &opts.scenario_file,
                x,
                opts.out.as_deref(),
            )?;
            l.mirror_eye(MirrorEye::Left);
            (None, Some(l))
        }
        None => (
            Some(
                SimThread::start(
                    &opts.scenario_text,
                    &opts.scenario_file,
                    source,
                    Pacing::RealTime,
                    opts.out.as_deref(),
                )
                .map_err(|e| e.to_string())?,
            ),
            None,
        ),
    };
    let event_loop = EventLoop::new().map_err(|e| {
        format!("cannot open a window ({e}); is DISPLAY set? (headless: xvfb-run, or --headless)")
    })?;
    let source = match (&opts.trace, &xr) {
        (_, Some(l)) => format!("headset ({})", l.runtime_name()),
        (Some((_, name)), None) => format!("playing {name}"),
        (None, None) => "mouse and keyboard".to_string(),
    };
    let mut dashboard = Dashboard::new(info, &source, AlarmRules::for_procedure(info));
    let desktop = (opts.trace.is_none() && xr.is_none()).then(|| {
        dashboard.key_map = hands.key_map();
        (hands, desk)
    });
    if xr.is_some() {
        dashboard.key_map = [
            ("V", "left eye / right eye / free camera"),
            ("arrows, shift + arrows", "orbit, pan (free camera)"),
            ("PgUp / PgDn, R", "zoom, reset (free camera)"),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    }
    let view_mode = if xr.is_some() {
        ViewMode::Eye(MirrorEye::Left)
    } else {
        ViewMode::Free
    };
    let mut app = App {
        dashboard,
        desktop,
        shift: false,
        opts,
        sim,
        xr,
        xr_run: None,
        view_mode,
        mirror_id: None,
        mirror_size: (1, 1),
        scene_renders: 0,
        last_window_frame: None,
        view: None,
        camera: OrbitCamera::at(&info.view),
        outcome: None,
        frames: 0,
        shot: None,
        shot_taken: false,
        error: None,
        start: Instant::now(),
    };
    event_loop.run_app(&mut app).map_err(|e| e.to_string())?;
    if let Some(e) = app.error.take() {
        // Keep what the session did before the failure: its record is written all the same.
        let kept = match app.end_session() {
            Ok(()) => app
                .opts
                .out
                .as_ref()
                .map(|d| format!(" (the session so far is in {})", d.display()))
                .unwrap_or_default(),
            Err(e2) => format!(" (and its record could not be written: {e2})"),
        };
        return Err(format!("{e}{kept}"));
    }
    if app.outcome.is_none() {
        app.end_session()?;
    }
    let outcome = app
        .outcome
        .take()
        .ok_or("the session ended without an outcome")?;
    let device = app
        .view
        .as_ref()
        .map_or_else(String::new, |v| v.gpu.describe());
    Ok(WindowRun {
        outcome,
        frames: app.frames,
        scene_renders: app.scene_renders,
        xr: app.xr_run.take(),
        screenshot: app.shot,
        device,
    })
}

/// Everything that exists once the window does.
struct View {
    window: Arc<Window>,
    gpu: Gpu,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
    egui: egui_winit::State,
    painter: egui_wgpu::Renderer,
    /// The 3D view's texture, its size and its id in egui.
    scene: Option<Scene>,
    last_step: Option<u64>,
}

struct Scene {
    size: (u32, u32),
    _texture: Tracked<wgpu::Texture>,
    view: wgpu::TextureView,
    id: egui::TextureId,
}

struct App {
    opts: WindowOptions,
    dashboard: Dashboard,
    /// Desktop mode: the instruments the mouse drives, and where the simulation reads them.
    desktop: Option<(DesktopHands, Arc<ArcSwap<InputFrame>>)>,
    shift: bool,
    sim: Option<SimThread>,
    xr: Option<XrLoop>,
    /// Runtime, stereo frames, sessions and eye size of a finished XR session.
    xr_run: Option<(String, u64, u32, (u32, u32))>,
    view_mode: ViewMode,
    /// The mirrored eye's texture in egui.
    mirror_id: Option<egui::TextureId>,
    mirror_size: (u32, u32),
    scene_renders: u64,
    /// Simulated and wall time of the last window frame under XR.
    last_window_frame: Option<(f64, Instant)>,
    view: Option<View>,
    camera: OrbitCamera,
    outcome: Option<Outcome>,
    frames: u64,
    shot: Option<((u32, u32), PathBuf)>,
    shot_taken: bool,
    error: Option<String>,
    start: Instant,
}

impl App {
    fn fail(&mut self, el: &ActiveEventLoop, e: impl std::fmt::Display) {
        self.error.get_or_insert(e.to_string());
        el.exit();
    }

    fn open(&mut self, el: &ActiveEventLoop) -> Result<View, String> {
        let (w, h) = self.opts.size;
        let attrs = Window::default_attributes()
            .with_title(format!("Vesalius: {}", self.opts.procedure))
            .with_inner_size(winit::dpi::LogicalSize::new(w, h))
            .with_min_inner_size(winit::dpi::LogicalSize::new(800, 500));
        let window = Arc::new(el.create_window(attrs).map_err(|e| e.to_string())?);
        let (gpu, surface) = match &self.xr {
            Some(x) => {
                // The headset's device draws the window too: its frames are copied, not sent
                // across devices.
                let surface = x
                    .gpu
                    .instance
                    .create_surface(window.clone())
                    .map_err(|e| format!("cannot draw into the window: {e}"))?;
                (x.gpu.clone(), surface)
            }
            None => own_gpu(el, &window)?,
        };
        finish_open(window, gpu, surface)
    }
}

/// A Vulkan device of the window's own (no headset).
fn own_gpu(
    el: &ActiveEventLoop,
    window: &Arc<Window>,
) -> Result<(Gpu, wgpu::Surface<'static>), String> {
    let mut desc =
        wgpu::InstanceDescriptor::new_with_display_handle(Box::new(el.owned_display_handle()));
    desc.backends = wgpu::Backends::VULKAN;
    let instance = wgpu::Instance::new(desc);
    let surface = instance
        .create_surface(window.clone())
        .map_err(|e| format!("cannot draw into the window: {e}"))?;
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        force_fallback_adapter: false,
        compatible_surface: Some(&surface),
        apply_limit_buckets: false,
    }))
    .map_err(|e| format!("no Vulkan adapter can draw into the window: {e}"))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("vesalius window"),
        required_limits: wgpu::Limits::default().using_resolution(adapter.limits()),
        ..Default::default()
    }))
    .map_err(|e| format!("cannot open the GPU: {e}"))?;
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
) -> Result<View, String> {
    let caps = surface.get_capabilities(&gpu.adapter);
    if caps.formats.is_empty() {
        return Err("this GPU cannot draw into the window".into());
    }
    // egui blends in gamma space: it prefers a plain (non-sRGB) 8-bit target.
    let format = [
        wgpu::TextureFormat::Bgra8Unorm,
        wgpu::TextureFormat::Rgba8Unorm,
    ]
    .into_iter()
    .find(|f| caps.formats.contains(f))
    .or_else(|| caps.formats.first().copied())
    .ok_or("the window's surface offers no format")?;
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
    let renderer = Renderer::with_multiview(&gpu, EYE_FORMAT, false);
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

impl App {
    /// The session ended: keep its outcome, write its files, show its report.
    fn end_session(&mut self) -> Result<(), String> {
        let outcome = if let Some(sim) = self.sim.take() {
            sim.finish().map_err(|e| e.to_string())?
        } else if let Some(x) = self.xr.take() {
            let run = x.finish()?;
            self.xr_run = Some((run.runtime, run.frames, run.sessions, run.eye_size));
            run.outcome
        } else {
            return Ok(());
        };
        let written = match &self.opts.out {
            Some(dir) => {
                crate::session::write_outputs(&outcome, dir).map_err(|e| e.to_string())?;
                Some(dir.display().to_string())
            }
            None => None,
        };
        self.dashboard.summary = Some(Summary::from_report(&outcome.report, written));
        self.outcome = Some(outcome);
        Ok(())
    }

    fn key(&mut self, key: &Key) {
        let c = &mut self.camera;
        // Orbit 0.05 rad, pan 5 mm, zoom 10 % a press.
        let (turn, pan) = (0.05, 0.005);
        match (key, self.shift) {
            (Key::Named(NamedKey::ArrowLeft), false) => c.orbit(-turn, 0.0),
            (Key::Named(NamedKey::ArrowRight), false) => c.orbit(turn, 0.0),
            (Key::Named(NamedKey::ArrowUp), false) => c.orbit(0.0, turn),
            (Key::Named(NamedKey::ArrowDown), false) => c.orbit(0.0, -turn),
            (Key::Named(NamedKey::ArrowLeft), true) => c.pan(-pan, 0.0),
            (Key::Named(NamedKey::ArrowRight), true) => c.pan(pan, 0.0),
            (Key::Named(NamedKey::ArrowUp), true) => c.pan(0.0, pan),
            (Key::Named(NamedKey::ArrowDown), true) => c.pan(0.0, -pan),
            (Key::Named(NamedKey::PageUp), _) => c.zoom(0.1),
            (Key::Named(NamedKey::PageDown), _) => c.zoom(-0.1),
            (Key::Character(s), _) => match s.as_str() {
                "r" | "R" => *c = OrbitCamera::at(&self.dashboard.info.view),
                "1" => self.select(Hand::Left),
                "2" => self.select(Hand::Right),
                "v" | "V" if self.xr.is_some() => self.next_view(),
                _ => {}
            },
            _ => {}
        }
    }

    /// Applies the sliders to the running simulation, or writes them to the scenario file.
    fn act(&mut self, a: super::dashboard::Actions) {
        if let (Some((model, values)), Some(sim)) = (a.tune, &self.sim) {
            // The thread is gone only when the session has ended; then there is nothing to tune.
            let _ = sim
                .commands
                .send(super::runner::Command::Tune(model, values));
        }
        if a.save {
            let path = &self.opts.save_tuning_to;
            let written = crate::scenario::with_tunables(
                &self.opts.scenario_file,
                &self.opts.scenario_text,
                &self.dashboard.status.tunables,
            )
            .map_err(|e| e.to_string())
            .and_then(|text| write_atomic(path, &text));
            self.dashboard.saved = Some(match written {
                Ok(()) => format!("saved to {}", path.display()),
                Err(e) => format!("not saved: {e}"),
            });
        }
    }

    /// Left eye, right eye, free camera, and round again.
    fn next_view(&mut self) {
        self.view_mode = match self.view_mode {
            ViewMode::Eye(MirrorEye::Left) => ViewMode::Eye(MirrorEye::Right),
            ViewMode::Eye(MirrorEye::Right) => ViewMode::Free,
            ViewMode::Free => ViewMode::Eye(MirrorEye::Left),
        };
        if let (ViewMode::Eye(e), Some(x)) = (self.view_mode, self.xr.as_mut()) {
            x.mirror_eye(e);
        }
    }

    fn select(&mut self, hand: Hand) {
        if let Some((h, _)) = self.desktop.as_mut() {
            h.selected = hand;
        }
    }

    fn redraw(&mut self, el: &ActiveEventLoop) -> Result<(), String> {
        let t0 = Instant::now();
        if self.sim.as_ref().is_some_and(SimThread::finished) {
            self.end_session()?;
        }
        let Some(v) = self.view.as_mut() else {
            return Ok(());
        };
        // The newest simulation state (a free camera under XR takes a snapshot of its own).
        // After the session, the last mirrored frame stays on screen.
        let mirrored = matches!(self.view_mode, ViewMode::Eye(_))
            && (self.mirror_id.is_some() || self.xr.is_some());
        let snapshot = match (&self.sim, self.xr.as_mut()) {
            (Some(sim), _) => {
                self.dashboard.update((**sim.status.load()).clone());
                Some(sim.bus.latest())
            }
            (None, Some(x)) => {
                self.dashboard
                    .update(x.live().status(super::runner::LOOK_M));
                (!mirrored).then(|| Arc::new(x.live().snapshot()))
            }
            _ => None,
        };
        if self.mirror_id.is_none()
            && let Some(m) = self.xr.as_ref().and_then(|x| x.mirror.as_ref())
        {
            self.mirror_id = Some(v.painter.register_native_texture(
                &v.gpu.device,
                &m.view,
                wgpu::FilterMode::Linear,
            ));
            self.mirror_size = m.size;
        }
        let mirror = self
            .mirror_id
            .map(|id| (self.mirror_size, id))
            .filter(|_| mirrored);
        self.dashboard.viewing = self.xr.is_some().then_some(match self.view_mode {
            ViewMode::Eye(MirrorEye::Left) => "the headset's left eye",
            ViewMode::Eye(MirrorEye::Right) => "the headset's right eye",
            ViewMode::Free => "a free camera",
        });
        if let Some(s) = &snapshot
            && v.last_step != Some(s.step)
        {
            v.renderer.update(s);
            v.last_step = Some(s.step);
        }
        // Panels first: they decide how large the 3D view is.
        let input = v.egui.take_egui_input(&v.window);
        let ppp = v.egui.egui_ctx().pixels_per_point();
        let mut view_px = (1u32, 1u32);
        let mut pointer = Pointer::default();
        let scene_id = v.scene.as_ref().map(|s| s.id);
        self.dashboard.driving = self.desktop.as_ref().map(|(h, _)| match h.selected {
            Hand::Left => "the grasper",
            Hand::Right => "the laser",
        });
        let dashboard = &mut self.dashboard;
        let mut actions = Default::default();
        let ui_start = Instant::now();
        let out = v.egui.egui_ctx().clone().run_ui(input, |ui| {
            actions = dashboard.show(ui, |ui| {
                let rect = ui.available_rect_before_wrap();
                view_px = (
                    ((rect.width() * ppp).round() as u32).max(1),
                    ((rect.height() * ppp).round() as u32).max(1),
                );
                if let Some(((w, h), id)) = mirror {
                    // The eye's picture, whole, centred at its own aspect ratio.
                    let scale = (rect.width() / w as f32).min(rect.height() / h as f32);
                    let fit = egui::Rect::from_center_size(
                        rect.center(),
                        egui::vec2(w as f32 * scale, h as f32 * scale),
                    );
                    ui.put(
                        fit,
                        egui::Image::new(egui::load::SizedTexture::new(id, fit.size())),
                    );
                } else if let Some(id) = scene_id {
                    let r = ui.put(
                        rect,
                        egui::Image::new(egui::load::SizedTexture::new(id, rect.size()))
                            .sense(egui::Sense::click_and_drag()),
                    );
                    pointer = read_pointer(ui, &r, rect);
                }
            });
        });
        let ui_ms = ui_start.elapsed().as_secs_f32() * 1e3;
        self.act(actions);
        let Some(v) = self.view.as_mut() else {
            return Ok(());
        };
        v.egui
            .handle_platform_output(&v.window, out.platform_output.clone());
        // The 3D view, at the central panel's size.
        let render_start = Instant::now();
        ensure_scene(v, view_px);
        // Mirroring, the headset's renderer did the frame's work: its counters.
        let mut counters = match (&self.xr, mirror.is_some()) {
            (Some(x), true) => x.counters.clone(),
            _ => Default::default(),
        };
        if let Some(scene) = v.scene.as_ref().filter(|_| mirror.is_none()) {
            self.scene_renders += 1;
            let aspect = scene.size.0 as f32 / scene.size.1 as f32;
            let eye = self.camera.view(aspect);
            if let Some((hands, shared)) = self.desktop.as_mut() {
                hands.pointer(&eye, pointer);
                shared.store(Arc::new(hands.frame));
            }
            counters =
                v.renderer
                    .render(RenderTarget::Single(&scene.view), scene.size, &[eye, eye]);
        }
        let render_ms = render_start.elapsed().as_secs_f32() * 1e3;
        // The panels over the swapchain image.
        let jobs = v
            .egui
            .egui_ctx()
            .tessellate(out.shapes.clone(), out.pixels_per_point);
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [v.config.width, v.config.height],
            pixels_per_point: out.pixels_per_point,
        };
        for (id, deltas) in &out.textures_delta.set {
            for delta in deltas {
                v.painter
                    .update_texture(&v.gpu.device, &v.gpu.queue, *id, delta);
            }
        }
        match v.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame)
            | wgpu::CurrentSurfaceTexture::Suboptimal(frame) => {
                let target = frame
                    .texture
                    .create_view(&wgpu::TextureViewDescriptor::default());
                paint(v, &jobs, &screen, &target);
                v.gpu.queue.present(frame);
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                v.surface.configure(&v.gpu.device, &v.config);
            }
            other => return Err(format!("the window's swapchain failed: {other:?}")),
        }
        // The screenshot: the same frame, painted again into a texture that is read back.
        let due = match (self.opts.screenshot_at_s, &self.outcome) {
            (Some(at), _) => self.dashboard.status.time_s >= at,
            (None, Some(_)) => true,
            (None, None) => false,
        };
        if !self.shot_taken
            && due
            && let Some(path) = self.opts.screenshot.clone()
        {
            let size = screenshot(v, &jobs, &screen, &path)?;
            self.shot = Some((size, path));
            self.shot_taken = true;
        }
        for id in &out.textures_delta.free {
            v.painter.free_texture(id);
        }
        v.gpu.check().map_err(|e| e.to_string())?;
        self.frames += 1;
        let frame_ms = t0.elapsed().as_secs_f32() * 1e3;
        self.dashboard.frame(
            counters,
            FrameTimes {
                time_s: self.start.elapsed().as_secs_f64(),
                frame_ms,
                render_ms,
                ui_ms,
            },
        );
        // A scripted run with a screenshot closes itself once the session is over; in desktop
        // mode, where nothing else ends it, the session ends with a screenshot taken at a time.
        if self.shot_taken && self.desktop.is_some() && self.outcome.is_none() {
            self.end_session()?;
        }
        if self.outcome.is_some() && self.opts.screenshot.is_some() && self.shot_taken {
            el.exit();
        }
        Ok(())
    }
}

/// The mouse over the 3D view: where (normalised, y up), its buttons, the wheel's notches.
fn read_pointer(ui: &egui::Ui, r: &egui::Response, rect: egui::Rect) -> Pointer {
    let ndc = r.hover_pos().map(|p| {
        Vec2::new(
            (p.x - rect.left()) / rect.width() * 2.0 - 1.0,
            1.0 - (p.y - rect.top()) / rect.height() * 2.0,
        )
    });
    ui.input(|i| {
        let wheel = i
            .events
            .iter()
            .filter_map(|e| match e {
                egui::Event::MouseWheel { unit, delta, .. } => Some(match unit {
                    egui::MouseWheelUnit::Line | egui::MouseWheelUnit::Page => delta.y,
                    // A notch is about 50 points on pixel-scrolling devices.
                    egui::MouseWheelUnit::Point => delta.y / 50.0,
                }),
                _ => None,
            })
            .sum();
        Pointer {
            ndc,
            primary_down: ndc.is_some() && i.pointer.primary_down(),
            secondary_down: ndc.is_some() && i.pointer.secondary_down(),
            wheel: if ndc.is_some() { wheel } else { 0.0 },
        }
    })
}

/// (Re)makes the 3D view's texture when the central panel changes size.
fn ensure_scene(v: &mut View, size: (u32, u32)) {
    if v.scene.as_ref().is_some_and(|s| s.size == size) {
        return;
    }
    let texture = tracked_texture(
        &v.gpu.device,
        &v.gpu.ledger,
        "3d view",
        size,
        1,
        EYE_FORMAT,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
    let id = match v.scene.take() {
        Some(old) => {
            v.painter.update_egui_texture_from_wgpu_texture(
                &v.gpu.device,
                &view,
                wgpu::FilterMode::Linear,
                old.id,
            );
            old.id
        }
        None => v
            .painter
            .register_native_texture(&v.gpu.device, &view, wgpu::FilterMode::Linear),
    };
    v.scene = Some(Scene {
        size,
        _texture: texture,
        view,
        id,
    });
}

/// Paints egui's primitives into `target` (cleared first).
fn paint(
    v: &mut View,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
    target: &wgpu::TextureView,
) {
    let mut encoder = v
        .gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("panels"),
        });
    let extra = v
        .painter
        .update_buffers(&v.gpu.device, &v.gpu.queue, &mut encoder, jobs, screen);
    {
        let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("panels"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let mut pass = pass.forget_lifetime();
        v.painter.render(&mut pass, jobs, screen);
    }
    v.gpu
        .queue
        .submit(extra.into_iter().chain([encoder.finish()]));
}

/// Paints the frame into a readable texture and writes it as a PNG; returns its size.
fn screenshot(
    v: &mut View,
    jobs: &[egui::ClippedPrimitive],
    screen: &egui_wgpu::ScreenDescriptor,
    path: &std::path::Path,
) -> Result<(u32, u32), String> {
    let size = (screen.size_in_pixels[0], screen.size_in_pixels[1]);
    let format = v.config.format;
    let texture = colour_texture(
        &v.gpu.device,
        "screenshot",
        size,
        1,
        format,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    let target = texture.create_view(&wgpu::TextureViewDescriptor::default());
    paint(v, jobs, screen, &target);
    let mut pixels = crate::render::gpu::read_texture(&v.gpu, &texture, size, 1)
        .map_err(|e| e.to_string())?
        .pop()
        .unwrap_or_default();
    if matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    ) {
        for p in pixels.chunks_exact_mut(4) {
            p.swap(0, 2);
        }
    }
    for p in pixels.chunks_exact_mut(4) {
        p[3] = 255;
    }
    crate::render::gpu::write_png(path, size, &pixels).map_err(|e| e.to_string())?;
    Ok(size)
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.view.is_some() {
            return;
        }
        match self.open(el) {
            Ok(v) => {
                v.window.request_redraw();
                self.view = Some(v);
            }
            Err(e) => self.fail(el, e),
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(v) = self.view.as_mut() else {
            return;
        };
        let used = v.egui.on_window_event(&v.window, &event).consumed;
        match event {
            WindowEvent::CloseRequested => {
                // End the session, and draw its last frame (taking the screenshot if due).
                if let Err(e) = self.end_session().and_then(|()| self.redraw(el)) {
                    self.fail(el, e);
                }
                el.exit();
            }
            WindowEvent::Resized(size) => {
                v.config.width = size.width.max(1);
                v.config.height = size.height.max(1);
                v.surface.configure(&v.gpu.device, &v.config);
            }
            WindowEvent::ModifiersChanged(m) => self.shift = m.state().shift_key(),
            WindowEvent::KeyboardInput { event, .. }
                if !used && event.state == ElementState::Pressed =>
            {
                self.key(&event.logical_key);
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(el) {
                    self.fail(el, e);
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, el: &ActiveEventLoop) {
        // SIGINT or SIGTERM: the session ends as if closed, its files written, and so does
        // the window.
        if crate::session::interrupt::interrupted().is_some() && self.outcome.is_none() {
            if let Some(x) = self.xr.as_mut() {
                x.live().set_ended(crate::session::ended::INTERRUPTED);
            }
            if let Err(e) = self.end_session() {
                self.fail(el, e);
            }
            el.exit();
            return;
        }
        // Under XR the headset sets the pace: one frame of it each pass, and the window
        // redrawn at most 30 times a second beside it (or as soon as the session ends).
        let mut due = true;
        if let Some(x) = self.xr.as_mut() {
            el.set_control_flow(winit::event_loop::ControlFlow::Poll);
            match x.tick() {
                Ok(Tick::Exit) => {
                    if let Err(e) = self.end_session() {
                        self.fail(el, e);
                    }
                }
                Ok(_) => {
                    // 30 window frames a second of the headset's time (a simulated runtime's
                    // clock runs as fast as frames are made), and at least 10 of wall time
                    // while the session waits.
                    let t = x.live().time_s();
                    due = self.last_window_frame.is_none_or(|(s, wall)| {
                        t - s >= 1.0 / 30.0 || wall.elapsed().as_secs_f64() >= 0.1
                    });
                }
                Err(e) => self.fail(el, e),
            }
        }
        if due && let Some(v) = &self.view {
            let t = self.xr.as_mut().map_or(0.0, |x| x.live().time_s());
            self.last_window_frame = Some((t, Instant::now()));
            v.window.request_redraw();
        }
    }
}
