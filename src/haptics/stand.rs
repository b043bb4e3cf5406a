//! The servo loop against a procedure, as `vesalius haptics` runs it: the procedure steps in
//! real time on a simulation thread, its instrument following the stylus (mapped into the field
//! through a [`Workspace`]), and publishes a haptic frame every step; the servo loop runs on
//! its own thread at 1 kHz. Neither waits on the other: they meet in two lock-free slots.

use super::device::{DeviceState, HapticDevice, HapticsError};
use super::render::Workspace;
use super::safety::SafetyParams;
use super::servo::{ServoConfig, ServoLinks, ServoReport, held_off_notice, run_servo};
use crate::procedures::{ProcedureInfo, ToolKind};
use crate::session::{Live, SessionError, interrupt};
use crate::sim::{Hand, InputFrame, Pacing, Pose};
use glam::{DVec3, Vec3};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// How far above the point the procedure's viewpoint looks at the device's origin lands, m:
/// for the sandbox, 15 mm above its block's top.
pub const ORIGIN_ABOVE_TARGET_M: f32 = 0.03;

impl Workspace {
    /// The workspace for `info`: scale 1, the device's origin [`ORIGIN_ABOVE_TARGET_M`] above
    /// the point its viewpoint looks at (for the sandbox, (0, 0.045, 0)).
    pub fn for_procedure(info: &ProcedureInfo) -> Workspace {
        Workspace {
            scale: 1.0,
            offset_m: info.view.target + Vec3::Y * ORIGIN_ABOVE_TARGET_M,
        }
    }
}

/// What a stand runs.
#[derive(Debug, Clone, Copy)]
pub struct StandOptions {
    pub procedure: &'static ProcedureInfo,
    /// How long the servo loop runs, s.
    pub seconds: f64,
    pub workspace: Workspace,
    pub safety: SafetyParams,
}

impl StandOptions {
    /// `seconds` of `procedure` with its workspace and the default safety figures.
    pub fn new(procedure: &'static ProcedureInfo, seconds: f64) -> StandOptions {
        StandOptions {
            procedure,
            seconds,
            workspace: Workspace::for_procedure(procedure),
            safety: SafetyParams::default(),
        }
    }
}

/// How a stand went.
#[derive(Debug, Clone)]
pub struct StandReport {
    pub servo: ServoReport,
    /// The hand whose instrument the device drove.
    pub hand: Hand,
    /// Simulation steps made.
    pub sim_steps: u64,
    /// Simulated seconds.
    pub sim_s: f64,
}

/// A thread pool for a simulation that shares the machine with `servos` servo loops: the
/// cores left once each servo has one (at least one thread), never more than the global
/// pool has (`--threads`). A servo that has to share its core with the simulation's workers
/// misses deadlines; the simulation's results do not depend on its pool's size.
pub fn sim_pool(servos: usize) -> Result<rayon::ThreadPool, HapticsError> {
    let cores = std::thread::available_parallelism().map_or(1, usize::from);
    let threads = cores
        .saturating_sub(servos)
        .clamp(1, rayon::current_num_threads().max(1));
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|k| format!("vesalius-sim-{k}"))
        .build()
        .map_err(|e| HapticsError::Thread(format!("cannot start the simulation's threads: {e}")))
}

/// The hand a single device drives: the procedure's probe, else the right.
pub fn device_hand(info: &ProcedureInfo) -> Hand {
    let held = |kind: ToolKind| info.tools.iter().find(|t| t.kind == kind);
    held(ToolKind::Steerable)
        .or_else(|| held(ToolKind::Probe))
        .map_or(Hand::Right, |t| t.hand)
}

/// One step's input: the device's instrument where the stylus is (pointing down), its buttons
/// (bit 0: trigger, bit 1: grip); the other instrument parked where the desktop mode parks it,
/// pointing down.
pub fn input_frame(
    info: &ProcedureInfo,
    hand: Hand,
    workspace: &Workspace,
    stylus: &DeviceState,
) -> InputFrame {
    let down = |p: Vec3| Pose::looking_at(p, p - Vec3::Y);
    let mut frame = InputFrame::default();
    for h in Hand::BOTH {
        frame.hands[h.index()].pose = down(info.desk_park[h.index()]);
    }
    let held = &mut frame.hands[hand.index()];
    held.pose = down(workspace.to_field(stylus.position_m));
    held.buttons.trigger = f32::from(u8::from(stylus.buttons & 1 != 0));
    held.buttons.grip = f32::from(u8::from(stylus.buttons & 2 != 0));
    frame
}

