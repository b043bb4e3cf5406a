//! The simulation's own thread under XR. The frame loop sends each frame's display time (in
//! simulated seconds) and the hands' input at that time; this thread steps the session up to
//! it, the input interpolated from the previous frame's, publishes a snapshot and a status,
//! and sends back what the hands felt over those steps (for the controllers' vibration).
//!
//! Two couplings (see [`Coupling`]): **paced**, the frame loop never waits for the simulation
//! (a real headset: the runtime paces frames at the panel's rate, the simulation keeps up on
//! its own thread, and a frame shows the newest state there is); **lockstep**, the frame loop
//! waits for each frame's steps before it vibrates and draws (the simulated runtime, whose
//! clock runs as fast as frames are made: every frame then shows exactly its own time, so a
//! run is the same frame for frame). The recorded input, and so the replayed session, is the
//! same in both: the steps depend only on the frames' times and readings.

use super::vibration::FrameFeel;
use crate::haptics::RigInput;
use crate::session::{Live, SessionError, Status};
use crate::sim::{EventKind, HandInput, InputFrame, Snapshot, SnapshotBus};
use arc_swap::ArcSwap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::thread::JoinHandle;
use std::time::Duration;

/// How the frame loop and the simulation thread keep time with each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Coupling {
    /// The frame loop never waits: it draws the newest state and vibrates with what the
    /// simulation has reported so far.
    #[default]
    Paced,
    /// The frame loop waits until the simulation has reached each frame's time.
    Lockstep,
}

/// What the frame loop tells the simulation thread, in order.
enum ToSim {
    /// Step until `target_s` (simulated seconds); `hands` is the input by then.
    Frame {
        target_s: f64,
        hands: [HandInput; 2],
    },
    /// An event of the frame loop's (a controller lost, the session lost), at the next step.
    Note(EventKind),
    /// The session ends this way once the frames already sent are stepped.
    End(&'static str),
}

/// One frame's steps, done.
#[derive(Debug, Clone, Copy)]
pub struct FrameDone {
    /// What the hands felt over the frame's steps.
    pub feel: FrameFeel,
    /// Where the simulation stands after them, s.
    pub time_s: f64,
}

/// The simulation thread and what it publishes.
pub struct Stepper {
    to_sim: Sender<ToSim>,
    done: Receiver<Result<FrameDone, ()>>,
    bus: Arc<SnapshotBus>,
    status: Arc<ArcSwap<Status>>,
    handle: Option<JoinHandle<Result<Live, SessionError>>>,
    /// Set: the thread steps no more (the frames still queued are passed over).
    halt: Arc<AtomicBool>,
    /// Frames sent and not yet reported done.
    pending: usize,
    /// The simulation's time after the last frame reported done, s.
    time_s: f64,
    dt_s: f64,
}

/// How long the thread waits for a frame before it flushes the recording anyway.
const IDLE_FLUSH: Duration = Duration::from_millis(200);

impl Stepper {
    /// Starts the thread with the session (built, its recording already streaming), for
    /// frames coupled as `coupling` says: paced, each frame's snapshot is built beside the
    /// simulation ([`SnapshotBus::publish_job`]: a frame shows the newest there is);
    /// lockstep, on this thread before the frame is done (the frame shows its own).
    /// With `devices` (force-feedback styluses bound to instruments: [`crate::haptics::Rig`]),
    /// each step takes their hands' input from the styluses and the others' from the frames.
    pub fn start(
        mut live: Live,
        coupling: Coupling,
        devices: Option<RigInput>,
    ) -> Result<Stepper, SessionError> {
        let bus = Arc::new(SnapshotBus::new());
        bus.publish(live.snapshot());
        let status = Arc::new(ArcSwap::from_pointee(live.status(crate::session::LOOK_M)));
        let (to_sim, inbox) = channel();
        let (done_tx, done) = channel();
        let (b, s) = (bus.clone(), status.clone());
        let halt = Arc::new(AtomicBool::new(false));
        let halted = halt.clone();
        let time_s = live.time_s();
        let dt_s = f64::from(live.dt_s());
        let handle = std::thread::Builder::new()
            .name("vesalius-sim".into())
            .spawn(move || -> Result<Live, SessionError> {
                // Steps on a worker of the pool (see `crate::session::on_pool`).
                crate::session::on_pool(move || {
                    let beside = coupling == Coupling::Paced;
                    let lines = (&inbox, &done_tx, &*halted);
                    let r = serve(&mut live, lines, (&b, &s), beside, devices);
                    if r.is_err() {
                        // The frame loop may be waiting for this frame.
                        let _ = done_tx.send(Err(()));
                    }
                    r.map(|()| live)
                })
            })
            .map_err(|e| SessionError::Io {
                path: "simulation thread".into(),
                source: e,
            })?;
        Ok(Stepper {
            to_sim,
            done,
            bus,
            status,
            handle: Some(handle),
            halt,
            pending: 0,
            time_s,
            dt_s,
        })
    }

    /// Asks for the steps up to `target_s` with the hands at `hands` by then.
    pub fn frame(&mut self, target_s: f64, hands: [HandInput; 2]) -> Result<(), SessionError> {
        self.send(ToSim::Frame { target_s, hands })?;
        self.pending += 1;
        Ok(())
    }

    /// Notes an event at the simulation's next step.
    pub fn note(&self, kind: EventKind) -> Result<(), SessionError> {
        self.send(ToSim::Note(kind))
    }

    fn send(&self, m: ToSim) -> Result<(), SessionError> {
        self.to_sim.send(m).map_err(|_| self.gone())
    }

