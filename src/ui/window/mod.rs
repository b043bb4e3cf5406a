//! The desktop window (winit + egui on the renderer's own wgpu device): the 3D view in the
//! middle, the supervisor's panels around it. The simulation steps on its own thread in real
//! time; each frame the window draws its newest snapshot into an offscreen texture that the
//! central panel shows, then paints the panels over the swapchain. A screenshot paints the same
//! frame into a texture that is read back, so it is exactly what the window shows.

use super::dashboard::{Dashboard, FrameTimes, Summary};
use super::desktop::{DesktopHands, OrbitCamera, Pointer};
use super::learning::LearningCentre;
use super::runner::{SimThread, Source};
use crate::assess::alarms::AlarmRules;
use crate::haptics::{DeviceRun, HapticDevice, HapticsError, Rig, RigOptions};
use crate::profiler::Tracked;
use crate::render::gpu::{EYE_FORMAT, colour_texture, tracked_texture};
use crate::render::{Gpu, RenderError, RenderTarget, Renderer};
use crate::session::{Outcome, SessionError};
use crate::sim::{Hand, InputFrame, Pacing, PadDirection};
use crate::xr::{MirrorEye, Tick, XrLoop, XrOptions, XrRunError};
use arc_swap::ArcSwap;
use glam::Vec2;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::error::EventLoopError;
use winit::event::{ElementState, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

mod frame;
mod open;

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
    /// Force-feedback devices driving the instruments instead of the mouse.
    pub devices: Option<WindowDevices>,
    /// The learning centre's records (file, trainee): the session is stored there when it
    /// ends (with `out`), and the Learning Centre panel shows them.
    pub records: Option<(PathBuf, String)>,
    /// Desktop mode: begin at once, without the start screen (scripted runs).
    pub start_now: bool,
}

/// Force-feedback devices for a window session.
pub struct WindowDevices {
    /// One or two: the probe (else the right hand), or both hands.
    pub devices: Vec<Box<dyn HapticDevice>>,
    pub options: RigOptions,
    /// End after this many simulated seconds (none: when the window closes).
    pub until_s: Option<f64>,
}

/// What the 3D view shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum ViewMode {
    /// The headset's left or right eye, copied from the frame the headset got.
    Eye(MirrorEye),
    /// The window's own orbiting camera (drawn for the window).
    Free,
}

