//! A recorded session driven by force-feedback devices (`vesalius run <procedure> --haptics
//! D[,D]`): one device drives the procedure's probe (else its right-hand instrument), two drive
//! the left and the right hand's instruments (the papers' two hands). The procedure steps in
//! real time on a simulation thread and publishes a haptic frame every step; each device has
//! its servo loop on a thread of its own at 1 kHz. No thread waits on another: they meet in
//! lock-free slots. The session records its input and writes its report as any other does, so
//! it replays bit for bit; the servo loops' safety events join its event stream.

use super::clutch::{Binding, bound_frame, hand_workspace};
use super::device::{HapticDevice, HapticsError};
use super::safety::SafetyParams;
use super::servo::{ServoConfig, ServoLinks, ServoReport, held_off_notice, run_servo};
use super::stand::device_hand;
use crate::session::{Live, Outcome, SessionError, ended, interrupt};
use crate::sim::{Hand, Pacing};
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

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

/// One device's part of a session.
#[derive(Debug, Clone)]
pub struct DeviceRun {
    pub device: String,
    pub hand: Hand,
    pub servo: ServoReport,
    /// Times the clutch was let go.
    pub reanchors: u32,
}

/// How a device-driven session went.
pub struct BoundRun {
    pub outcome: Outcome,
    pub devices: Vec<DeviceRun>,
}

/// The hands `n` devices drive in `info`'s procedure, in device order.
pub fn bound_hands(info: &crate::procedures::ProcedureInfo, n: usize) -> Vec<Hand> {
    match n {
        1 => vec![device_hand(info)],
        _ => Hand::BOTH.into_iter().take(n).collect(),
    }
}

/// Runs a session with `devices` (one or two) bound to the procedure's instruments.
pub fn run_bound(
    devices: &mut [Box<dyn HapticDevice>],
    opts: &BoundOptions,
) -> Result<BoundRun, HapticsError> {
    if devices.is_empty() || devices.len() > 2 {
        return Err(HapticsError::Thread(format!(
            "a session takes one or two devices, not {}",
            devices.len()
        )));
    }
    let mut live =
        Live::new(opts.scenario_text, opts.scenario_file, Pacing::RealTime).map_err(Box::new)?;
    if let Some(dir) = opts.out {
        live.stream_to(&dir.join(crate::session::RECORDING))
            .map_err(Box::new)?;
    }
    let info = live.info();
    let hands = bound_hands(info, devices.len());
    let two = devices.len() == 2;
    let mut bindings: Vec<Binding> = devices
        .iter()
        .zip(&hands)
        .map(|(d, &h)| Binding::new(h, d.kind(), hand_workspace(info, h, two, opts.scale)))
        .collect();
    let stop = Arc::new(AtomicBool::new(false));
    let links: Vec<ServoLinks> = devices
        .iter()
        .map(|_| ServoLinks::new(live.haptics(), stop.clone()))
        .collect();
    let configs: Vec<ServoConfig> = hands
        .iter()
        .map(|&hand| ServoConfig {
            hand,
            workspace_scale: opts.scale,
            safety: opts.safety,
            // The servo loops end when the session does (this is only a backstop, well past
            // the session's end even at a fraction of real time).
            duration_s: 4.0 * opts.seconds + 10.0,
            clutch: true,
            ..ServoConfig::default()
        })
        .collect();
    let names: Vec<String> = devices.iter().map(|d| d.name().to_string()).collect();
    let notices: Vec<String> = names
        .iter()
        .zip(&hands)
        .map(|(n, &h)| held_off_notice(n, h))
        .collect();
    let pool = super::stand::sim_pool(devices.len())?;
    let (servos, sim) = std::thread::scope(|s| {
        let sim_links = &links;
        let bindings = &mut bindings;
        let stop = &stop;
        let pool = &pool;
        let sim = std::thread::Builder::new()
            .name("vesalius-sim".into())
            .spawn_scoped(s, move || -> Result<Live, SessionError> {
                pool.install(|| {
                    let mut said = vec![false; sim_links.len()];
                    let result = loop {
                        for ((l, said), notice) in sim_links.iter().zip(&mut said).zip(&notices) {
                            if !*said && l.held_off.load(Ordering::Relaxed) {
                                *said = true;
                                eprintln!("{notice}");
                            }
                        }
                        if stop.load(Ordering::Relaxed) {
                            break Ok(());
                        }
                        if interrupt::interrupted().is_some() {
                            live.set_ended(ended::INTERRUPTED);
                            break Ok(());
                        }
                        if live.time_s() >= opts.seconds {
                            live.set_ended(ended::TIME_UP);
                            break Ok(());
                        }
                        for (b, l) in bindings.iter_mut().zip(sim_links) {
                            // Until the servo's first tick the stylus is at the device's origin.
                            b.update(&l.stylus.latest().unwrap_or_default());
                        }
                        if let Err(e) = live.step(bound_frame(info, bindings)) {
                            break Err(e);
                        }
                    };
                    // Whatever ended the simulation ends the servo loops.
                    stop.store(true, Ordering::Relaxed);
                    result.map(|()| live)
                })
            });
        let servos: Vec<_> = devices
            .iter_mut()
            .zip(links.iter().zip(&configs))
            .map(|(d, (l, c))| {
                std::thread::Builder::new()
                    .name("vesalius-servo".into())
                    .spawn_scoped(s, move || {
                        let r = run_servo(d.as_mut(), l, c);
                        // A servo that ends (a device fault) ends the session.
                        l.stop.store(true, Ordering::Relaxed);
                        r
                    })
            })
            .collect();
        let servos: Vec<Result<ServoReport, HapticsError>> = servos
            .into_iter()
            .map(|h| match h {
                Ok(h) => h.join().unwrap_or_else(|_| {
                    Err(HapticsError::Thread("a servo thread panicked".into()))
                }),
                Err(e) => Err(HapticsError::Thread(format!(
                    "cannot start a servo thread: {e}"
                ))),
            })
            .collect();
        stop.store(true, Ordering::Relaxed);
        let sim = match sim {
            Ok(h) => h
                .join()
                .unwrap_or_else(|_| Err(thread_failed("the simulation thread panicked"))),
            Err(e) => Err(thread_failed(&format!(
                "cannot start the simulation thread: {e}"
            ))),
        };
        (servos, sim)
    });
    let mut live = sim.map_err(Box::new)?;
    let mut runs = Vec::new();
    for (((servo, name), &hand), b) in servos.into_iter().zip(names).zip(&hands).zip(&bindings) {
        let mut servo = servo?;
        live.merge_events(std::mem::take(&mut servo.events));
        runs.push(DeviceRun {
            device: name,
            hand,
            servo,
            reanchors: b.reanchors,
        });
    }
    let outcome = live.finish(Vec::new()).map_err(Box::new)?;
    Ok(BoundRun {
        outcome,
        devices: runs,
    })
}

fn thread_failed(what: &str) -> SessionError {
    SessionError::Io {
        path: what.to_string(),
        source: std::io::Error::other(what.to_string()),
    }
}
