//! The trainee in the headset: an OpenXR session (any runtime: SteamVR, Monado, or the
//! simulated one) drives the simulation. Each frame the app waits for the runtime's display
//! time, reads both controllers and hands the reading to the simulation's own thread, which
//! steps up to that time (the controller poses interpolated between frames, so the
//! instruments move at the simulation's rate; see [`stepper`]); it vibrates the controllers
//! with the contact force and with pulses for grasps, cuts and tears (see [`vibration`]), and
//! draws both eyes of the newest state into the swapchain in one multiview pass. The frame
//! loop does not wait for the simulation unless asked to ([`Coupling::Lockstep`]).
//!
//! Each controller holds the instrument its procedure gives that hand: the aim-pose ray is the
//! instrument's axis, the trigger its trigger (a laser cuts), the grip its jaws, the trackpad
//! click its mark button. A controller that stops tracking
//! freezes its instrument and raises `controller_lost`; a lost session stops the simulation,
//! keeps its record, and a new session carries on when the headset returns.
//!
//! Force-feedback styluses may drive instruments instead ([`XrDevices`]): a hand bound to a
//! stylus follows it, its servo loop renders the tissue's force at 1 kHz on a thread of its
//! own, and the other hand (if any) follows its controller. The simulation then steps in
//! real time, so that the servo loops get a haptic frame every step rather than a burst each
//! display frame.

use crate::profiler::FrameCounters;
use crate::render::{EyeView, Fov, Gpu, RenderError, RenderTarget, Renderer};
use crate::scenario::HeadsetView;
use crate::session::{Live, Outcome, SessionError, Status};
use crate::sim::{Buttons, EventKind, Hand, HandInput, Pacing, PadDirection, Pose, Snapshot};
use glam::{Quat, Vec3};
use std::sync::Arc;
use xr_bindings::app::{EYE_FORMAT, HandReading, XrApp, XrError, XrSession};
use xr_bindings::openxr as xr;
use xr_bindings::{Command, SessionMachine};

pub mod room;
pub mod stepper;
pub mod vibration;
pub use stepper::{Coupling, Stepper};
pub use vibration::{
    AMPLITUDE_FLOOR, Buzz, FORCE_FLOOR_N, FrameFeel, HapticProfile, Order, Pulse, Vibrator,
};

/// What a run under an XR runtime did.
pub struct XrRun {
    pub outcome: Outcome,
    pub runtime: String,
    /// Frames submitted with a stereo projection layer.
    pub frames: u64,
    /// Sessions started (more than one after a loss).
    pub sessions: u32,
    /// Display time the simulation was let fall behind by, paced, so that it kept within
    /// [`XrOptions::max_lag_s`] of the frames, s (0: it kept up).
    pub slowed_s: f64,
    pub eye_size: (u32, u32),
    pub device: String,
    /// How each force-feedback device went (none without styluses).
    pub devices: Vec<crate::haptics::DeviceRun>,
    /// A device's fault, if one ended its servo loop (the session is kept all the same).
    pub device_error: Option<crate::haptics::HapticsError>,
}

/// Force-feedback devices bound to the instruments of a session in the headset: one drives
/// the procedure's probe (else its right-hand instrument), two drive both hands.
pub struct XrDevices {
    pub devices: Vec<Box<dyn crate::haptics::HapticDevice>>,
    pub options: crate::haptics::RigOptions,
}

/// How long to run, and at what eye size.
#[derive(Debug, Clone, Default)]
pub struct XrOptions {
    /// Stop after this much simulated time, seconds (the trace's length under the simulated
    /// runtime); none: until the trainee presses the menu button.
    pub duration_s: Option<f64>,
    /// Per-eye image size; none: the runtime's recommendation.
    pub eye_size: Option<(u32, u32)>,
    /// Whether frames wait for the simulation (see [`Coupling`]).
    pub coupling: Coupling,
    /// Paced: the most the simulation may fall behind the frames' display times, s (none:
    /// no bound, every frame's time is stepped). A simulation slower than real time then
    /// runs slower than the display's clock instead of drawing an ever older state.
    pub max_lag_s: Option<f64>,
    /// An assessment tree to score the session with instead of the procedure's own (its
    /// file's name, for errors, and the tree): its rules give the instructions.
    pub assessment: Option<(String, crate::assess::Tree)>,
}

