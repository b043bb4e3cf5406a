//! A session stepped from outside (the XR frame loop, the window's simulation thread, the
//! headless loop): the procedure, its clock, its events and its recording.

use super::output::{io, new_session_id};
use super::{Outcome, Recorded, Report, SessionError, Status, ended};
use crate::assess::{Assessment, Tree};
use crate::params::TuneError;
use crate::procedures::{Plan, Procedure, ProcedureInfo, Tunable};
use crate::sim::{
    Clock, HapticFrame, HapticSlot, InputFrame, Pacing, SimEvent, Snapshot, ToolHaptics,
};
use crate::trace::{Recording, RecordingHeader, RecordingWriter, Tail, TuningRecord};
use std::cell::Cell;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// A session in progress.
pub struct Live {
    info: &'static ProcedureInfo,
    plan: Plan,
    scenario_text: String,
    session_id: String,
    proc_: Box<dyn Procedure>,
    clock: Clock,
    /// The recording streams here when the session has an output folder...
    writer: Option<RecordingWriter>,
    /// ...and is kept in memory when it has none.
    frames: Vec<InputFrame>,
    tunings: Vec<TuningRecord>,
    events: Vec<SimEvent>,
    ended: String,
    start: Instant,
    /// The newest haptic frame, for device loops and vibration.
    haptics: Arc<HapticSlot>,
    last_haptics: HapticFrame,
    /// Raises an alarm event when a condition begins (a tool near or on a vulnerable
    /// structure, a holding tool pressing too hard).
    alarms: crate::assess::alarms::AlarmWatch,
    /// The tree that scores the session (the procedure's own unless one was given).
    tree: Tree,
    /// The live score and the step it was taken at (the tree is evaluated at most every
    /// [`LIVE_SCORE_EVERY`] steps).
    live_score: Cell<(u64, f32)>,
    /// The tree's rules as last evaluated, and the instructions they gave (time, words).
    rule_state: Vec<crate::assess::rules::RuleState>,
    instructions: Vec<(f64, String)>,
    /// The session over time for reports' plots, a sample every [`RULES_EVERY_S`].
    timeline: Vec<super::Sample>,
    /// The instruments' path lengths at the last sample (for their speeds), m.
    last_path_m: [f32; 2],
    /// The instruments' tips over the session, for the motion analysis...
    motion: crate::assess::motion::MotionRecorder,
    /// ...and its last analysis with the samples it was made of.
    motion_now: std::cell::RefCell<(u64, crate::assess::motion::Motion)>,
}

/// Simulated seconds between two evaluations of the dynamic assessment's rules.
const RULES_EVERY_S: f64 = 0.1;
/// Instructions the panels show (the newest).
const INSTRUCTIONS_SHOWN: usize = 5;

/// Steps between two evaluations of the tree for the panels' live score.
const LIVE_SCORE_EVERY: u64 = 50;

/// Weight of the newest estimate in the smoothed stiffness.
const STIFFNESS_SMOOTHING: f32 = 0.1;
/// The stiffest tissue the estimate reports, N/m (a tool pressed on bone).
const MAX_STIFFNESS_N_PER_M: f32 = 1e5;