/// Why the window, or the session in it, stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    #[error("unknown procedure '{0}'")]
    UnknownProcedure(String),
    /// The scenario, the output folder, the recording or the session's files.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// The headset's session (under XR).
    #[error(transparent)]
    Xr(#[from] XrRunError),
    #[error(transparent)]
    Render(#[from] RenderError),
    /// A force-feedback device or its servo loop.
    #[error(transparent)]
    Haptics(#[from] HapticsError),
    /// The learning centre's records the session is stored in.
    #[error(transparent)]
    Records(#[from] crate::records::RecordsError),
    #[error("cannot open a window ({0}); is DISPLAY set? (headless: xvfb-run, or --headless)")]
    NoDisplay(#[source] EventLoopError),
    /// The event loop failed while the window was open.
    #[error(transparent)]
    EventLoop(EventLoopError),
    #[error(transparent)]
    CreateWindow(#[from] winit::error::OsError),
    #[error("cannot draw into the window: {0}")]
    Surface(#[from] wgpu::CreateSurfaceError),
    #[error("no Vulkan adapter can draw into the window: {0}")]
    NoAdapter(#[from] wgpu::RequestAdapterError),
    #[error("cannot open the GPU: {0}")]
    Device(#[from] wgpu::RequestDeviceError),
    #[error("this GPU cannot draw into the window")]
    SurfaceUnsupported,
    #[error("the window's surface offers no format")]
    NoSurfaceFormat,
    /// The surface gave no image to draw into: its state (`Timeout`, `Occluded`, ...).
    #[error("the window's swapchain failed: {0}")]
    Swapchain(String),
    #[error("the session ended without an outcome")]
    NoOutcome,
    /// A failure after which the session's files were written all the same.
    #[error("{error} (the session so far is in {})", dir.display())]
    Kept {
        error: Box<WindowError>,
        dir: PathBuf,
    },
    /// A failure after which the session's files could not be written either.
    #[error("{error} (and its record could not be written: {record})")]
    RecordLost {
        error: Box<WindowError>,
        record: Box<WindowError>,
    },
}

/// Why the tuned scenario was not saved (shown in the window, which carries on).
#[derive(Debug, thiserror::Error)]
enum SaveError {
    #[error(transparent)]
    Scenario(#[from] crate::scenario::InputError),
    #[error("{}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Writes `text` to `path` through a temporary file and a rename: never half a file.
fn write_atomic(path: &std::path::Path, text: &str) -> Result<(), SaveError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|source| SaveError::Write {
            path: dir.to_path_buf(),
            source,
        })?;
    }
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|source| SaveError::Write {
            path: path.to_path_buf(),
            source,
        })
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
    /// How each force-feedback device's servo loop went.
    pub devices: Vec<DeviceRun>,
}

/// Runs the window until the session ends and its screenshot is taken, or the user closes it.
pub fn run(mut opts: WindowOptions) -> Result<WindowRun, WindowError> {
    let info = crate::registry::find(&opts.procedure)
        .ok_or_else(|| WindowError::UnknownProcedure(opts.procedure.clone()))?;
    let hands = DesktopHands::parked(info);
    let desk = Arc::new(ArcSwap::from_pointee(hands.frame));
    let source = match &opts.trace {
        Some((t, _)) => Source::Trace(t.clone()),
        None => Source::Live(desk.clone()),
    };
    // The procedure is built (and a bad scenario reported) before any window opens; under XR
    // the runtime and its Vulkan device are opened first, and the window shares that device.
    // Devices get their servo threads, and the simulation the cores those leave.
    let mut rig = None;
    let mut device_names = Vec::new();
    // Desktop mode (the mouse drives): the session waits on the start screen.
    let trainee_mode = opts.trace.is_none() && opts.xr.is_none() && opts.devices.is_none();
    let (sim, xr) = match (opts.xr.clone(), opts.devices.take()) {
        (None, Some(d)) => {
            let live = super::runner::open_live(
                &opts.scenario_text,
                &opts.scenario_file,
                Pacing::RealTime,
                opts.out.as_deref(),
            )?;
            device_names = d.devices.iter().map(|x| x.name().to_string()).collect();
            let pool = crate::haptics::stand::sim_pool(d.devices.len())?;
            let (r, input) = Rig::start(d.devices, info, live.haptics(), d.options)?;
            rig = Some(r);
            let source = Source::Devices {
                input,
                until_s: d.until_s,
            };
            (
                Some(SimThread::start_live(live, source, Some(pool), false)?),
                None,
            )
        }
        (xr, d) => match xr {
            Some(x) => {
                // Styluses in the headset: they drive their hands' instruments there.
                let devices = d.map(|d| {
                    device_names = d.devices.iter().map(|x| x.name().to_string()).collect();
                    crate::xr::XrDevices {
                        devices: d.devices,
                        options: d.options,
                    }
                });
                let mut l = XrLoop::open(
                    &opts.scenario_text,
                    &opts.scenario_file,
                    x,
                    opts.out.as_deref(),
                    devices,
                )?;
                l.mirror_eye(MirrorEye::Left);
                (None, Some(l))
            }
            None => (
                Some(SimThread::start(
                    &opts.scenario_text,
                    &opts.scenario_file,
                    source,
                    Pacing::RealTime,
                    opts.out.as_deref(),
                    trainee_mode && !opts.start_now,
                )?),
                None,
            ),
        },
    };
    let event_loop = EventLoop::new().map_err(WindowError::NoDisplay)?;
    let source = match (&opts.trace, &xr) {
        (_, Some(l)) if !device_names.is_empty() => format!(
            "headset ({}), force feedback: {}",
            l.runtime_name(),
            device_names.join(", ")
        ),
        _ if !device_names.is_empty() => format!("force feedback: {}", device_names.join(", ")),
        (_, Some(l)) => format!("headset ({})", l.runtime_name()),
        (Some((_, name)), None) => format!("playing {name}"),
        (None, None) => "mouse and keyboard".to_string(),
    };
    let mut dashboard = Dashboard::new(info, &source, AlarmRules::for_procedure(info));
    if let Some((file, _)) = &opts.records {
        let mut r = crate::records::Db::open(file)?;
        dashboard.learning = Some(LearningCentre::read(&r.shown(), &mut r)?);
    }
    let desktop = (opts.trace.is_none() && xr.is_none() && rig.is_none()).then(|| {
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
    let trainer = desktop.is_some().then_some(Trainer {
        started: opts.start_now,
        ..Trainer::default()
    });
    let mut app = App {
        dashboard,
        desktop,
        trainer,
        shift: false,
        opts,
        sim,
        rig,
        device_runs: Vec::new(),
        xr,
        xr_run: None,
        view_mode,
        mirror_id: None,
        mirror_size: (1, 1),
        picture: None,
        teaching_view: false,
        scene_renders: 0,
        last_window_frame: None,
        view: None,
        camera: OrbitCamera::at(&info.view),
        scope_seen: None,
        outcome: None,
        frames: 0,
        shot: None,
        shot_taken: false,
        error: None,
        start: Instant::now(),
    };
    event_loop
        .run_app(&mut app)
        .map_err(WindowError::EventLoop)?;
    if let Some(error) = app.error.take() {
        // Keep what the session did before the failure: its record is written all the same.
        return Err(match (app.end_session(), app.opts.out.clone()) {
            (Ok(()), Some(dir)) => WindowError::Kept {
                error: Box::new(error),
                dir,
            },
            (Ok(()), None) => error,
            (Err(record), _) => WindowError::RecordLost {
                error: Box::new(error),
                record: Box::new(record),
            },
        });
    }
    if app.outcome.is_none() {
        app.end_session()?;
    }
    let outcome = app.outcome.take().ok_or(WindowError::NoOutcome)?;
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
        devices: std::mem::take(&mut app.device_runs),
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
    /// Desktop mode's screens.
    trainer: Option<Trainer>,
    shift: bool,
    sim: Option<SimThread>,
    /// The force-feedback devices' servo threads, and how they went once stopped.
    rig: Option<Rig>,
    device_runs: Vec<DeviceRun>,
    xr: Option<XrLoop>,
    /// Runtime, stereo frames, sessions and eye size of a finished XR session.
    xr_run: Option<(String, u64, u32, (u32, u32))>,
    view_mode: ViewMode,
    /// The mirrored eye's texture in egui.
    mirror_id: Option<egui::TextureId>,
    mirror_size: (u32, u32),
    /// The procedure's own picture (a fluoroscope's) as egui shows it, and the snapshot's
    /// copy it was made from; `teaching_view`: the 3D view instead (T).
    picture: Option<(Arc<crate::imaging::fluoro::Picture>, egui::TextureHandle)>,
    teaching_view: bool,
    scene_renders: u64,
    /// Simulated and wall time of the last window frame under XR.
    last_window_frame: Option<(f64, Instant)>,
    view: Option<View>,
    camera: OrbitCamera,
    /// The procedure's laparoscope as last applied to `camera` (the trainee drives it with a
    /// device: each new place it publishes moves the window's camera there).
    scope_seen: Option<crate::sim::ScopeView>,
    outcome: Option<Outcome>,
    frames: u64,
    shot: Option<((u32, u32), PathBuf)>,
    shot_taken: bool,
    error: Option<WindowError>,
    start: Instant,
}

/// Where the desktop trainee is: on the start screen, working, paused, or reading the results.
#[derive(Debug, Clone, Copy, Default)]
struct Trainer {
    started: bool,
    paused: bool,
    results: bool,
    /// Frames drawn with the results screen up.
    shown: u32,
}

impl App {
    /// Keeps the first failure (`run` returns it) and closes the window.
    fn fail(&mut self, el: &ActiveEventLoop, e: impl Into<WindowError>) {
        self.error.get_or_insert(e.into());
        el.exit();
    }
}

impl App {
    /// The session ended: keep its outcome, write its files, show its report.
    fn end_session(&mut self) -> Result<(), WindowError> {
        let mut device_error = None;
        let outcome = if let Some(sim) = self.sim.take() {
            // The servo loops stop first (their devices at zero force); their events join
            // the session's stream.
            let mut events = Vec::new();
            match self.rig.take().map(Rig::stop) {
                Some(Ok(mut runs)) => {
                    for r in &mut runs {
                        events.append(&mut r.servo.events);
                    }
                    self.device_runs = runs;
                }
                Some(Err(e)) => device_error = Some(e),
                None => {}
            }
            sim.finish_with(events)?
        } else if let Some(x) = self.xr.take() {
            let run = x.finish()?;
            self.xr_run = Some((run.runtime, run.frames, run.sessions, run.eye_size));
            self.device_runs = run.devices;
            device_error = run.device_error;
            run.outcome
        } else {
            return Ok(());
        };
        let written = match &self.opts.out {
            Some(dir) => {
                crate::session::write_outputs(&outcome, dir)?;
                Some(dir.display().to_string())
            }
            None => None,
        };
        if let (Some((file, trainee)), Some(dir)) = (&self.opts.records, &self.opts.out) {
            let mut r = crate::records::Db::open(file)?;
            r.store_dir(dir, trainee)?;
            let selected = Some(trainee.clone());
            self.dashboard.learning = Some(LearningCentre {
                selected,
                ..LearningCentre::read(&r.shown(), &mut r)?
            });
        }
        self.dashboard.summary = Some(Summary::from_report(&outcome.report, written));
        self.outcome = Some(outcome);
        // A device's failure, once the session's record is safe.
        match device_error {
            Some(e) => Err(e.into()),
            None => Ok(()),
        }
    }

    /// Over the procedure's own picture (the X-ray) the arrows are its pads': held down they
    /// turn the C-arm, with shift they move the table. True where the key was taken.
    fn pad_key(&mut self, key: &Key, down: bool) -> bool {
        let over_picture = self.picture.is_some() && !self.teaching_view;
        let dir = match key {
            Key::Named(NamedKey::ArrowLeft) => PadDirection::Left,
            Key::Named(NamedKey::ArrowRight) => PadDirection::Right,
            Key::Named(NamedKey::ArrowUp) => PadDirection::Up,
            Key::Named(NamedKey::ArrowDown) => PadDirection::Down,
            _ => return false,
        };
        match self.desktop.as_mut() {
            Some((h, _)) if over_picture && down => h.pad_key(Some(dir), self.shift),
            // Let go: both pads (shift may have been let go first).
            Some((h, _)) => h.pad_key(None, false) && h.pad_key(None, true),
            None => false,
        }
    }

    fn key(&mut self, key: &Key) {
        if self.pad_key(key, true) {
            return;
        }
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
                "p" | "P" => self.toggle_pause(),
                "t" | "T" => self.teaching_view = !self.teaching_view,
                other => {
                    if let Some((h, _)) = self.desktop.as_mut() {
                        h.imaging_key(other);
                    }
                }
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
            let file = &self.opts.scenario_file;
            let written = crate::scenario::with_tunables(
                &|text| crate::registry::plan(file, text).map(|_| ()),
                file,
                &self.opts.scenario_text,
                self.dashboard
                    .status
                    .tunables
                    .iter()
                    .map(|t| (t.model.as_str(), t.key, t.value)),
            )
            .map_err(SaveError::from)
            .and_then(|text| write_atomic(path, &text));
            self.dashboard.saved = Some(match written {
                Ok(()) => format!("saved to {}", path.display()),
                Err(e) => format!("not saved: {e}"),
            });
        }
    }

    /// Desktop mode: pauses the session, or lets it go on (not before it starts or after it
    /// ends).
    fn toggle_pause(&mut self) {
        if let (Some(t), Some(sim)) = (self.trainer.as_mut(), &self.sim)
            && t.started
            && !t.results
        {
            t.paused = !t.paused;
            sim.set_paused(t.paused);
        }
    }

    /// What the trainee did on a screen.
    fn on_screens(&mut self, el: &ActiveEventLoop, a: super::screens::ScreenActions) {
        let Some(t) = self.trainer.as_mut() else {
            return;
        };
        if a.start || a.resume {
            t.started = true;
            t.paused = false;
            if let Some(sim) = &self.sim {
                sim.set_paused(false);
            }
        }
        if a.close {
            el.exit();
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
                // End the session, and draw its last frame (taking the screenshot if due). A
                // desktop trainee's session that began shows its results first: the next
                // close (or the results' Close) closes the window.
                let results = match self.trainer.as_mut() {
                    Some(t) if t.started && !t.results => {
                        t.results = true;
                        true
                    }
                    _ => false,
                };
                if let Err(e) = self.end_session().and_then(|()| self.redraw(el)) {
                    self.fail(el, e);
                }
                if !results {
                    el.exit();
                }
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
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Released => {
                self.pad_key(&event.logical_key, false);
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
                x.interrupted();
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
                    let t = x.time_s();
                    due = self.last_window_frame.is_none_or(|(s, wall)| {
                        t - s >= 1.0 / 30.0 || wall.elapsed().as_secs_f64() >= 0.1
                    });
                }
                Err(e) => self.fail(el, e),
            }
        }
        if due && let Some(v) = &self.view {
            let t = self.xr.as_mut().map_or(0.0, |x| x.time_s());
            self.last_window_frame = Some((t, Instant::now()));
            v.window.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failure_says_what_became_of_the_session() {
        let kept = WindowError::Kept {
            error: Box::new(WindowError::NoOutcome),
            dir: PathBuf::from("out/run1"),
        };
        assert_eq!(
            kept.to_string(),
            "the session ended without an outcome (the session so far is in out/run1)"
        );
        let lost = WindowError::RecordLost {
            error: Box::new(WindowError::SurfaceUnsupported),
            record: Box::new(WindowError::UnknownProcedure("x".into())),
        };
        assert_eq!(
            lost.to_string(),
            "this GPU cannot draw into the window (and its record could not be written: \
             unknown procedure 'x')"
        );
    }

    #[test]
    fn a_scenario_that_cannot_be_saved_names_the_file() {
        let e = write_atomic(std::path::Path::new("/proc/no-such/tuned.toml"), "x")
            .expect_err("/proc is not writable");
        assert!(
            matches!(&e, SaveError::Write { path, .. } if path.starts_with("/proc")),
            "{e:?}"
        );
        assert!(e.to_string().starts_with("/proc/no-such"), "{e}");
    }
}