    /// What the frames done since the last call felt, merged; with `wait`, after every frame
    /// sent is done.
    pub fn collect(&mut self, wait: bool) -> Result<FrameFeel, SessionError> {
        let mut feel = FrameFeel::default();
        while self.pending > 0 {
            let next = if wait {
                self.done.recv().map_err(|_| ())
            } else {
                match self.done.try_recv() {
                    Ok(d) => Ok(d),
                    Err(_) => break,
                }
            };
            match next {
                Ok(Ok(d)) => {
                    feel.merge(&d.feel);
                    self.time_s = d.time_s;
                    self.pending -= 1;
                }
                // The thread stopped with an error; `finish` returns it.
                Ok(Err(())) | Err(()) => return Err(self.gone()),
            }
        }
        Ok(feel)
    }

    /// The simulation's time after the last frame collected, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// The newest snapshot.
    pub fn snapshot(&self) -> Arc<Snapshot> {
        self.bus.latest()
    }

    /// The newest status, for the panels.
    pub fn status(&self) -> Arc<Status> {
        self.status.load_full()
    }

    fn gone(&self) -> SessionError {
        SessionError::Io {
            path: "simulation thread".into(),
            source: std::io::Error::other("the simulation thread stopped"),
        }
    }

    /// Ends the session as `how` at once, the frames sent and not yet stepped left
    /// unstepped (a simulation far behind the wall clock is not waited for), and returns it.
    pub fn finish_now(self, how: &'static str) -> Result<Live, SessionError> {
        self.halt.store(true, Ordering::Relaxed);
        self.finish(how)
    }

    /// Ends the session as `how` once the frames sent are stepped, and returns it.
    pub fn finish(mut self, how: &'static str) -> Result<Live, SessionError> {
        let _ = self.to_sim.send(ToSim::End(how));
        match self.handle.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            _ => Err(SessionError::Io {
                path: "simulation thread".into(),
                source: std::io::Error::other("the simulation thread panicked"),
            }),
        }
    }
}

impl Drop for Stepper {
    fn drop(&mut self) {
        let _ = self.to_sim.send(ToSim::End(crate::session::ended::CLOSED));
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// The thread's loop: each frame's steps, in the order they came.
fn serve(
    live: &mut Live,
    (inbox, done, halt): (
        &Receiver<ToSim>,
        &Sender<Result<FrameDone, ()>>,
        &AtomicBool,
    ),
    (bus, status): (&Arc<SnapshotBus>, &ArcSwap<Status>),
    beside: bool,
    mut devices: Option<RigInput>,
) -> Result<(), SessionError> {
    let dt = f64::from(live.dt_s());
    let tools = live.info().tools;
    let haptics = live.haptics();
    // The previous frame's input (none before the first frame: its steps take its own
    // reading, rather than sweeping the instruments in from the origin) and the time its
    // steps ended at.
    let mut held: Option<[HandInput; 2]> = None;
    let mut last_t_s = live.time_s();
    loop {
        let message = match inbox.recv_timeout(IDLE_FLUSH) {
            Ok(m) => m,
            Err(RecvTimeoutError::Timeout) => {
                live.flush_if_due()?;
                continue;
            }
            // The frame loop is gone without a word: the session ends as closed.
            Err(RecvTimeoutError::Disconnected) => ToSim::End(crate::session::ended::CLOSED),
        };
        match message {
            // Halted: the frames still queued are passed over, unanswered.
            ToSim::Frame { .. } if halt.load(Ordering::Relaxed) => {}
            ToSim::Frame { target_s, hands } => {
                let mut feel = FrameFeel::default();
                let span = (target_s - last_t_s).max(1e-9);
                let from = held.unwrap_or(hands);
                while live.time_s() + dt * 0.5 <= target_s && !halt.load(Ordering::Relaxed) {
                    let s = ((live.time_s() - last_t_s) / span).clamp(0.0, 1.0) as f32;
                    let mut frame = InputFrame {
                        hands: [
                            super::between(&from[0], &hands[0], s),
                            super::between(&from[1], &hands[1], s),
                        ],
                    };
                    // A hand a stylus drives follows the stylus as it is now.
                    if let Some(d) = devices.as_mut() {
                        let bound = d.frame();
                        for h in d.hands() {
                            frame.hands[h.index()] = bound.hands[h.index()];
                        }
                    }
                    // The frame's snapshot follows the last of its steps.
                    if live.time_s() + dt * 1.5 > target_s {
                        live.snapshot_follows();
                    }
                    for e in live.step(frame)? {
                        feel.note(&e.kind, &tools);
                    }
                    // Vibration reads the haptic channel, as a force-feedback loop would.
                    let felt = haptics.latest();
                    feel.touch([
                        felt.tools[0].force_n.length(),
                        felt.tools[1].force_n.length(),
                    ]);
                }
                last_t_s = live.time_s();
                held = Some(hands);
                if beside {
                    bus.publish_job(live.snapshot_job());
                } else {
                    bus.publish(live.snapshot());
                }
                status.store(Arc::new(live.status(crate::session::LOOK_M)));
                let _ = done.send(Ok(FrameDone {
                    feel,
                    time_s: last_t_s,
                }));
            }
            ToSim::Note(kind) => {
                // A new session carries on from where the simulation stopped: real-time
                // pacing (styluses bound) goes on from now, not from before the gap.
                if matches!(kind, EventKind::SessionRestarted) {
                    live.resume_pacing();
                }
                live.note(kind);
            }
            ToSim::End(how) => {
                if live.ended() == crate::session::ended::END_OF_INPUT {
                    live.set_ended(how);
                }
                return Ok(());
            }
        }
    }
}
