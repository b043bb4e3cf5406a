//! The simulation on its own thread for the window: it steps in real time, takes its input from
//! a trace, the desktop controls or force-feedback devices, and publishes snapshots for the
//! renderer and a status for the panels, never waiting on the window.

use crate::haptics::RigInput;
use crate::session::{self, Live, Outcome, SETTLE_S, SessionError, Status, ended, interrupt};
use crate::sim::{InputFrame, Pacing, SimEvent, SnapshotBus};
use crate::trace::KeyTrace;
use arc_swap::ArcSwap;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

/// Where the instruments' input comes from.
pub enum Source {
    /// A keyframed trace, sampled per step; the session ends with it.
    Trace(KeyTrace),
    /// The desktop controls, which the window updates; the session ends when asked.
    Live(Arc<ArcSwap<InputFrame>>),
    /// Force-feedback devices (their servo loops run on threads of their own); the session
    /// ends when asked, after `until_s` simulated seconds if given, or when a device faults.
    Devices {
        input: RigInput,
        until_s: Option<f64>,
    },
}

/// What the window asks of the simulation.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// New values for a model's tunable parameters from the next step (recorded with the
    /// session).
    Tune(String, Vec<(String, f32)>),
}

/// The simulation thread and what it publishes.
pub struct SimThread {
    pub bus: Arc<SnapshotBus>,
    pub commands: Sender<Command>,
    pub status: Arc<ArcSwap<Status>>,
    stop: Arc<AtomicBool>,
    done: Arc<AtomicBool>,
    /// While set, the session takes no steps (a start screen, a pause).
    paused: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<Live, SessionError>>>,
}

pub use crate::session::LOOK_M;

impl SimThread {
    /// Builds the procedure (here, so a bad scenario is reported before any window opens)
    /// and starts stepping it (`paused`: once [`SimThread::set_paused`] lets it go).
    pub fn start(
        scenario_text: &str,
        scenario_file: &str,
        source: Source,
        pacing: Pacing,
        out: Option<&Path>,
        paused: bool,
    ) -> Result<SimThread, SessionError> {
        let live = open_live(scenario_text, scenario_file, pacing, out)?;
        SimThread::start_live(live, source, None, paused)
    }

    /// Starts stepping a session already built, on `pool`'s threads when given (else on
    /// the global pool's); `paused`: it waits for [`SimThread::set_paused`] (false) first.
    pub fn start_live(
        mut live: Live,
        mut source: Source,
        pool: Option<rayon::ThreadPool>,
        paused: bool,
    ) -> Result<SimThread, SessionError> {
        let bus = Arc::new(SnapshotBus::new());
        bus.publish(live.snapshot());
        let status = Arc::new(ArcSwap::from_pointee(live.status(LOOK_M)));
        let stop = Arc::new(AtomicBool::new(false));
        let done = Arc::new(AtomicBool::new(false));
        let paused = Arc::new(AtomicBool::new(paused));
        let (b, st, s, d) = (bus.clone(), status.clone(), stop.clone(), done.clone());
        let p = paused.clone();
        let (commands, inbox): (Sender<Command>, Receiver<Command>) = channel();
        let handle = std::thread::Builder::new()
            .name("simulation".into())
            .spawn(move || {
                let work = move || {
                    let stepped = play(&mut live, &mut source, &inbox, (&b, &st, &s, &p));
                    b.publish(live.snapshot());
                    st.store(Arc::new(live.status(LOOK_M)));
                    d.store(true, Ordering::Release);
                    stepped.map(|()| live)
                };
                match pool {
                    Some(p) => p.install(work),
                    None => session::on_pool(work),
                }
            })
            .map_err(|e| SessionError::Io {
                path: "simulation thread".into(),
                source: e,
            })?;
        Ok(SimThread {
            bus,
            commands,
            status,
            stop,
            done,
            paused,
            handle: Some(handle),
        })
    }

    /// Holds the session (it takes no steps, and real-time pacing resumes from the moment
    /// it goes on) or lets it go on.
    pub fn set_paused(&self, paused: bool) {
        self.paused.store(paused, Ordering::Release);
    }

