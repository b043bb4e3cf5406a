//! A session: a procedure driven by its input at a fixed step, recorded as it runs, and
//! reported. The recording streams to the output folder in checksummed blocks, so a killed
//! session loses at most its last second; a signal ends it cleanly with an interrupted report.

pub mod interrupt;
mod live;
mod output;

pub use live::Live;
pub use output::{EVENTS, RECORDING, REPORT, TIMING, new_session_id, prepare, write_outputs};

use crate::procedures::BuildError;
pub use crate::procedures::ModelReport;
use crate::scenario::InputError;
use crate::sim::{Pacing, SimEvent, Snapshot, SnapshotBus};
use crate::trace::{KeyTrace, Recording, Tail};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Where the inputs come from.
pub enum Input {
    Keys(KeyTrace),
    /// A recording: its frames, and its tissue tunings at their steps.
    Recorded(Recording),
}

/// How a session ended, as its report and recording say.
pub mod ended {
    /// The trace or recording played out.
    pub const END_OF_INPUT: &str = "end_of_input";
    /// SIGINT or SIGTERM asked the session to stop.
    pub const INTERRUPTED: &str = "interrupted";
    /// The trainee or supervisor closed the window.
    pub const CLOSED: &str = "closed";
    /// The XR runtime ended the session, or its duration ran out.
    pub const XR_EXIT: &str = "xr_exit";
    /// The session's set length (`run --haptics --seconds`) ran out.
    pub const TIME_UP: &str = "time_up";
    /// A force-feedback device's servo loop ended (a device fault) in a session in the
    /// headset.
    pub const DEVICE_STOPPED: &str = "device_stopped";
    /// A replay of a recording that stops short (its session was killed or crashed).
    pub const TRUNCATED_RECORDING: &str = "truncated_recording";
}

/// A session's state at one step (the core's word for it: the panels and alarms read it).
pub use crate::sim::SessionStatus as Status;

/// Vulnerable structures are reported in the status within this distance, metres (the
/// alarms use a nearer limit of their own).
pub const LOOK_M: f32 = 0.01;

/// How long an instruction stays in the headset's panel, simulated seconds.
pub const INSTRUCTION_CURRENT_S: f64 = 8.0;

/// Extra simulated time after the trace ends, seconds, so that motion settles.
pub const SETTLE_S: f64 = 0.25;

/// The longest session a trace, a duration or a window may ask for, seconds (4 hours).
pub const DEFAULT_MAX_SESSION_S: f64 = xr_bindings::keyframes::DEFAULT_MAX_SESSION_S;

#[derive(Debug, Serialize)]
pub struct Report {
    pub procedure: String,
    /// The id every file of this output set carries (a replay keeps the recording's).
    pub session_id: String,
    /// FNV-1a of the scenario's text, so records name the exact scenario a session ran.
    pub scenario_digest: String,
    /// Whether the procedure's task was completed.
    pub completed: bool,
    /// How the session ended (see [`ended`]).
    pub ended: String,
    pub dt_s: f32,
    pub steps: u64,
    pub simulated_s: f64,
    /// Where the models stepped: `gpu` where any did on a GPU (its adapter beside), else
    /// `cpu`. A replay on another backend or adapter may give other bytes.
    pub compute: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adapter: Option<String>,
    pub models: Vec<ModelReport>,
    pub events: BTreeMap<String, u64>,
    /// Errors the procedure counted (vulnerable structures touched, tissue torn, ...).
    pub errors: u32,
    /// The procedure's own metrics.
    pub metrics: serde_json::Value,
    /// The procedure's own task components (completion, efficiency, ...).
    pub score_parts: serde_json::Value,
    /// The assessment tree's weighted score, 0-100, and the level of expertise it gives.
    pub score: f32,
    pub level: String,
    /// The whole assessment: the tree scored node by node, the fuzzy memberships.
    pub assessment: crate::assess::Assessment,
    /// How the instruments moved (`assess::motion`; the measures `motion.<key>`).
    pub motion: crate::assess::motion::Motion,
    /// The session over time, a sample every 0.1 s simulated (for reports' plots).
    pub timeline: Vec<Sample>,
    /// FNV-1a digest of the final simulation state.
    pub state_hash: String,
    /// A replay's word on its bytes: set where the recorded session stepped on another
    /// backend or adapter.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub replay_note: Option<String>,
}

/// One sample of a session's timeline.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample {
    /// Simulated time, s.
    pub t_s: f32,
    /// Each instrument's (left, right) mean speed since the last sample, m/s.
    pub speed_m_per_s: [f32; 2],
    /// Each instrument's reaction force now, N.
    pub force_n: [f32; 2],
    /// The assessment tree's score so far, 0-100.
    pub score: f32,
}

/// Where a session's recording is.
#[derive(Debug)]
pub enum Recorded {
    /// Streamed to this file while the session ran.
    Streamed(PathBuf),
    /// Held in memory (a session without an output folder).
    InMemory(Recording),
}

pub struct Outcome {
    pub report: Report,
    pub events: Vec<SimEvent>,
    pub recording: Recorded,
    pub wall_s: f64,
    /// Snapshots taken for rendering (`run_capturing`), evenly spaced, the last at the end.
    pub captured: Vec<Snapshot>,
}

