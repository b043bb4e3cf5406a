//! Force-feedback devices bound to a session's instruments: one servo thread per device
//! ([`Rig`]) and what the simulation reads each step ([`RigInput`]): the bindings, with their
//! clutches, and a line said once for a device whose forces stay off at start-up. The session
//! itself steps wherever its owner likes: on the calling thread (`run --haptics` without a
//! window) or on the window's simulation thread. No thread waits on another: they meet in
//! lock-free slots.

use super::clutch::{Binding, bound_frame, hand_workspace};
use super::device::{HapticDevice, HapticsError};
use super::safety::SafetyParams;
use super::servo::{ServoConfig, ServoLinks, ServoReport, held_off_notice, run_servo};
use super::stand::device_hand;
use crate::procedures::ProcedureInfo;
use crate::sim::{Hand, HapticSlot, InputFrame};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::thread::JoinHandle;

/// How the devices are bound.
#[derive(Debug, Clone, Copy)]
pub struct RigOptions {
    /// Field metres per device metre.
    pub scale: f64,
    pub safety: SafetyParams,
    /// The servo loops end by themselves after this long, s (a backstop: the owner stops
    /// them first).
    pub backstop_s: f64,
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

/// The hands `n` devices drive in `info`'s procedure, in device order.
pub fn bound_hands(info: &ProcedureInfo, n: usize) -> Vec<Hand> {
    match n {
        1 => vec![device_hand(info)],
        _ => Hand::BOTH.into_iter().take(n).collect(),
    }
}

type ServoThread = JoinHandle<Result<ServoReport, HapticsError>>;

/// The servo threads of the devices bound to a session.
pub struct Rig {
    stop: Arc<AtomicBool>,
    threads: Vec<(String, Hand, ServoThread)>,
    /// Per device: times its clutch was let go (the simulation's side counts them).
    reanchors: Vec<Arc<AtomicU32>>,
}

/// What the simulation reads each step.
pub struct RigInput {
    info: &'static ProcedureInfo,
    bindings: Vec<Binding>,
    links: Vec<ServoLinks>,
    notices: Vec<(String, bool)>,
    stop: Arc<AtomicBool>,
    reanchors: Vec<Arc<AtomicU32>>,
}

impl Rig {
    /// Binds `devices` (one or two) to `info`'s instruments and starts a servo thread for
    /// each, reading the session's haptic frames from `frames`.
    pub fn start(
        devices: Vec<Box<dyn HapticDevice>>,
        info: &'static ProcedureInfo,
        frames: Arc<HapticSlot>,
        opts: RigOptions,
    ) -> Result<(Rig, RigInput), HapticsError> {
        if devices.is_empty() || devices.len() > 2 {
            return Err(HapticsError::Thread(format!(
                "a session takes one or two devices, not {}",
                devices.len()
            )));
        }
        let hands = bound_hands(info, devices.len());
        let two = devices.len() == 2;
        let stop = Arc::new(AtomicBool::new(false));
        let reanchors: Vec<Arc<AtomicU32>> =
            hands.iter().map(|_| Arc::new(AtomicU32::new(0))).collect();
        let mut rig = Rig {
            stop: stop.clone(),
            threads: Vec::new(),
            reanchors: reanchors.clone(),
        };
        let mut input = RigInput {
            info,
            bindings: Vec::new(),
            links: Vec::new(),
            notices: Vec::new(),
            stop: stop.clone(),
            reanchors,
        };
        for (mut device, hand) in devices.into_iter().zip(hands) {
            let name = device.name().to_string();
            let links = ServoLinks::new(frames.clone(), stop.clone());
            let config = ServoConfig {
                hand,
                workspace_scale: opts.scale,
                safety: opts.safety,
                duration_s: opts.backstop_s,
                clutch: true,
                ..ServoConfig::default()
            };
            let workspace = hand_workspace(info, hand, two, opts.scale);
            input
                .bindings
                .push(Binding::new(hand, device.kind(), workspace));
            input.notices.push((held_off_notice(&name, hand), false));
            let servo_links = links.clone();
            input.links.push(links);
            let thread = std::thread::Builder::new()
                .name("vesalius-servo".into())
                .spawn(move || {
                    let r = run_servo(device.as_mut(), &servo_links, &config);
                    // A servo that ends (a device fault) ends the session.
                    servo_links.stop.store(true, Ordering::Relaxed);
                    r
                });
            match thread {
                Ok(t) => rig.threads.push((name, hand, t)),
                Err(e) => {
                    // The threads started so far stop when `rig` drops.
                    return Err(HapticsError::Thread(format!(
                        "cannot start a servo thread: {e}"
                    )));
                }
            }
        }
        Ok((rig, input))
    }

    /// Whether a servo loop has ended (a device fault, or its backstop): the session
    /// should end too.
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// Stops the servo loops (each leaves its device at zero force) and returns how each
    /// went; the first device error, if any.
    pub fn stop(mut self) -> Result<Vec<DeviceRun>, HapticsError> {
        self.stop.store(true, Ordering::Relaxed);
        let mut runs = Vec::new();
        let mut first_error = None;
        let counts: Vec<u32> = self
            .reanchors
            .iter()
            .map(|c| c.load(Ordering::Relaxed))
            .collect();
        for ((name, hand, thread), reanchors) in self.threads.drain(..).zip(counts) {
            let servo = thread
                .join()
                .unwrap_or_else(|_| Err(HapticsError::Thread("a servo thread panicked".into())));
            match servo {
                Ok(servo) => runs.push(DeviceRun {
                    device: name,
                    hand,
                    servo,
                    reanchors,
                }),
                Err(e) => {
                    first_error.get_or_insert(e);
                }
            }
        }
        match first_error {
            Some(e) => Err(e),
            None => Ok(runs),
        }
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for (_, _, t) in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

impl RigInput {
    /// This step's input: each bound instrument where its stylus puts it (until a servo's
    /// first tick, at its device's origin), the others parked. Says once, on stderr, why a
    /// device's forces stay off at start-up.
    pub fn frame(&mut self) -> InputFrame {
        for (((b, l), (notice, said)), count) in self
            .bindings
            .iter_mut()
            .zip(&self.links)
            .zip(&mut self.notices)
            .zip(&self.reanchors)
        {
            b.update(&l.stylus.latest().unwrap_or_default());
            count.store(b.reanchors, Ordering::Relaxed);
            if !*said && l.held_off.load(Ordering::Relaxed) {
                *said = true;
                eprintln!("{notice}");
            }
        }
        bound_frame(self.info, &self.bindings)
    }

    /// Whether a servo loop has ended (see [`Rig::stopped`]).
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// The hands the devices drive, in device order.
    pub fn hands(&self) -> Vec<Hand> {
        self.bindings.iter().map(|b| b.hand).collect()
    }
}
