//! A headless session: a procedure driven by a trace at a fixed step, recorded, and reported.

use crate::assess;
use crate::models::Tuning;
use crate::procedures::Nephrectomy;
use crate::scenario::{InputError, Scenario};
use crate::sim::{Clock, InputFrame, Pacing, SimEvent, Snapshot, SnapshotBus, TissueModel};
use crate::trace::{KeyTrace, Recording};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Where the inputs come from.
pub enum Input {
    Keys(KeyTrace),
    /// A recording: its frames, and its tissue tunings at their steps.
    Recorded(Recording),
}

/// A session's state at one step, as the supervisor's panels show it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Status {
    pub step: u64,
    /// Simulated time, seconds.
    pub time_s: f64,
    /// Instrument tip path length so far (left, right), metres.
    pub path_m: [f32; 2],
    /// Length cut so far, metres, and triangles removed.
    pub cut_length_m: f32,
    pub cut_faces: u32,
    /// Errors: vulnerable-structure contacts and torn ties.
    pub errors: u32,
    /// Score so far (0-100), by the scenario's weights.
    pub score: f32,
    /// Task steps done, in order.
    pub steps_done: Vec<String>,
    pub completed: bool,
    /// Contact force on each tool, newtons.
    pub force_n: [f32; 2],
    /// Whether each tool touches a vulnerable structure.
    pub touching: [bool; 2],
    /// The nearest vulnerable structure near each tool, and its distance, metres.
    pub near: [Option<(String, f32)>; 2],
    /// The kidney's tunable parameters now.
    pub tuning: Tuning,
}

/// Extra simulated time after the trace ends, seconds, so that motion settles.
pub const SETTLE_S: f64 = 0.25;

#[derive(Debug, Serialize)]
pub struct ModelReport {
    pub name: String,
    pub kind: String,
    pub vertices: usize,
    pub triangles: usize,
    pub constraints: usize,
}

#[derive(Debug, Serialize)]
pub struct Report {
    pub procedure: String,
    pub completed: bool,
    pub dt_s: f32,
    pub steps: u64,
    pub simulated_s: f64,
    pub models: Vec<ModelReport>,
    pub events: BTreeMap<String, u64>,
    pub metrics: crate::procedures::nephrectomy::Metrics,
    pub score_parts: assess::ScoreParts,
    pub score: f32,
    /// FNV-1a digest of the final simulation state.
    pub state_hash: String,
}

pub struct Outcome {
    pub report: Report,
    pub events: Vec<SimEvent>,
    pub recording: Recording,
    pub wall_s: f64,
    /// Snapshots taken for rendering (`run_capturing`), evenly spaced, the last at the end.
    pub captured: Vec<Snapshot>,
}