#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Build(#[from] BuildError),
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("--out {dir}: {reason}")]
    Out { dir: String, reason: String },
    #[error(
        "cannot write the recording {path}: {source}; the session stopped at step {step} \
         and no report was written (the recording up to the last complete block replays)"
    )]
    Recording {
        path: String,
        step: u64,
        source: std::io::Error,
    },
}

/// How a session runs besides its scenario and input.
#[derive(Default)]
pub struct Options<'a> {
    pub pacing: Pacing,
    /// Publish a snapshot here at the scenario's rate.
    pub bus: Option<&'a SnapshotBus>,
    /// Keep this many snapshots, evenly spaced, for rendering.
    pub frames_wanted: u32,
    /// Stream the recording into this folder (made and tested first, see [`prepare`]).
    pub out: Option<&'a Path>,
    /// Score with this tree (its file's name for errors, the tree) instead of the
    /// procedure's own.
    pub assessment: Option<(&'a str, &'a crate::assess::Tree)>,
}

/// Runs a session to the end of its input.
pub fn run(
    scenario_text: &str,
    scenario_file: &str,
    input: Input,
    pacing: Pacing,
    bus: Option<&SnapshotBus>,
) -> Result<Outcome, SessionError> {
    let opts = Options {
        pacing,
        bus,
        ..Options::default()
    };
    run_with(scenario_text, scenario_file, input, &opts)
}

/// Runs a session and keeps `frames` snapshots, evenly spaced over it, for rendering.
pub fn run_capturing(
    scenario_text: &str,
    scenario_file: &str,
    input: Input,
    pacing: Pacing,
    bus: Option<&SnapshotBus>,
    frames_wanted: u32,
) -> Result<Outcome, SessionError> {
    let opts = Options {
        pacing,
        bus,
        frames_wanted,
        out: None,
        assessment: None,
    };
    run_with(scenario_text, scenario_file, input, &opts)
}

/// Runs `f` on a worker of rayon's pool (at once when already on one). A loop that steps a
/// world from there starts each step's parallel work inside the pool; from any other thread
/// every step is injected into the pool and waited for, a wake-up and a sleep per step.
pub fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    if rayon::current_thread_index().is_some() {
        return f();
    }
    rayon::join(f, || ()).0
}

/// Runs a session to the end of its input, or until SIGINT/SIGTERM (see [`interrupt`]).
pub fn run_with(
    scenario_text: &str,
    scenario_file: &str,
    input: Input,
    opts: &Options,
) -> Result<Outcome, SessionError> {
    if let Some(dir) = opts.out {
        prepare(dir)?;
    }
    // Refuse an absurd session before its anatomy is built.
    let (_, plan) = crate::registry::plan(scenario_file, scenario_text)?;
    let total_steps = match &input {
        Input::Keys(k) => ((k.duration_s() + SETTLE_S) / f64::from(plan.dt_s)).ceil() as u64,
        Input::Recorded(r) => r.frames.len() as u64,
    };
    crate::scenario::check_cost(scenario_file, plan.nodes, total_steps)?;
    let mut live = match &input {
        Input::Recorded(r) => {
            Live::with_id(scenario_text, scenario_file, opts.pacing, &r.session_id)?
        }
        Input::Keys(_) => Live::new(scenario_text, scenario_file, opts.pacing)?,
    };
    if let Some((file, tree)) = opts.assessment {
        live.set_assessment(file, tree.clone())?;
    }
    if let Some(dir) = opts.out {
        live.stream_to(&dir.join(RECORDING))?;
    }
    let publish_every = live.publish_every();
    let n = opts.frames_wanted as u64;
    let capture_at: Vec<u64> = (1..=n)
        .map(|k| (k * total_steps / n.max(1)).saturating_sub(1))
        .collect();
    let stepped = on_pool(|| -> Result<_, SessionError> {
        let mut captured = Vec::with_capacity(capture_at.len());
        // The next recorded tuning to make (they are in step order).
        let mut next_tuning = 0;
        while live.step_count() < total_steps {
            if interrupt::interrupted().is_some() {
                live.set_ended(ended::INTERRUPTED);
                break;
            }
            let step = live.step_count();
            let frame = match &input {
                Input::Keys(k) => k.sample(live.time_s()),
                Input::Recorded(r) => {
                    while let Some(t) = r.tunings.get(next_tuning).filter(|t| t.step == step) {
                        live.tune_recorded(t).map_err(|m| {
                            SessionError::Input(InputError::new(
                                scenario_file,
                                "tunings",
                                m.to_string(),
                            ))
                        })?;
                        next_tuning += 1;
                    }
                    r.frames[step as usize]
                }
            };
            let captured_now = capture_at.binary_search(&step).is_ok();
            if captured_now || (opts.bus.is_some() && step.is_multiple_of(publish_every)) {
                live.snapshot_follows();
            }
            live.step(frame)?;
            if captured_now {
                captured.push(live.snapshot());
            }
            if let Some(bus) = opts.bus
                && step.is_multiple_of(publish_every)
            {
                bus.publish(live.snapshot());
            }
        }
        Ok(captured)
    });
    let captured = stepped?;
    if let Input::Recorded(r) = &input
        && live.ended() == ended::END_OF_INPUT
    {
        // A replay ends as its session did, so its report is the same bytes.
        match &r.tail {
            Tail::Ended { how } if how != "legacy" => live.set_ended(how),
            Tail::Ended { .. } => {}
            Tail::Cut { .. } => live.set_ended(ended::TRUNCATED_RECORDING),
        }
    }
    live.finish(captured)
}
