//! A session stepped from outside (the XR frame loop, the window's simulation thread, the
//! headless loop): the procedure, its clock, its events and its recording.

use super::output::{io, new_session_id};
use super::{ModelReport, Outcome, Recorded, Report, SessionError, Status, ended};
use crate::assess;
use crate::models::Tuning;
use crate::procedures::Nephrectomy;
use crate::procedures::nephrectomy::TUNED_MODEL;
use crate::scenario::Scenario;
use crate::sim::{Clock, InputFrame, Pacing, SimEvent, Snapshot, TissueModel};
use crate::trace::{Recording, RecordingHeader, RecordingWriter, Tail, TuningRecord};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// A session in progress.
pub struct Live {
    scenario: Scenario,
    scenario_text: String,
    session_id: String,
    proc_: Nephrectomy,
    clock: Clock,
    /// The recording streams here when the session has an output folder...
    writer: Option<RecordingWriter>,
    /// ...and is kept in memory when it has none.
    frames: Vec<InputFrame>,
    tunings: Vec<TuningRecord>,
    events: Vec<SimEvent>,
    ended: String,
    start: Instant,
}

impl Live {
    /// A new session with a new id.
    pub fn new(
        scenario_text: &str,
        scenario_file: &str,
        pacing: Pacing,
    ) -> Result<Live, SessionError> {
        Self::with_id(scenario_text, scenario_file, pacing, &new_session_id())
    }

    /// A session under a given id (a replay keeps its recording's; an old recording has
    /// none, and gets a new one).
    pub fn with_id(
        scenario_text: &str,
        scenario_file: &str,
        pacing: Pacing,
        session_id: &str,
    ) -> Result<Live, SessionError> {
        let scenario = Scenario::parse(scenario_file, scenario_text)?;
        let proc_ = Nephrectomy::new(scenario.clone())?;
        Ok(Live {
            clock: Clock::new(scenario.dt_s, pacing),
            scenario,
            scenario_text: scenario_text.to_string(),
            session_id: if session_id.is_empty() {
                new_session_id()
            } else {
                session_id.to_string()
            },
            proc_,
            writer: None,
            frames: Vec::new(),
            tunings: Vec::new(),
            events: Vec::new(),
            ended: ended::END_OF_INPUT.to_string(),
            start: Instant::now(),
        })
    }

    /// Streams the recording to `path` from now on (call before the first step).
    pub fn stream_to(&mut self, path: &Path) -> Result<(), SessionError> {
        let header = RecordingHeader {
            session_id: &self.session_id,
            procedure: &self.scenario.procedure,
            dt_s: self.scenario.dt_s,
            scenario: &self.scenario_text,
        };
        let mut w = RecordingWriter::create(path, &header).map_err(io(path))?;
        for f in &self.frames {
            w.push_frame(f).map_err(io(path))?;
        }
        self.frames.clear();
        self.writer = Some(w);
        Ok(())
    }

    pub fn session_id(&self) -> &str {
        &self.session_id
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

    /// How the session will say it ended (see [`ended`]).
    pub fn set_ended(&mut self, how: &str) {
        self.ended = how.to_string();
    }

    pub fn ended(&self) -> &str {
        &self.ended
    }

    fn recording_failed(&self, source: std::io::Error) -> SessionError {
        SessionError::Recording {
            path: self
                .writer
                .as_ref()
                .map_or_else(String::new, |w| w.path().display().to_string()),
            step: self.clock.step(),
            source,
        }
    }

    /// One step with this input; the events it raised are returned (and kept). A recording
    /// that cannot be written stops the session with an error.
    pub fn step(&mut self, frame: InputFrame) -> Result<&[SimEvent], SessionError> {
        let step = self.clock.step();
        let before = self.events.len();
        self.proc_.step(&frame, step, &mut self.events);
        match self.writer.as_mut().map(|w| w.push_frame(&frame)) {
            Some(Err(e)) => return Err(self.recording_failed(e)),
            Some(Ok(())) => {}
            None => self.frames.push(frame),
        }
        self.clock.tick();
        Ok(&self.events[before..])
    }

    /// Writes what the recording holds so far when a second has passed (for loops that wait
    /// between steps, such as a lost XR session).
    pub fn flush_if_due(&mut self) -> Result<(), SessionError> {
        match self.writer.as_mut().map(RecordingWriter::flush_if_due) {
            Some(Err(e)) => Err(self.recording_failed(e)),
            _ => Ok(()),
        }
    }

    /// Changes the tuned model's spring, damping, pressure and offset from the next step on;
    /// the change is recorded (a replay makes it at the same step) and raised as an event.
    pub fn tune(&mut self, t: Tuning) -> Result<(), String> {
        t.check()
            .map_err(|(key, m)| format!("{TUNED_MODEL}.{key}: {m}"))?;
        let record = TuningRecord {
            step: self.clock.step(),
            model: TUNED_MODEL.to_string(),
            values: Tuning::RANGES
                .iter()
                .zip(t.values())
                .map(|((k, _, _), v)| ((*k).to_string(), v))
                .collect(),
        };
        if let Some(w) = self.writer.as_mut() {
            w.push_tuning(&record).map_err(|e| e.to_string())?;
        } else {
            self.tunings.push(record);
        }
        self.proc_.tune_kidney(&t);
        self.note(crate::sim::EventKind::TissueTuned {
            model: TUNED_MODEL.into(),
            tuning: t,
        });
        Ok(())
    }

    /// Makes a recorded tuning.
    pub fn tune_recorded(&mut self, r: &TuningRecord) -> Result<(), String> {
        if r.model != TUNED_MODEL {
            return Err(format!(
                "step {}: model '{}' has no tunable parameters",
                r.step, r.model
            ));
        }
        let mut t = self.tuning();
        for (key, v) in &r.values {
            match key.as_str() {
                "spring_n_per_m" => t.spring_n_per_m = *v,
                "damping_per_s" => t.damping_per_s = *v,
                "pressure_pa" => t.pressure_pa = *v,
                "offset_m" => t.offset_m = *v,
                other => return Err(format!("step {}: unknown parameter '{other}'", r.step)),
            }
        }
        self.tune(t)
    }

    /// The tuned model's parameters now.
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

    /// Ends the session: the recording is finished (end block, synced) and the report made.
    pub fn finish(self, captured: Vec<Snapshot>) -> Result<Outcome, SessionError> {
        let wall_s = self.start.elapsed().as_secs_f64();
        let recording = match self.writer {
            Some(w) => {
                let path = w.path().to_path_buf();
                let step = self.clock.step();
                w.finish(&self.ended)
                    .map_err(|source| SessionError::Recording {
                        path: path.display().to_string(),
                        step,
                        source,
                    })?;
                Recorded::Streamed(path)
            }
            None => Recorded::InMemory(Recording {
                procedure: self.scenario.procedure.clone(),
                session_id: self.session_id.clone(),
                dt_s: self.scenario.dt_s,
                scenario: self.scenario_text,
                frames: self.frames,
                tunings: self.tunings,
                tail: Tail::Ended {
                    how: self.ended.clone(),
                },
            }),
        };
        let proc_ = self.proc_;
        let scenario = self.scenario;
        let clock = self.clock;
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
            session_id: self.session_id,
            completed: proc_.is_completed(),
            ended: self.ended,
            dt_s: scenario.dt_s,
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
        Ok(Outcome {
            report,
            events: self.events,
            recording,
            wall_s,
            captured,
        })
    }
}