/// One instrument's haptics after a step, its stiffness estimated from the last frame: the
/// change of force along the normal over the change of depth, when the tip moved.
fn feel(
    before: &ToolHaptics,
    force_n: glam::Vec3,
    contact: Option<(glam::Vec3, glam::Vec3)>,
) -> ToolHaptics {
    let Some((point, normal)) = contact else {
        return ToolHaptics {
            force_n,
            ..ToolHaptics::default()
        };
    };
    let mut stiffness = if before.in_contact {
        before.stiffness_n_per_m
    } else {
        0.0
    };
    let deeper_m = (before.point - point).dot(normal);
    if before.in_contact && deeper_m.abs() > 1e-7 {
        let more_n = (force_n - before.force_n).dot(normal);
        let k = (more_n / deeper_m).clamp(0.0, MAX_STIFFNESS_N_PER_M);
        stiffness += STIFFNESS_SMOOTHING * (k - stiffness);
    }
    ToolHaptics {
        force_n,
        point,
        normal,
        stiffness_n_per_m: stiffness,
        in_contact: true,
    }
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
        let (info, plan) = crate::registry::plan(scenario_file, scenario_text)?;
        let tree = Tree::parse(
            &format!("builtin {} assessment", info.name),
            info.assessment,
        )?;
        let proc_ = (info.build)(scenario_file, scenario_text)?;
        Ok(Live {
            clock: Clock::new(plan.dt_s, pacing),
            info,
            plan,
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
            haptics: Arc::new(HapticSlot::new()),
            last_haptics: HapticFrame::default(),
            alarms: crate::assess::alarms::AlarmWatch::new(
                crate::assess::alarms::AlarmRules::for_procedure(info),
            ),
            tree,
            live_score: Cell::new((u64::MAX, 0.0)),
            rule_state: Vec::new(),
            instructions: Vec::new(),
            timeline: Vec::new(),
            last_path_m: [0.0; 2],
            motion: crate::assess::motion::MotionRecorder::new(),
            motion_now: std::cell::RefCell::new((u64::MAX, Default::default())),
        })
    }

    /// Steps from now on are paced in real time from where the session stands (a session
    /// warmed up as fast as possible, then run live: `vesalius profile`).
    pub fn pace_from_now(&mut self) {
        self.clock.pace_from_now();
    }

    /// The adapter the models step on, where any steps on a GPU.
    pub fn adapter(&self) -> Option<String> {
        self.proc_.model_reports().into_iter().find_map(|m| m.gpu)
    }

    /// The heap each part of the simulation holds, bytes.
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        self.proc_.memory()
    }

    /// After a pause: real-time pacing goes on from now.
    pub fn resume_pacing(&mut self) {
        self.clock.resume();
    }

    /// Scores the session with `tree` instead of the procedure's own (`file` names it in
    /// errors): it must be for this procedure and bind only measures it reports.
    pub fn set_assessment(&mut self, file: &str, tree: Tree) -> Result<(), SessionError> {
        crate::assess::check_for(self.info, file, &tree)?;
        self.tree = tree;
        self.live_score.set((u64::MAX, 0.0));
        self.rule_state.clear();
        Ok(())
    }

    /// The session's measures in a report of it.
    fn measures(
        &self,
        report: &crate::procedures::ProcedureReport,
    ) -> std::collections::BTreeMap<String, Option<f64>> {
        let steps_done = report
            .metrics
            .get("steps_done")
            .and_then(serde_json::Value::as_array)
            .map_or(0, Vec::len);
        let mut m = crate::assess::tree::measures(
            &report.metrics,
            report.completed,
            report.errors,
            steps_done,
            self.info.steps.len(),
            self.clock.time_s(),
        );
        m.extend(self.motion_analysis().measures());
        m
    }

    /// The motion analysis of the session so far (made again only when there are new
    /// samples).
    fn motion_analysis(&self) -> crate::assess::motion::Motion {
        let mut now = self.motion_now.borrow_mut();
        let taken = self.motion.samples();
        if now.0 != taken {
            *now = (taken, self.motion.analyse());
        }
        now.1.clone()
    }

    /// The session's measures now, scored by its tree.
    fn assess(&self, report: &crate::procedures::ProcedureReport) -> Assessment {
        self.tree.score(&self.measures(report))
    }

    /// Streams the recording to `path` from now on (call before the first step).
    pub fn stream_to(&mut self, path: &Path) -> Result<(), SessionError> {
        let header = RecordingHeader {
            session_id: &self.session_id,
            procedure: self.info.name,
            dt_s: self.plan.dt_s,
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
        self.plan.dt_s
    }

    /// The procedure's description (steps, tools, viewpoint).
    pub fn info(&self) -> &'static ProcedureInfo {
        self.info
    }

    /// A snapshot follows the next step: a model whose state lags on a device brings all of
    /// it back with that step, not in a round trip of the snapshot's own.
    pub fn snapshot_follows(&mut self) {
        if let Some(m) = self.proc_.models_mut() {
            m.read_whole_after_step();
        }
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.clock.time_s()
    }

    /// Steps between two snapshots published for renderers (the scenario's `publish_hz`).
    pub fn publish_every(&self) -> u64 {
        self.plan.publish_every()
    }

    /// Steps that cover `duration_s` of simulated time.
    pub fn steps_for(&self, duration_s: f64) -> u64 {
        (duration_s / f64::from(self.plan.dt_s)).ceil() as u64
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
        let _span = tracing::debug_span!("session_step", step).entered();
        let before = self.events.len();
        {
            let _s = tracing::debug_span!("procedure_step", procedure = self.proc_.info().name)
                .entered();
            self.proc_.step(&frame, step, &mut self.events);
        }
        match self.writer.as_mut().map(|w| w.push_frame(&frame)) {
            Some(Err(e)) => return Err(self.recording_failed(e)),
            Some(Ok(())) => {}
            None => self.frames.push(frame),
        }
        self.clock.tick();
        let tips = self
            .proc_
            .instrument_tips()
            .unwrap_or_else(|| frame.hands.map(|h| h.pose.position));
        let acting = frame
            .hands
            .map(|h| h.buttons.trigger > 0.5 || h.buttons.grip > 0.5 || h.buttons.mark);
        self.motion.record(self.clock.time_s(), tips, acting);
        let forces = self.proc_.reactions();
        let contacts = self.proc_.contacts_now();
        let last = self.last_haptics.tools;
        self.last_haptics = HapticFrame {
            step,
            time_s: self.clock.time_s(),
            tools: [0, 1].map(|k| feel(&last[k], forces[k], contacts[k])),
        };
        self.haptics.publish(&self.last_haptics);
        self.raise_alarms(step);
        self.instruct(step);
        Ok(&self.events[before..])
    }

    /// Every [`RULES_EVERY_S`] of simulated time: the dynamic assessment (the tree's rules on
    /// the measures now; an `instruction` event for each whose condition began) and a sample
    /// of the timeline (the instruments' speeds and forces, the score so far).
    fn instruct(&mut self, step: u64) {
        let every = ((RULES_EVERY_S / f64::from(self.plan.dt_s)).round() as u64).max(1);
        if !(step + 1).is_multiple_of(every) {
            return;
        }
        let report = self.proc_.report();
        let measures = self.measures(&report);
        let time_s = self.clock.time_s();
        let path = self.proc_.status(0.0).path_m;
        let span = (every as f64 * f64::from(self.plan.dt_s)) as f32;
        let forces = self.proc_.reactions();
        self.timeline.push(super::Sample {
            t_s: time_s as f32,
            speed_m_per_s: [0, 1].map(|k| (path[k] - self.last_path_m[k]).max(0.0) / span),
            force_n: forces.map(|f| f.length()),
            score: self.tree.score(&measures).score as f32,
        });
        self.last_path_m = path;
        let spoke =
            crate::assess::rules::evaluate(&self.tree.rules, &mut self.rule_state, &measures);
        for r in spoke {
            self.instructions.push((time_s, r.say.clone()));
            self.events.push(SimEvent {
                step,
                kind: crate::sim::EventKind::Instruction {
                    rule: r.id.clone(),
                    message: r.say.clone(),
                },
            });
        }
    }

    /// Alarm events for the conditions that began with this step.
    fn raise_alarms(&mut self, step: u64) {
        let t = self.proc_.status(self.alarms.rules.near_m);
        let f = self.proc_.reactions();
        let status = Status {
            step,
            time_s: self.clock.time_s(),
            force_n: [f[0].length(), f[1].length()],
            touching: t.touching,
            near: t.near,
            ..Status::default()
        };
        let (_, raised) = self.alarms.update(&status);
        for a in raised {
            self.events.push(SimEvent {
                step,
                kind: crate::sim::EventKind::Alarm {
                    tool: a.tool.to_string(),
                    message: a.message(),
                },
            });
        }
    }

    /// Writes what the recording holds so far when a second has passed (for loops that wait
    /// between steps, such as a lost XR session).
    pub fn flush_if_due(&mut self) -> Result<(), SessionError> {
        match self.writer.as_mut().map(RecordingWriter::flush_if_due) {
            Some(Err(e)) => Err(self.recording_failed(e)),
            _ => Ok(()),
        }
    }

    /// Changes tunable values of `model` from the next step on; the change is recorded (a
    /// replay makes it at the same step) and raised as an event. Values out of their ranges
    /// are refused and change nothing.
    pub fn tune(&mut self, model: &str, values: &[(String, f32)]) -> Result<(), TuneError> {
        self.proc_.tune(model, values)?;
        let record = TuningRecord {
            step: self.clock.step(),
            model: model.to_string(),
            values: values.to_vec(),
        };
        if let Some(w) = self.writer.as_mut() {
            w.push_tuning(&record)?;
        } else {
            self.tunings.push(record);
        }
        self.note(crate::sim::EventKind::TissueTuned {
            model: model.to_string(),
            values: values.iter().cloned().collect(),
        });
        Ok(())
    }

    /// Makes a recorded tuning.
    pub fn tune_recorded(&mut self, r: &TuningRecord) -> Result<(), TuneError> {
        self.tune(&r.model, &r.values)
            .map_err(|e| TuneError::AtStep {
                step: r.step,
                source: Box::new(e),
            })
    }

    /// The values the supervisor may tune now.
    pub fn tunables(&self) -> Vec<Tunable> {
        self.proc_.tunables()
    }

    /// Adds an event from outside the simulation (a controller lost, a session restarted).
    pub fn note(&mut self, kind: crate::sim::EventKind) {
        let step = self.clock.step();
        self.events.push(SimEvent { step, kind });
    }

    /// Adds events from outside the simulation that carry their own steps (a servo loop's
    /// clamps and stalls), in step order among the session's own (stable: at a tie the
    /// session's come first).
    pub fn merge_events(&mut self, more: Vec<SimEvent>) {
        let mine = std::mem::take(&mut self.events);
        self.events = merge_by_step(mine, more);
    }

    pub fn snapshot(&mut self) -> Snapshot {
        let _span = tracing::debug_span!("snapshot").entered();
        self.proc_.snapshot(self.clock.step())
    }

    /// [`Live::snapshot`] as a job whose build may run on another thread
    /// ([`crate::sim::SnapshotBus::publish_job`]).
    pub fn snapshot_job(&mut self) -> crate::sim::SnapshotJob {
        let _span = tracing::debug_span!("snapshot").entered();
        self.proc_.snapshot_job(self.clock.step())
    }

    pub fn is_completed(&self) -> bool {
        self.proc_.is_completed()
    }

    /// The haptic channel: the newest frame, readable from any thread without blocking the
    /// step.
    pub fn haptics(&self) -> Arc<HapticSlot> {
        self.haptics.clone()
    }

    /// Reaction force on each tool (left, right) after the last step, newtons.
    pub fn reactions(&self) -> [glam::Vec3; 2] {
        self.proc_.reactions()
    }

    /// The tree's score of the session so far (evaluated again every
    /// [`LIVE_SCORE_EVERY`] steps).
    pub fn live_score(&self) -> f32 {
        let step = self.clock.step();
        let (at, score) = self.live_score.get();
        if at != u64::MAX && step < at + LIVE_SCORE_EVERY {
            return score;
        }
        let score = self.assess(&self.proc_.report()).score as f32;
        self.live_score.set((step, score));
        score
    }

    /// How the session stands now, for the supervisor's panels; vulnerable structures are
    /// looked for within `near_m` of the tools.
    pub fn status(&self, near_m: f32) -> Status {
        let t = self.proc_.status(near_m);
        let f = self.proc_.reactions();
        Status {
            step: self.clock.step(),
            time_s: self.clock.time_s(),
            path_m: t.path_m,
            errors: t.errors,
            score: self.live_score(),
            instructions: self
                .instructions
                .iter()
                .rev()
                .take(INSTRUCTIONS_SHOWN)
                .map(|(t, m)| format!("{t:.1} s: {m}"))
                .collect(),
            current_instructions: self
                .instructions
                .iter()
                .rev()
                .take_while(|(t, _)| self.clock.time_s() - t <= super::INSTRUCTION_CURRENT_S)
                .map(|(_, m)| m.clone())
                .collect(),
            steps_done: t.steps_done,
            completed: t.completed,
            force_n: [f[0].length(), f[1].length()],
            touching: t.touching,
            near: t.near,
            figures: t.figures,
            tunables: self.proc_.tunables(),
        }
    }

    /// Ends the session: the recording is finished (end block, synced) and the report made.
    pub fn finish(self, captured: Vec<Snapshot>) -> Result<Outcome, SessionError> {
        let wall_s = self.start.elapsed().as_secs_f64();
        let mut done = self.proc_.report();
        crate::sim::shortest_f32(&mut done.metrics);
        crate::sim::shortest_f32(&mut done.score_parts);
        let assessment = self.assess(&done);
        let motion = self.motion_analysis();
        let scenario_digest = format!(
            "{:016x}",
            crate::assess::tree::fnv1a(self.scenario_text.as_bytes())
        );
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
                procedure: self.info.name.to_string(),
                session_id: self.session_id.clone(),
                dt_s: self.plan.dt_s,
                scenario: self.scenario_text,
                frames: self.frames,
                tunings: self.tunings,
                tail: Tail::Ended {
                    how: self.ended.clone(),
                },
            }),
        };
        let mut counts: BTreeMap<String, u64> = BTreeMap::new();
        for e in &self.events {
            *counts.entry(e.kind.name().to_string()).or_default() += 1;
        }
        let models = self.proc_.model_reports();
        let adapter = models.iter().find_map(|m| m.gpu.clone());
        let report = Report {
            procedure: self.info.name.to_string(),
            session_id: self.session_id,
            scenario_digest,
            completed: done.completed,
            ended: self.ended,
            dt_s: self.plan.dt_s,
            steps: self.clock.step(),
            simulated_s: self.clock.time_s(),
            compute: if adapter.is_some() { "gpu" } else { "cpu" },
            adapter,
            models,
            events: counts,
            errors: done.errors,
            metrics: done.metrics,
            score_parts: done.score_parts,
            score: assessment.score as f32,
            level: assessment.level.clone(),
            assessment,
            motion,
            timeline: self.timeline,
            state_hash: format!("{:016x}", self.proc_.state_hash()),
            replay_note: None,
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

/// `mine` (in step order) with `more` merged in by step; at a tie, `mine` first.
fn merge_by_step(mine: Vec<SimEvent>, mut more: Vec<SimEvent>) -> Vec<SimEvent> {
    more.sort_by_key(|e| e.step);
    let mut merged = Vec::with_capacity(mine.len() + more.len());
    let mut theirs = more.into_iter().peekable();
    for e in mine {
        while let Some(t) = theirs.next_if(|t| t.step < e.step) {
            merged.push(t);
        }
        merged.push(e);
    }
    merged.extend(theirs);
    merged
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::EventKind;

    #[test]
    fn outside_events_merge_in_step_order_after_the_sessions_own() {
        let e = |step, what: &str| SimEvent {
            step,
            kind: EventKind::TaskStep { name: what.into() },
        };
        let mine = vec![e(1, "a"), e(3, "b"), e(3, "c"), e(7, "d")];
        let more = vec![e(9, "z"), e(3, "y"), e(0, "x")];
        let names: Vec<String> = merge_by_step(mine, more)
            .into_iter()
            .map(|s| match s.kind {
                EventKind::TaskStep { name } => name,
                _ => String::new(),
            })
            .collect();
        assert_eq!(names, ["x", "a", "b", "c", "y", "d", "z"]);
    }
}