    pub fn is_paused(&self) -> bool {
        self.paused.load(Ordering::Acquire)
    }

    /// Whether the session has ended (its trace played out, or stopped).
    pub fn finished(&self) -> bool {
        self.done.load(Ordering::Acquire)
    }

    /// Stops the session (if it still runs) and returns its outcome.
    pub fn finish(self) -> Result<Outcome, SessionError> {
        self.finish_with(Vec::new())
    }

    /// Stops the session (if it still runs) and returns its outcome, with `events` from
    /// elsewhere (the servo loops') merged into its stream by step.
    pub fn finish_with(mut self, events: Vec<SimEvent>) -> Result<Outcome, SessionError> {
        self.stop.store(true, Ordering::Relaxed);
        match self.handle.take().map(JoinHandle::join) {
            Some(Ok(r)) => {
                let mut live = r?;
                live.merge_events(events);
                live.finish(Vec::new())
            }
            _ => Err(SessionError::Io {
                path: "simulation thread".into(),
                source: std::io::Error::other("the simulation thread panicked"),
            }),
        }
    }
}

/// A session for `scenario_text`, its recording streaming into `out` (made and tested first)
/// when given.
pub fn open_live(
    scenario_text: &str,
    scenario_file: &str,
    pacing: Pacing,
    out: Option<&Path>,
) -> Result<Live, SessionError> {
    let mut live = Live::new(scenario_text, scenario_file, pacing)?;
    if let Some(dir) = out {
        session::prepare(dir)?;
        live.stream_to(&dir.join(session::RECORDING))?;
    }
    Ok(live)
}

/// Steps `live` until its trace ends, the window stops it, or a signal asks it to end.
fn play(
    live: &mut Live,
    source: &mut Source,
    inbox: &Receiver<Command>,
    (bus, status, stop, paused): (
        &Arc<SnapshotBus>,
        &ArcSwap<Status>,
        &AtomicBool,
        &AtomicBool,
    ),
) -> Result<(), SessionError> {
    let mut was_paused = false;
    let publish_every = live.publish_every();
    // A trace plays for as many steps as it would headless, so the report is the same.
    let end = match source {
        Source::Trace(t) => Some(live.steps_for(t.duration_s() + SETTLE_S)),
        Source::Live(_) => None,
        Source::Devices { until_s, .. } => until_s.map(|s| live.steps_for(s)),
    };
    loop {
        if interrupt::interrupted().is_some() {
            live.set_ended(ended::INTERRUPTED);
            return Ok(());
        }
        if stop.load(Ordering::Relaxed) {
            live.set_ended(ended::CLOSED);
            return Ok(());
        }
        if end.is_some_and(|e| live.step_count() >= e) {
            if matches!(source, Source::Devices { .. }) {
                live.set_ended(ended::TIME_UP);
            }
            return Ok(());
        }
        if paused.load(Ordering::Acquire) {
            was_paused = true;
            std::thread::sleep(std::time::Duration::from_millis(5));
            continue;
        }
        if was_paused {
            live.resume_pacing();
            was_paused = false;
        }
        while let Ok(Command::Tune(model, values)) = inbox.try_recv() {
            // The sliders stay inside the allowed ranges; a value outside them is refused by
            // `tune` and changes nothing.
            let _ = live.tune(&model, &values);
        }
        let frame = match source {
            Source::Trace(t) => t.sample(live.time_s()),
            Source::Live(input) => **input.load(),
            Source::Devices { input, .. } => {
                if input.stopped() {
                    // A servo loop ended (a device fault): so does the session.
                    return Ok(());
                }
                input.frame()
            }
        };
        if (live.step_count() + 1).is_multiple_of(publish_every) {
            live.snapshot_follows();
        }
        live.step(frame)?;
        if live.step_count().is_multiple_of(publish_every) {
            // Built on the bus's thread while the simulation steps on.
            bus.publish_job(live.snapshot_job());
            status.store(Arc::new(live.status(LOOK_M)));
        }
    }
}

impl Drop for SimThread {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