/// Why a run in the headset stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum XrRunError {
    /// An OpenXR call (or the loader, runtime, headset or its Vulkan device) failed.
    #[error(transparent)]
    Xr(#[from] XrError),
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The scenario, the output folder or the recording.
    #[error(transparent)]
    Session(#[from] SessionError),
    #[error("the headset did not come back within 60 s")]
    HeadsetGone,
    #[error("the runtime located fewer than two views")]
    TooFewViews,
    /// A force-feedback device could not be bound (its servo thread did not start).
    #[error(transparent)]
    Haptics(#[from] crate::haptics::HapticsError),
}

/// A frame-loop call's result, its error named after the OpenXR function.
fn call<T>(name: &'static str, r: xr::Result<T>) -> Result<T, XrRunError> {
    r.map_err(|result| XrRunError::Xr(XrError::Call { call: name, result }))
}

fn field_pose(aim: ([f32; 3], [f32; 4])) -> Pose {
    Pose {
        position: xr_bindings::stage::stage_to_field(Vec3::from(aim.0)),
        orientation: Quat::from_array(aim.1).normalize(),
    }
}

fn eye_view(v: &xr::View) -> EyeView {
    let (p, q) = (v.pose.position, v.pose.orientation);
    EyeView {
        position: xr_bindings::stage::stage_to_field(Vec3::new(p.x, p.y, p.z)),
        orientation: Quat::from_xyzw(q.x, q.y, q.z, q.w).normalize(),
        fov: Fov {
            left: v.fov.angle_left,
            right: v.fov.angle_right,
            up: v.fov.angle_up,
            down: v.fov.angle_down,
        },
    }
}

/// Input between two frames' readings, `s` of the way (0..1). An instrument that did not
/// move (a lost controller's) stays exactly where it is.
fn between(a: &HandInput, b: &HandInput, s: f32) -> HandInput {
    let (p, q) = (a.pose.position, a.pose.orientation);
    HandInput {
        pose: Pose {
            position: p + (b.pose.position - p) * s,
            orientation: if q == b.pose.orientation {
                q
            } else {
                q.slerp(b.pose.orientation, s)
            },
        },
        buttons: Buttons {
            trigger: a.buttons.trigger + (b.buttons.trigger - a.buttons.trigger) * s,
            grip: a.buttons.grip + (b.buttons.grip - a.buttons.grip) * s,
            mark: b.buttons.mark,
            pad: b.buttons.pad,
        },
    }
}

/// Which picture the desktop mirror shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MirrorEye {
    Left,
    Right,
}

/// A copy of one eye of each submitted frame, for the desktop mirror: the swapchain layer is
/// copied on the GPU before the image goes back to the runtime, so the scene is not drawn again.
pub struct Mirror {
    pub eye: MirrorEye,
    pub size: (u32, u32),
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
}

impl Mirror {
    fn new(device: &wgpu::Device, size: (u32, u32), eye: MirrorEye) -> Mirror {
        let texture = crate::render::gpu::colour_texture(
            device,
            "xr mirror",
            size,
            1,
            EYE_FORMAT,
            wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        Mirror {
            eye,
            size,
            texture,
            view,
        }
    }
}

/// What one pass of the frame loop did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tick {
    /// A frame was submitted (with `rendered` stereo images or an empty one).
    Frame { rendered: bool },
    /// The session is not running frames yet (or any more): nothing was submitted.
    Idle,
    /// The runtime ended the session; call [`XrLoop::finish`].
    Exit,
}

/// The XR frame loop, one frame a [`XrLoop::tick`], so that a desktop window can run beside
/// it on the same thread (winit owns the main thread; OpenXR's frame calls may come from it).
pub struct XrLoop {
    app: XrApp,
    pub gpu: Gpu,
    renderer: Renderer,
    eye: (u32, u32),
    sim: Stepper,
    /// The styluses' servo loops, where styluses drive instruments.
    rig: Option<crate::haptics::Rig>,
    /// How the session will say it ended (unless the simulation ended it first).
    ending: &'static str,
    opts: XrOptions,
    dt: f64,
    machine: SessionMachine,
    session: Option<(XrSession, xr::FrameWaiter, xr::FrameStream<xr::Vulkan>)>,
    /// The input each hand last gave (a lost controller's instrument stays there).
    held: [HandInput; 2],
    /// The port each hand's instrument passes through (a monitor's room; none: held freely).
    ports: [Option<Vec3>; 2],
    /// Whether each controller was tracked at the last focused frame (none yet: unknown).
    tracked: [Option<bool>; 2],
    vibrator: Vibrator,
    frames: u64,
    sessions: u32,
    /// Display time (ns) that corresponds to simulated time 0 in the current session.
    origin: Option<i64>,
    /// See [`XrRun::slowed_s`].
    slowed_s: f64,
    exit_asked: bool,
    buf: xr::EventDataBuffer,
    /// The desktop mirror's copy of one eye, if a window wants it.
    pub mirror: Option<Mirror>,
    /// The last stereo frame's profiler counters.
    pub counters: FrameCounters,
}

impl XrLoop {
    /// Opens the runtime, its Vulkan device and the procedure; the first session starts at
    /// the first [`XrLoop::tick`].
    pub fn open(
        scenario_text: &str,
        scenario_file: &str,
        opts: XrOptions,
        out: Option<&std::path::Path>,
        devices: Option<XrDevices>,
    ) -> Result<XrLoop, XrRunError> {
        let (app, xg) = XrApp::open("vesalius")?;
        let gpu = Gpu::from_parts(xg.instance, xg.adapter, xg.device, xg.queue, xg.multiview);
        let mut renderer = Renderer::new(&gpu, EYE_FORMAT)?;
        let eye = opts.eye_size.unwrap_or(app.eye_size);
        gpu.check_eye_size(eye)?;
        // Styluses: steps in real time, each publishing the servo loops' frame (not a burst
        // of steps each display frame, between which a servo loop would see a stall).
        let pacing = if devices.is_some() {
            Pacing::RealTime
        } else {
            Pacing::AsFastAsPossible
        };
        let mut live = Live::new(scenario_text, scenario_file, pacing)?;
        if let Some((file, tree)) = &opts.assessment {
            live.set_assessment(file, tree.clone())?;
        }
        // In the headset, as the scenario says: the operative field all around in the scope's
        // light (no image circle), or the scope's picture on a monitor across the table, the
        // laparoscopic instruments then passing their ports.
        let info = live.info();
        renderer.set_field(Some(&(info.field)().mesh()));
        let headset = crate::scenario::headset_of(scenario_file, scenario_text)
            .map_err(SessionError::from)?;
        let ports = match headset.view {
            HeadsetView::Scope => {
                renderer.set_optics(crate::render::optics::Optics::headset(&info.view));
                [None; 2]
            }
            HeadsetView::Monitor => {
                renderer.set_monitor(Some(room::monitor(info)))?;
                room::ports(info)
            }
        };
        if let Some(dir) = out {
            crate::session::prepare(dir)?;
            live.stream_to(&dir.join(crate::session::RECORDING))?;
        }
        let dt = f64::from(live.dt_s());
        let vibrator = Vibrator::new(&live.info().tools);
        // Until a controller is first tracked, its instrument waits where the procedure parks
        // it, over the field pointing away (not at the origin, inside the organ).
        let parked = live.info().desk_park.map(|at| HandInput {
            pose: Pose::looking_at(at, at + glam::Vec3::Y),
            buttons: Buttons::default(),
        });
        let (rig, input) = match devices {
            Some(d) => {
                let (rig, input) =
                    crate::haptics::Rig::start(d.devices, live.info(), live.haptics(), d.options)?;
                (Some(rig), Some(input))
            }
            None => (None, None),
        };
        let sim = Stepper::start(live, opts.coupling, input)?;
        Ok(XrLoop {
            rig,
            app,
            gpu,
            renderer,
            eye,
            sim,
            ending: crate::session::ended::XR_EXIT,
            opts,
            dt,
            machine: SessionMachine::new(),
            session: None,
            held: parked,
            ports,
            tracked: [None; 2],
            vibrator,
            frames: 0,
            sessions: 0,
            origin: None,
            slowed_s: 0.0,
            exit_asked: false,
            buf: xr::EventDataBuffer::new(),
            mirror: None,
            counters: FrameCounters::default(),
        })
    }

    /// Starts copying `eye` of every frame into [`XrLoop::mirror`].
    /// Where the headset shows a monitor, the mirror shows the monitor's picture (what the
    /// trainee operates by), whichever eye is asked for.
    pub fn mirror_eye(&mut self, eye: MirrorEye) {
        let size = self.renderer.monitor_picture().map_or(self.eye, |(_, s)| s);
        match &mut self.mirror {
            Some(m) => m.eye = eye,
            None => self.mirror = Some(Mirror::new(&self.gpu.device, size, eye)),
        }
    }

    /// The runtime's name ("SteamVR/OpenXR", "Monado", ...).
    pub fn runtime_name(&self) -> &str {
        &self.app.runtime_name
    }

    /// The simulation's newest status, for the panels.
    pub fn status(&self) -> Arc<Status> {
        self.sim.status()
    }

    /// The simulation's newest state, for a third-person view.
    pub fn snapshot(&self) -> Arc<Snapshot> {
        self.sim.snapshot()
    }

    /// Where the simulation stands (as of the last frame it reported done), s.
    pub fn time_s(&self) -> f64 {
        self.sim.time_s()
    }

    /// The session is to end as interrupted (SIGINT or SIGTERM) at [`XrLoop::finish`].
    pub fn interrupted(&mut self) {
        self.ending = crate::session::ended::INTERRUPTED;
    }

    /// Polls the runtime's events, then waits for, simulates, draws and submits one frame
    /// when the session runs.
    pub fn tick(&mut self) -> Result<Tick, XrRunError> {
        if crate::session::interrupt::interrupted().is_some() {
            self.interrupted();
            return Ok(Tick::Exit);
        }
        // A stylus's servo loop ended (a device fault): so does the session.
        if self.rig.as_ref().is_some_and(crate::haptics::Rig::stopped) {
            self.ending = crate::session::ended::DEVICE_STOPPED;
            return Ok(Tick::Exit);
        }
        if self.session.is_none() {
            let s = self.app.session(&self.gpu.device, self.eye)?;
            self.session = Some(s);
            self.sessions += 1;
            if self.sessions > 1 {
                self.sim.note(EventKind::SessionRestarted)?;
                self.machine.recreated();
                self.origin = None;
                self.exit_asked = false;
            }
        }
        while let Some(ev) = self.app.poll(&mut self.buf)? {
            let xr::Event::SessionStateChanged(e) = ev else {
                continue;
            };
            let Some((xs, _, _)) = self.session.as_ref() else {
                break;
            };
            match self.machine.on_state(e.state()) {
                Some(Command::BeginSession) => {
                    call(
                        "xrBeginSession",
                        xs.session.begin(xr::ViewConfigurationType::PRIMARY_STEREO),
                    )?;
                }
                Some(Command::EndSession) => {
                    call("xrEndSession", xs.session.end())?;
                }
                Some(Command::Exit) => return Ok(Tick::Exit),
                Some(Command::Recreate) => {
                    self.sim.note(EventKind::SessionLost)?;
                    self.vibrator.reset();
                    self.session = None;
                    // Wait for the headset to come back (a real runtime: minutes at most).
                    let mut tries = 0u32;
                    while !self.app.headset_present() {
                        tries += 1;
                        if tries > 600 {
                            return Err(XrRunError::HeadsetGone);
                        }
                        std::thread::sleep(std::time::Duration::from_millis(100));
                    }
                    return Ok(Tick::Idle);
                }
                _ => {}
            }
        }
        if !self.machine.submits_frames() {
            std::thread::sleep(std::time::Duration::from_millis(1));
            return Ok(Tick::Idle);
        }
        self.frame()
    }

    fn frame(&mut self) -> Result<Tick, XrRunError> {
        let dt = self.dt;
        let lockstep = self.opts.coupling == Coupling::Lockstep;
        let Some((xs, waiter, stream)) = self.session.as_mut() else {
            return Ok(Tick::Idle);
        };
        let fs = call("xrWaitFrame", waiter.wait())?;
        call("xrBeginFrame", stream.begin())?;
        let t = fs.predicted_display_time;
        let sim = &mut self.sim;
        let o = match self.origin {
            Some(o) => o,
            None => {
                // A session's first frame: simulated time carries on from where the
                // simulation is, so wait for it to get there.
                sim.collect(true)?;
                *self
                    .origin
                    .insert(t.as_nanos() - (sim.time_s() * 1e9).round() as i64)
            }
        };
        let mut target_s = (t.as_nanos() - o) as f64 / 1e9;
        // Paced, a simulation slower than real time falls behind the frames. Past the bound
        // its time runs slower than the display's (the origin moves on by the excess), so no
        // frame draws an older state and no step takes older hands than that.
        if let (false, Some(most)) = (lockstep, self.opts.max_lag_s) {
            let excess = target_s - sim.time_s() - most;
            if excess > 0.0 {
                let ns = (excess * 1e9).round() as i64;
                self.origin = Some(o + ns);
                target_s = (t.as_nanos() - o - ns) as f64 / 1e9;
                if self.slowed_s == 0.0 {
                    tracing::warn!(
                        "the simulation is behind the headset by more than {most} s: it runs \
                         slower than real time from here"
                    );
                }
                self.slowed_s += ns as f64 / 1e9;
            }
        }
        if let Some(d) = self.opts.duration_s {
            target_s = target_s.min(d);
        }
        let focused = self.machine.focused();
        let readings = if focused {
            xs.read_hands(&self.app.controls, t)?
        } else {
            [HandReading::default(); 2]
        };
        let mut now = self.held;
        for h in Hand::BOTH {
            let k = h.index();
            let r = readings[k];
            let is_tracked = r.aim.is_some();
            if focused {
                // A change is an event; the first reading is not.
                if self.tracked[k].is_some_and(|was| was != is_tracked) {
                    let hand = h.name().to_string();
                    sim.note(if is_tracked {
                        EventKind::ControllerRegained { hand }
                    } else {
                        EventKind::ControllerLost { hand }
                    })?;
                }
                self.tracked[k] = Some(is_tracked);
            }
            if let Some(aim) = r.aim {
                let pose = field_pose(aim);
                now[k] = HandInput {
                    pose: self.ports[k].map_or(pose, |port| room::through_port(pose, port)),
                    buttons: Buttons {
                        trigger: r.trigger,
                        grip: if r.squeeze { 1.0 } else { 0.0 },
                        mark: r.click,
                        pad: PadDirection::of_click(r.click, r.pad),
                    },
                };
            }
        }
        // The simulation steps up to the display time on its own thread, inputs interpolated.
        sim.frame(target_s, now)?;
        self.held = now;
        // What the hands felt in the steps done so far (lockstep: this frame's).
        let feel = sim.collect(lockstep)?;
        // Contact buzz and event pulses; a stop when they end.
        if focused {
            let tracked = self.tracked.map(|t| t == Some(true));
            let orders = self.vibrator.orders(sim.time_s(), &feel, tracked);
            for (k, order) in orders.into_iter().enumerate() {
                match order {
                    Order::Vibrate(b) => {
                        xs.vibrate(
                            &self.app.controls,
                            k,
                            b.amplitude,
                            b.frequency_hz,
                            b.duration_s,
                        )?;
                    }
                    Order::Stop => xs.stop_vibration(&self.app.controls, k)?,
                    Order::Nothing => {}
                }
            }
        }
        let rendered = fs.should_render;
        if rendered {
            let views = xs.views(t)?;
            if views.len() < 2 {
                return Err(XrRunError::TooFewViews);
            }
            let eyes = [eye_view(&views[0]), eye_view(&views[1])];
            // The dynamic assessment's current instructions, in a panel before the eyes.
            self.renderer.show_lines(&sim.status().current_instructions);
            self.renderer.update(&sim.snapshot());
            let multiview = self.gpu.multiview;
            let copy = self.mirror.as_ref().map(|m| (m, &self.gpu));
            self.counters = draw(xs, &mut self.renderer, self.eye, &eyes, multiview, copy)?;
            xs.end_frame(stream, t, &views)?;
            self.frames += 1;
        } else {
            call(
                "xrEndFrame",
                stream.end(t, xr::EnvironmentBlendMode::OPAQUE, &[]),
            )?;
        }
        self.gpu.check()?;
        // Lockstep: done once the simulation is there; paced: once its last steps are asked
        // for (it catches up before the session ends).
        let done = self.opts.duration_s.is_some_and(|d| {
            if lockstep {
                sim.time_s() + dt * 0.5 > d
            } else {
                target_s >= d
            }
        });
        if done && !self.exit_asked && self.machine.focused() {
            call("xrRequestExitSession", xs.session.request_exit())?;
            self.exit_asked = true;
        }
        Ok(Tick::Frame { rendered })
    }

    /// Ends the loop: the simulation steps what it was sent, and the session's outcome.
    pub fn finish(self) -> Result<XrRun, XrRunError> {
        let device = self.gpu.describe();
        let mut live = self.sim.finish(self.ending)?;
        // The servo loops stop with the simulation; their safety events join the session's.
        let (mut devices, device_error) = match self.rig.map(crate::haptics::Rig::stop) {
            Some(Ok(runs)) => (runs, None),
            Some(Err(e)) => (Vec::new(), Some(e)),
            None => (Vec::new(), None),
        };
        for r in &mut devices {
            live.merge_events(std::mem::take(&mut r.servo.events));
        }
        Ok(XrRun {
            devices,
            device_error,
            outcome: live.finish(Vec::new())?,
            runtime: self.app.runtime_name.clone(),
            frames: self.frames,
            sessions: self.sessions,
            slowed_s: self.slowed_s,
            eye_size: self.eye,
            device,
        })
    }
}

/// Runs the procedure in the headset until `duration_s` or the menu button (styluses, where
/// given, drive their hands' instruments); the recording streams into `out` while it runs.
pub fn run(
    scenario_text: &str,
    scenario_file: &str,
    opts: XrOptions,
    out: Option<&std::path::Path>,
    devices: Option<XrDevices>,
) -> Result<XrRun, XrRunError> {
    let mut xr_loop = XrLoop::open(scenario_text, scenario_file, opts, out, devices)?;
    while xr_loop.tick()? != Tick::Exit {}
    xr_loop.finish()
}

fn draw(
    xs: &mut XrSession,
    renderer: &mut Renderer,
    eye: (u32, u32),
    eyes: &[EyeView; 2],
    multiview: bool,
    mirror: Option<(&Mirror, &Gpu)>,
) -> Result<FrameCounters, xr_bindings::app::XrError> {
    let mut counters = FrameCounters::default();
    xs.draw(|texture| {
        let (array, layers) = crate::render::gpu::eye_views(texture);
        let target = if multiview {
            RenderTarget::Array(&array)
        } else {
            RenderTarget::PerEye([&layers[0], &layers[1]])
        };
        counters = renderer.render(target, eye, eyes);
        // The mirror's eye, copied before the image goes back to the runtime (or the
        // monitor's picture, where the eyes see a monitor).
        if let Some((m, gpu)) = mirror {
            let (texture, layer) = match (renderer.monitor_picture(), m.eye) {
                (Some((picture, _)), _) => (picture, 0),
                (None, MirrorEye::Left) => (texture, 0),
                (None, MirrorEye::Right) => (texture, 1),
            };
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("mirror copy"),
                });
            encoder.copy_texture_to_texture(
                crate::gpu::texture_layer(texture, layer),
                crate::gpu::texture_layer(&m.texture, 0),
                wgpu::Extent3d {
                    width: m.size.0,
                    height: m.size.1,
                    depth_or_array_layers: 1,
                },
            );
            gpu.queue.submit([encoder.finish()]);
        }
    })?;
    Ok(counters)
}