/// Runs `device` against its options' procedure for `seconds`: the servo loop and the
/// simulation on two threads of their own. SIGINT or SIGTERM ends it early.
pub fn run_stand(
    device: &mut dyn HapticDevice,
    opts: &StandOptions,
) -> Result<StandReport, HapticsError> {
    let info = opts.procedure;
    let file = format!("builtin {} scenario", info.name);
    let mut live = Live::new(info.scenario, &file, Pacing::RealTime).map_err(Box::new)?;
    let hand = device_hand(info);
    let links = ServoLinks::new(live.haptics(), Arc::new(AtomicBool::new(false)));
    let notice = held_off_notice(device.name(), hand);
    let config = ServoConfig {
        hand,
        workspace_scale: opts.workspace.scale,
        safety: opts.safety,
        duration_s: opts.seconds,
        ..ServoConfig::default()
    };
    let workspace = opts.workspace;
    let pool = sim_pool(1)?;
    let (servo, sim) = std::thread::scope(|s| {
        let sim_links = links.clone();
        let pool = &pool;
        let sim = std::thread::Builder::new()
            .name("vesalius-sim".into())
            .spawn_scoped(s, move || -> Result<(u64, f64), SessionError> {
                pool.install(|| {
                    let stop = &sim_links.stop;
                    // Until the servo's first tick the stylus is at the device's origin.
                    let mut last = DeviceState::default();
                    let mut said = false;
                    let result = loop {
                        if !said && sim_links.held_off.load(Ordering::Relaxed) {
                            said = true;
                            eprintln!("{notice}");
                        }
                        if stop.load(Ordering::Relaxed) {
                            break Ok(());
                        }
                        if interrupt::interrupted().is_some() {
                            break Ok(());
                        }
                        if let Some(s) = sim_links.stylus.latest()
                            && s.position_m.is_finite()
                        {
                            last = s;
                        }
                        if let Err(e) = live.step(input_frame(info, hand, &workspace, &last)) {
                            break Err(e);
                        }
                    };
                    // Whatever ended the simulation ends the servo loop.
                    stop.store(true, Ordering::Relaxed);
                    result.map(|()| (live.step_count(), live.time_s()))
                })
            });
        let servo = std::thread::Builder::new()
            .name("vesalius-servo".into())
            .spawn_scoped(s, || run_servo(device, &links, &config));
        let servo = match servo {
            Ok(h) => h.join(),
            Err(e) => Ok(Err(HapticsError::Thread(format!(
                "cannot start the servo thread: {e}"
            )))),
        };
        links.stop.store(true, Ordering::Relaxed);
        let sim = match sim {
            Ok(h) => h.join(),
            Err(e) => Ok(Err(SessionError::Io {
                path: "simulation thread".into(),
                source: e,
            })),
        };
        (servo, sim)
    });
    let panicked = |what: &str| HapticsError::Thread(format!("the {what} thread panicked"));
    let servo = servo.map_err(|_| panicked("servo"))??;
    let (sim_steps, sim_s) = sim.map_err(|_| panicked("simulation"))?.map_err(Box::new)?;
    Ok(StandReport {
        servo,
        hand,
        sim_steps,
        sim_s,
    })
}

/// The device position that lands at `field_m` (the workspace map's inverse).
pub fn device_position_for(workspace: &Workspace, field_m: Vec3) -> DVec3 {
    (field_m - workspace.offset_m).as_dvec3() / workspace.scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stylus_drives_the_probe_and_the_other_tool_is_parked() {
        let info = &crate::procedures::sandbox::INFO;
        let hand = device_hand(info);
        assert_eq!(hand, Hand::Right);
        let w = Workspace::for_procedure(info);
        assert!(w.offset_m.distance(Vec3::new(0.0, 0.045, 0.0)) < 1e-6);
        let target = Vec3::new(0.01, 0.03, -0.005);
        let stylus = DeviceState {
            position_m: device_position_for(&w, target),
            buttons: 2,
            ..DeviceState::default()
        };
        let f = input_frame(info, hand, &w, &stylus);
        let probe = f.hand(Hand::Right);
        assert!(probe.pose.position.distance(target) < 1e-6);
        assert!(probe.pose.forward().distance(-Vec3::Y) < 1e-6);
        assert_eq!((probe.buttons.trigger, probe.buttons.grip), (0.0, 1.0));
        assert_eq!(f.hand(Hand::Left).pose.position, info.desk_park[0]);
    }
}
