//! A recorded session driven by force-feedback devices without a window (`vesalius run
//! <procedure> --haptics D[,D] --no-window`): one device drives the procedure's probe (else its
//! right-hand instrument), two drive the left and the right hand's instruments (the papers'
//! two hands). The procedure steps in real time on this thread, on the cores the servo loops
//! leave free, and publishes a haptic frame every step; each device has its servo loop on a
//! thread of its own at 1 kHz ([`Rig`]). No thread waits on another: they meet in lock-free
//! slots. The session records its input and writes its report as any other does, so it
//! replays bit for bit; the servo loops' safety events join its event stream.

use super::device::{HapticDevice, HapticsError};
use super::rig::{DeviceRun, Rig, RigOptions};
use super::safety::SafetyParams;
use crate::session::{Live, Outcome, SessionError, ended, interrupt};
use crate::sim::Pacing;
use std::path::Path;

/// What a device-driven session runs.
#[derive(Debug, Clone, Copy)]
pub struct BoundOptions<'a> {
    pub scenario_text: &'a str,
    pub scenario_file: &'a str,
    /// Where the recording streams (the folder was prepared); none: kept in memory.
    pub out: Option<&'a Path>,
    /// Simulated seconds before the session ends (SIGINT or SIGTERM end it earlier).
    pub seconds: f64,
    /// Field metres per device metre.
    pub scale: f64,
    pub safety: SafetyParams,
}

/// How a device-driven session went.
pub struct BoundRun {
    pub outcome: Outcome,
    pub devices: Vec<DeviceRun>,
}

/// Runs a session with `devices` (one or two) bound to the procedure's instruments.
pub fn run_bound(
    devices: Vec<Box<dyn HapticDevice>>,
    opts: &BoundOptions,
) -> Result<BoundRun, HapticsError> {
    let mut live =
        Live::new(opts.scenario_text, opts.scenario_file, Pacing::RealTime).map_err(Box::new)?;
    if let Some(dir) = opts.out {
        live.stream_to(&dir.join(crate::session::RECORDING))
            .map_err(Box::new)?;
    }
    let pool = super::stand::sim_pool(devices.len())?;
    let rig_opts = RigOptions {
        scale: opts.scale,
        safety: opts.safety,
        // The servo loops end when the session does (this is only a backstop, well past the
        // session's end even at a fraction of real time).
        backstop_s: 4.0 * opts.seconds + 10.0,
    };
    let (rig, mut input) = Rig::start(devices, live.info(), live.haptics(), rig_opts)?;
    let stepped = pool.install(|| -> Result<(), SessionError> {
        loop {
            if input.stopped() {
                return Ok(());
            }
            if interrupt::interrupted().is_some() {
                live.set_ended(ended::INTERRUPTED);
                return Ok(());
            }
            if live.time_s() >= opts.seconds {
                live.set_ended(ended::TIME_UP);
                return Ok(());
            }
            live.step(input.frame())?;
        }
    });
    // Whatever ended the simulation ends the servo loops.
    let runs = rig.stop();
    stepped.map_err(Box::new)?;
    let mut runs = runs?;
    for r in &mut runs {
        live.merge_events(std::mem::take(&mut r.servo.events));
    }
    let outcome = live.finish(Vec::new()).map_err(Box::new)?;
    Ok(BoundRun {
        outcome,
        devices: runs,
    })
}