#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error("building the anatomy: {0}")]
    Mesh(#[from] crate::mesh::MeshError),
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SessionError + '_ {
    move |source| SessionError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Runs a session to the end of its input.
pub fn run(
    scenario_text: &str,
    scenario_file: &str,
    input: Input,
    pacing: Pacing,
    bus: Option<&SnapshotBus>,
) -> Result<Outcome, SessionError> {
    run_capturing(scenario_text, scenario_file, input, pacing, bus, 0)
}

/// A session stepped from outside (the XR frame loop): the procedure, its clock, and what it
/// has recorded so far.
pub struct Live {
    scenario: Scenario,
    scenario_text: String,
    proc_: Nephrectomy,
    clock: Clock,
    frames: Vec<InputFrame>,
    tunings: Vec<(u64, Tuning)>,
    events: Vec<SimEvent>,
    start: Instant,
}

impl Live {
    pub fn new(
        scenario_text: &str,
        scenario_file: &str,
        pacing: Pacing,
    ) -> Result<Live, SessionError> {
        let scenario = Scenario::parse(scenario_file, scenario_text)?;
        let proc_ = Nephrectomy::new(scenario.clone())?;
        Ok(Live {
            clock: Clock::new(scenario.dt_s, pacing),
            scenario,
            scenario_text: scenario_text.to_string(),
            proc_,
            frames: Vec::new(),
            tunings: Vec::new(),
            events: Vec::new(),
            start: Instant::now(),
        })
    }

    pub fn dt_s(&self) -> f32 {
        self.scenario.dt_s
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.clock.time_s()
    }

    /// Steps between two snapshots published for renderers (the scenario's `publish_hz`).
    pub fn publish_every(&self) -> u64 {
        ((1.0 / self.scenario.publish_hz) / self.scenario.dt_s)
            .round()
            .max(1.0) as u64
    }

    /// Steps that cover `duration_s` of simulated time.
    pub fn steps_for(&self, duration_s: f64) -> u64 {
        (duration_s / f64::from(self.scenario.dt_s)).ceil() as u64
    }

    pub fn step_count(&self) -> u64 {
        self.clock.step()
    }

    /// One step with this input; the events it raised are returned (and kept).
    pub fn step(&mut self, frame: InputFrame) -> &[SimEvent] {
        let step = self.clock.step();
        let before = self.events.len();
        self.proc_.step(&frame, step, &mut self.events);
        self.frames.push(frame);
        self.clock.tick();
        &self.events[before..]
    }

    /// Changes the kidney's spring, damping, pressure and offset from the next step on; the
    /// change is recorded (a replay makes it at the same step) and raised as an event.
    pub fn tune(&mut self, t: Tuning) -> Result<(), String> {
        t.check().map_err(|(key, m)| format!("kidney.{key}: {m}"))?;
        self.proc_.tune_kidney(&t);
        self.tunings.push((self.clock.step(), t));
        self.note(crate::sim::EventKind::TissueTuned {
            model: "kidney".into(),
            tuning: t,
        });
        Ok(())
    }

    /// The kidney's tunable parameters now.
    pub fn tuning(&self) -> Tuning {
        Tuning::of(&self.proc_.scenario.kidney)
    }

    /// Adds an event from outside the simulation (a controller lost, a session restarted).
    pub fn note(&mut self, kind: crate::sim::EventKind) {
        let step = self.clock.step();
        self.events.push(SimEvent { step, kind });
    }

    pub fn snapshot(&mut self) -> Snapshot {
        self.proc_.snapshot(self.clock.step())
    }

    pub fn is_completed(&self) -> bool {
        self.proc_.is_completed()
    }

    /// Reaction force on each tool (left, right) after the last step, newtons.
    pub fn reactions(&self) -> [glam::Vec3; 2] {
        self.proc_.reactions()
    }

    /// How the session stands now, for the supervisor's panels; vulnerable structures are
    /// looked for within `near_m` of the tools.
    pub fn status(&self, near_m: f32) -> Status {
        let m = &self.proc_.metrics;
        let (score, _) = assess::score(&self.scenario, m);
        let f = self.proc_.reactions();
        Status {
            step: self.clock.step(),
            time_s: self.clock.time_s(),
            path_m: [m.path_length_left_m, m.path_length_right_m],
            cut_length_m: m.cut_length_m,
            cut_faces: m.cut_faces,
            errors: m.vessel_contacts + m.ties_torn,
            score,
            steps_done: m.steps_done.clone(),
            completed: self.proc_.is_completed(),
            force_n: [f[0].length(), f[1].length()],
            touching: self.proc_.touching_vulnerable(),
            near: self.proc_.vulnerable_near(near_m),
            tuning: self.tuning(),
        }
    }

    /// The report, events and recording of the session so far.
    pub fn finish(self, captured: Vec<Snapshot>) -> Outcome {
        let wall_s = self.start.elapsed().as_secs_f64();
        let proc_ = self.proc_;
        let scenario = self.scenario;
        let clock = self.clock;
        let dt = scenario.dt_s;
        let mut counts: BTreeMap<String, u64> = BTreeMap::new();
        for e in &self.events {
            *counts.entry(e.kind.name().to_string()).or_default() += 1;
        }
        let mut metrics = proc_.metrics.clone();
        if !proc_.is_completed() {
            metrics.healthy_removed_m2 = proc_.healthy_removed();
        }
        let (score, parts) = assess::score(&scenario, &metrics);
        let report = Report {
            procedure: scenario.procedure.clone(),
            completed: proc_.is_completed(),
            dt_s: dt,
            steps: clock.step(),
            simulated_s: clock.time_s(),
            models: proc_
                .models()
                .iter()
                .map(|m| {
                    let s = m.sizes();
                    ModelReport {
                        name: m.name().to_string(),
                        kind: m.kind().to_string(),
                        vertices: s.vertices,
                        triangles: s.triangles,
                        constraints: s.constraints,
                    }
                })
                .collect(),
            events: counts,
            metrics,
            score_parts: parts,
            score,
            state_hash: format!("{:016x}", proc_.state_hash()),
        };
        Outcome {
            report,
            events: self.events,
            recording: Recording {
                procedure: scenario.procedure,
                dt_s: dt,
                scenario: self.scenario_text,
                frames: self.frames,
                tunings: self.tunings,
            },
            wall_s,
            captured,
        }
    }
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
    let mut live = Live::new(scenario_text, scenario_file, pacing)?;
    let publish_every = live.publish_every();
    let total_steps = match &input {
        Input::Keys(k) => live.steps_for(k.duration_s() + SETTLE_S),
        Input::Recorded(r) => r.frames.len() as u64,
    };
    let n = frames_wanted as u64;
    let capture_at: Vec<u64> = (1..=n)
        .map(|k| (k * total_steps / n.max(1)).saturating_sub(1))
        .collect();
    let mut captured = Vec::with_capacity(capture_at.len());
    // The next recorded tuning to make (they are in step order).
    let mut next_tuning = 0;
    while live.step_count() < total_steps {
        let step = live.step_count();
        let frame = match &input {
            Input::Keys(k) => k.sample(live.time_s()),
            Input::Recorded(r) => {
                while let Some((_, t)) = r.tunings.get(next_tuning).filter(|(s, _)| *s == step) {
                    live.tune(*t).map_err(|m| {
                        SessionError::Input(InputError::new(scenario_file, "tunings", m))
                    })?;
                    next_tuning += 1;
                }
                r.frames[step as usize]
            }
        };
        live.step(frame);
        if capture_at.binary_search(&step).is_ok() {
            captured.push(live.proc_.snapshot(step));
        }
        if let Some(bus) = bus
            && step.is_multiple_of(publish_every)
        {
            bus.publish(live.proc_.snapshot(step));
        }
    }
    Ok(live.finish(captured))
}

/// Writes report.json, events.jsonl, input.vtrace and timing.json into `dir`.
pub fn write_outputs(o: &Outcome, dir: &Path) -> Result<(), SessionError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let write = |name: &str, bytes: &[u8]| -> Result<(), SessionError> {
        let path = dir.join(name);
        let tmp = dir.join(format!(".{name}.partial"));
        let mut f = std::fs::File::create(&tmp).map_err(io(&tmp))?;
        f.write_all(bytes).map_err(io(&tmp))?;
        std::fs::rename(&tmp, &path).map_err(io(&path))
    };
    let report = serde_json::to_string_pretty(&o.report).unwrap_or_default() + "\n";
    write("report.json", report.as_bytes())?;
    let mut lines = String::new();
    for e in &o.events {
        lines += &serde_json::to_string(e).unwrap_or_default();
        lines.push('\n');
    }
    write("events.jsonl", lines.as_bytes())?;
    let trace = dir.join("input.vtrace");
    o.recording.write(&trace).map_err(io(&trace))?;
    let steps_per_s = o.report.steps as f64 / o.wall_s.max(1e-9);
    let timing = serde_json::json!({
        "wall_s": o.wall_s,
        "steps_per_s": steps_per_s,
        "realtime_factor": steps_per_s * o.report.dt_s as f64,
        "threads": rayon::current_num_threads(),
    });
    write(
        "timing.json",
        (serde_json::to_string_pretty(&timing).unwrap_or_default() + "\n").as_bytes(),
    )
}
