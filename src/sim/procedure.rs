//! What every procedure is to the rest of the program: its description (name, paper, default
//! scenario, demo trace, task checklist, instruments, camera), the `Procedure` trait the
//! session steps, snapshots, asks for status and reports through, and the words every layer
//! shares about a running task (tools, plans, tunables, reports, status). Nothing here names
//! an organ or a procedure: the registry at the top lists them.

use super::{Hand, InputFrame, ModelSet, SimEvent, Snapshot};
use crate::scenario::InputError;
use glam::Vec3;

/// One step of a procedure's task, as its checklist shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TaskStep {
    /// The id the procedure raises in `task_step` events.
    pub id: &'static str,
    /// What the trainee does, for people.
    pub text: &'static str,
}

/// Ticks off the checklist in order: while the next step's entry in `done` holds, it is
/// recorded in `steps_done` and raised as a `task_step` event (so a step done early waits
/// its turn).
pub fn tick_off(
    steps: &[TaskStep],
    done: &[bool],
    steps_done: &mut Vec<String>,
    events: &mut Vec<super::EventKind>,
) {
    while let Some(next) = steps.get(steps_done.len()) {
        if !done.get(steps_done.len()).copied().unwrap_or(false) {
            break;
        }
        steps_done.push(next.id.to_string());
        events.push(super::EventKind::TaskStep {
            name: next.id.to_string(),
        });
    }
}

/// The `out_of_order` event for an action of task step `step` taken while an earlier step
/// of `steps` is still to do (`steps_done` are the ids done, in order); none when every step
/// before it is done, or `step` is not one of them.
pub fn out_of_order(
    steps: &[TaskStep],
    steps_done: &[String],
    step: &str,
) -> Option<super::EventKind> {
    let at = steps.iter().position(|s| s.id == step)?;
    let next = steps
        .iter()
        .position(|s| !steps_done.iter().any(|d| d == s.id))?;
    (next < at).then(|| super::EventKind::OutOfOrder {
        step: step.to_string(),
        expected: steps[next].id.to_string(),
    })
}

/// What an instrument does, so input devices and feedback know how to drive it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ToolKind {
    /// Jaws that hold tissue (grip closes them); pushes back when pressed into tissue.
    Grasper,
    /// A pointer whose beam identifies, marks (mark button) and cuts (trigger).
    Laser,
    /// A rigid tip for palpation and pushing.
    Probe,
    /// An electrosurgical L-hook: it presses tissue along its whole shape, and its current
    /// (the trigger) cuts what its end touches.
    Hook,
    /// A steerable flexible instrument held at its handle (an interventional one): the
    /// handle's travel pushes it in, the trigger bends its tip, the grip twists it.
    Steerable,
}

/// The instrument one hand holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolInfo {
    pub hand: Hand,
    /// Its name for people and alarms ("grasper", "laser").
    pub name: &'static str,
    pub kind: ToolKind,
    /// Contact force at which vibration or a force alarm reaches full scale, newtons.
    pub full_scale_n: f32,
}

/// Where the operating field is seen from: the headless and headset viewpoint, and where the
/// desktop camera starts. Metres, field frame (y up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Viewpoint {
    pub eye: Vec3,
    pub target: Vec3,
}

/// A procedure's scenario, read enough to plan the session before anything is built.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Simulation step, seconds.
    pub dt_s: f32,
    /// Snapshots published for renderers per second.
    pub publish_hz: f32,
    /// Simulated points the models will have (for the cost estimate).
    pub nodes: u64,
}

impl Plan {
    /// Steps between two snapshots published for renderers (`publish_hz`), at least one.
    pub fn publish_every(&self) -> u64 {
        ((1.0 / self.publish_hz) / self.dt_s).round().max(1.0) as u64
    }
}

/// Why a procedure could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error("building the anatomy: {0}")]
    Mesh(#[from] crate::mesh::MeshError),
    /// A model's own failure (a precomputation, a solver), carried without naming it.
    #[error(transparent)]
    Model(#[from] ModelError),
}

/// A model's own error, carried up through the core (which names no model): what was being
/// done, and the model's error.
#[derive(Debug, thiserror::Error)]
#[error("{doing}: {source}")]
pub struct ModelError {
    /// What was being done ("precomputing the tissue's responses").
    pub doing: &'static str,
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync>,
}

impl ModelError {
    pub fn new(
        doing: &'static str,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Self {
            doing,
            source: Box::new(source),
        }
    }
}

/// A force-feedback device a procedure is made for, or the command line asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceChoice {
    /// The simulated stylus, playing its scripted press.
    Sim,
    /// A Phantom Omni or Touch through OpenHaptics HD (`libHD.so`).
    Phantom,
    /// A Novint Falcon (or omega) through Force Dimension DHD (`libdhd.so`).
    Falcon,
}

impl DeviceChoice {
    /// Its name on the command line.
    pub fn flag(self) -> &'static str {
        match self {
            DeviceChoice::Sim => "sim",
            DeviceChoice::Phantom => "phantom",
            DeviceChoice::Falcon => "falcon",
        }
    }
}

/// Builds a procedure from a scenario (`file` names it in errors).
pub type BuildFn = fn(file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError>;

/// A procedure as the registry lists it.
pub struct ProcedureInfo {
    /// The name used on the command line, in scenarios, traces and recordings.
    pub name: &'static str,
    /// A title for people.
    pub title: &'static str,
    /// The paper it follows (file under `shared/papers/`).
    pub paper: &'static str,
    /// The default scenario (TOML text).
    pub scenario: &'static str,
    /// The demo trace `vesalius demo`, `bench` and `profile` play (TOML text).
    pub demo_trace: &'static str,
    /// The task's steps, in order.
    pub steps: &'static [TaskStep],
    /// The instrument in each hand: left, right.
    pub tools: [ToolInfo; 2],
    /// The viewpoint over the field.
    pub view: Viewpoint,
    /// Where the desktop mode parks each instrument before the trainee moves (left, right):
    /// over the field, pointing away from it.
    pub desk_park: [Vec3; 2],
    /// The parameter tables its scenario holds that have a table of specs: (scenario table,
    /// specs). They drive validation, sliders and `docs/parameters.md`.
    pub param_tables: &'static [(&'static str, &'static [crate::params::ParamSpec])],
    /// Its assessment tree (TOML text, `assets/assessment/<name>.toml`): how its measures
    /// are weighed into the score and the level of expertise.
    pub assessment: &'static str,
    /// What surrounds its models in the picture (cavity, neighbouring anatomy) and the
    /// laparoscope that sees them: built once per renderer.
    pub field: fn() -> super::field::OperativeField,
    /// Its metrics before anything happened (a JSON object): the measures it reports, by
    /// which trees are checked.
    pub blank_metrics: fn() -> serde_json::Value,
    /// Reads and checks a scenario for planning (`file` names it in errors).
    pub plan: fn(file: &str, text: &str) -> Result<Plan, InputError>,
    /// Builds the procedure from a scenario.
    pub build: BuildFn,
    /// What only some procedures have ([`Options::NONE`] for none of it).
    pub options: Options,
}

/// What only some procedures have: a laparoscope hand, instruments to swap, a paper's
/// profiler counters, legacy recordings, a precomputation, scene-wide reference cases,
/// benchmarks of their own, another force-feedback device.
#[derive(Clone, Copy)]
pub struct Options {
    /// Its paper's profiler counters (CPU and GPU columns) for `vesalius profile` to print
    /// beside ours; none where the paper gives none.
    pub profile_reference: Option<fn() -> [crate::profiler::PaperColumn; 2]>,
    /// Simulated seconds of `vesalius bench`'s all-awake pass (a model of a million points
    /// all awake steps far slower than real time).
    pub bench_all_awake_s: f64,
    /// The hand whose primary button makes its device drive the laparoscope (its instrument
    /// waits meanwhile), if any.
    pub scope_hand: Option<Hand>,
    /// The hand whose buttons work the procedure's imaging, if it has any (trigger: the
    /// fluoroscope's pedal, grip: a puff of contrast, primary button: the roadmap): the
    /// desktop gives them keys.
    pub imaging_hand: Option<Hand>,
    /// The other instruments one hand can change to with its primary button (the scrub
    /// nurse hands the next over; after the last, the hand's own comes back), all for the
    /// same hand; empty where the procedure offers none. The snapshot's
    /// `ToolSnapshot::instrument` says which the hand holds.
    pub swap: &'static [ToolInfo],
    /// The model that tunings in recordings of format versions 1 and 2 (which name no model)
    /// were made to; none for a procedure that had no such recordings.
    pub legacy_tuned_model: Option<&'static str>,
    /// The force-feedback device `--haptics default` opens for it (the paper's own).
    pub haptic_device: DeviceChoice,
    /// Benchmarks of its own beyond the stepping (a precomputation, a haptic-rate update at
    /// its largest), appended to `vesalius bench`'s lines; none for most.
    pub bench_extra: Option<super::bench::ExtraBench>,
    /// The benchmark lines of its models' GPU compute path (`vesalius bench --compute gpu`),
    /// on the device it is given; none where no model of it has one yet.
    pub gpu_bench: Option<super::bench::GpuBench>,
    /// Its preset for machines without a GPU (`--preset cpu`): the scenario keys that differ
    /// from its own scenario (TOML text, laid over it by [`crate::scenario::with_preset`]);
    /// none where the default already keeps real time on two cores.
    pub cpu_preset: Option<&'static str>,
    /// Its reference cases that need its whole scene (the models' own are `vesalius
    /// verify`'s already); `vesalius verify` runs them after the models'.
    pub cases: fn() -> Vec<super::Case>,
    /// The same on the GPU compute path (`vesalius verify --compute gpu`); none for most.
    pub gpu_cases: fn() -> Vec<super::Case>,
    /// The cases at its CPU preset's sizes (`vesalius verify --preset cpu`), read from the
    /// preset; none without a preset.
    pub preset_cases: fn() -> Vec<super::Case>,
    /// The precomputation it needs before its first session (`vesalius precompute`), if any.
    pub precompute: Option<&'static super::precompute::Precomputable>,
}

impl Options {
    /// None of it: no laparoscope hand, no swaps, no profiler reference, no legacy
    /// recordings, no precomputation, no scene cases, no extra benchmarks; the Phantom;
    /// the default all-awake benchmark.
    pub const NONE: Options = Options {
        profile_reference: None,
        bench_all_awake_s: super::bench::ALL_AWAKE_S,
        scope_hand: None,
        imaging_hand: None,
        swap: &[],
        legacy_tuned_model: None,
        haptic_device: DeviceChoice::Phantom,
        bench_extra: None,
        gpu_bench: None,
        cpu_preset: None,
        gpu_cases: Vec::new,
        preset_cases: Vec::new,
        cases: Vec::new,
        precompute: None,
    };
}

impl std::fmt::Debug for ProcedureInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProcedureInfo")
            .field("name", &self.name)
            .field("title", &self.title)
            .finish_non_exhaustive()
    }
}

impl ProcedureInfo {
    /// Its scenario with its CPU preset laid over it, named as the preset's file; None
    /// without a preset.
    pub fn cpu_preset_scenario(&self) -> Option<Result<(String, String), InputError>> {
        let overlay = self.options.cpu_preset?;
        let file = format!("assets/presets/cpu/{}.toml", self.name);
        let scenario = format!("builtin {} scenario", self.name);
        Some(
            crate::scenario::with_preset(&scenario, self.scenario, &file, overlay)
                .map(|t| (file, t)),
        )
    }

    /// The instrument `hand` holds.
    pub fn tool(&self, hand: Hand) -> &ToolInfo {
        &self.tools[hand.index()]
    }

    /// The hand whose primary button changes its instrument, if any.
    pub fn swap_hand(&self) -> Option<Hand> {
        self.options.swap.first().map(|t| t.hand)
    }

    /// The instrument `hand` holds when its snapshot says `instrument` (0: its own).
    pub fn held_tool(&self, hand: Hand, instrument: u8) -> &ToolInfo {
        match instrument {
            0 => self.tool(hand),
            k => self
                .options
                .swap
                .get(usize::from(k) - 1)
                .filter(|t| t.hand == hand)
                .unwrap_or(self.tool(hand)),
        }
    }
}

/// One value the supervisor may change during a session (a slider), with its table entry.
#[derive(Debug, Clone, PartialEq)]
pub struct Tunable {
    /// The model it belongs to: its table in the scenario.
    pub model: String,
    /// The key in the model's scenario table.
    pub key: &'static str,
    /// A label with its unit, for the slider.
    pub label: &'static str,
    pub min: f32,
    pub max: f32,
    /// The slider shows values multiplied by this (1000: metres as millimetres).
    pub scale: f32,
    /// The value now.
    pub value: f32,
}

/// Sizes of one model, for reports and benchmarks.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ModelReport {
    pub name: String,
    pub kind: String,
    pub vertices: usize,
    pub triangles: usize,
    pub constraints: usize,
    /// A mass-spring model's particulars.
    #[serde(flatten)]
    pub mass_spring: MassSpring,
    /// The adapter its substeps ran on, where they ran on a GPU (absent: on the CPU).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu: Option<String>,
}

/// A mass-spring model's mass points and springs and its time integrator, for reports and
/// benchmarks (each left out of the JSON when absent, as for other models).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MassSpring {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nodes: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub springs: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integrator: Option<&'static str>,
    /// An explicit integrator's substeps a step (the last step's) and its stability limit, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub substeps: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_limit_s: Option<f32>,
}

/// How the task stands now, for the panels, the alarms and the report.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TaskStatus {
    /// Step ids done, in order.
    pub steps_done: Vec<String>,
    pub completed: bool,
    /// Score so far, 0-100.
    pub score: f32,
    /// Errors so far (vulnerable structures touched, tissue torn, ...).
    pub errors: u32,
    /// Instrument path length so far (left, right), metres.
    pub path_m: [f32; 2],
    /// Live figures for the panels: a label and a formatted value.
    pub figures: Vec<(String, String)>,
    /// Whether each instrument touches a vulnerable structure.
    pub touching: [bool; 2],
    /// The nearest vulnerable structure near each instrument, and its distance, metres.
    pub near: [Option<(String, f32)>; 2],
}

/// A procedure's part of the session report.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcedureReport {
    pub completed: bool,
    /// The procedure's own metrics (a JSON object).
    pub metrics: serde_json::Value,
    /// The score's components (a JSON object).
    pub score_parts: serde_json::Value,
    pub score: f32,
    pub errors: u32,
}

/// A running procedure: models, instruments and task composed from a scenario. The session
/// steps it once per input frame and asks it for snapshots, status and its report.
pub trait Procedure: Send {
    fn info(&self) -> &'static ProcedureInfo;
    /// The simulation step of its scenario, seconds.
    fn dt_s(&self) -> f32;
    /// Advances one step with this input; what happened goes into `events`.
    fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>);
    /// What renderers need of this instant.
    fn snapshot(&mut self, step: u64) -> Snapshot;
    /// [`Procedure::snapshot`] as a job: what must be read of the simulation is read now,
    /// and the rest of the build may run on another thread (the same snapshot either way).
    /// By default everything is built now.
    fn snapshot_job(&mut self, step: u64) -> super::SnapshotJob {
        super::SnapshotJob::ready(self.snapshot(step))
    }
    /// How the task stands; vulnerable structures are looked for within `near_m`.
    fn status(&self, near_m: f32) -> TaskStatus;
    /// The report at the end of the session.
    fn report(&self) -> ProcedureReport;
    /// Reaction force on each instrument (left, right) after the last step, newtons.
    fn reactions(&self) -> [Vec3; 2];
    /// Where each instrument touches tissue after the last step: the point and the tissue's
    /// outward normal there (none: no contact).
    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2];
    /// Where each instrument (left, right) works after the last step, for the motion
    /// analysis (`assess::motion`); none: the hands' positions stand for them.
    fn instrument_tips(&self) -> Option<[Vec3; 2]> {
        None
    }
    /// The world its models step in, for the model figures below (a procedure whose models
    /// are not in a world yet gives none and answers those itself).
    fn models(&self) -> Option<&dyn ModelSet> {
        None
    }
    fn models_mut(&mut self) -> Option<&mut dyn ModelSet> {
        None
    }
    /// Each model's sizes.
    fn model_reports(&self) -> Vec<ModelReport> {
        self.models().map_or_else(Vec::new, ModelSet::model_reports)
    }
    /// Wall-clock seconds each model has spent stepping so far (benchmarks only).
    fn model_times(&self) -> Vec<f64> {
        self.models().map_or_else(Vec::new, ModelSet::model_times)
    }
    /// Heap bytes by part.
    fn memory(&self) -> Vec<(&'static str, usize)> {
        self.models().map_or_else(Vec::new, ModelSet::memory)
    }
    /// The mean share of each model's points awake so far (benchmarks): the world's, and 1
    /// for each further line a procedure reports (a part of a model, or its couplings).
    fn awake_fractions(&self) -> Vec<f64> {
        let mut a = self
            .models()
            .map_or_else(Vec::new, ModelSet::awake_fractions);
        a.resize(a.len().max(self.model_reports().len()), 1.0);
        a
    }
    /// Keeps every point of every model stepping from now on (benchmarks).
    fn stay_awake(&mut self) {
        if let Some(m) = self.models_mut() {
            m.stay_awake();
        }
    }
    /// A deterministic digest of the state, for replay and determinism checks (a procedure
    /// with state beyond its world's models adds it in its own).
    fn state_hash(&self) -> u64 {
        self.models().map_or(0, ModelSet::state_hash)
    }
    /// The values the supervisor may tune now (none by default).
    fn tunables(&self) -> Vec<Tunable> {
        Vec::new()
    }
    /// Changes tunable values of `model` (its scenario table) from the next step on (all or
    /// none); by default there is nothing to tune.
    fn tune(
        &mut self,
        model: &str,
        values: &[(String, f32)],
    ) -> Result<(), crate::params::TuneError> {
        let _ = values;
        Err(crate::params::TuneError::NoSuchModel(model.to_string()))
    }
    /// Whether the task is done.
    fn is_completed(&self) -> bool;
}

impl ProcedureReport {
    /// A report of a procedure's own `metrics` and `score_parts` (written as JSON objects).
    pub fn of(
        completed: bool,
        errors: u32,
        metrics: &impl serde::Serialize,
        score_parts: &impl serde::Serialize,
        score: f32,
    ) -> Self {
        Self {
            completed,
            errors,
            metrics: serde_json::to_value(metrics).unwrap_or_default(),
            score_parts: serde_json::to_value(score_parts).unwrap_or_default(),
            score,
        }
    }
}

/// A session's state at one step, as the supervisor's panels show it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SessionStatus {
    pub step: u64,
    /// Simulated time, seconds.
    pub time_s: f64,
    /// Instrument tip path length so far (left, right), metres.
    pub path_m: [f32; 2],
    /// Errors so far (the procedure counts them).
    pub errors: u32,
    /// Score so far (0-100), by the scenario's weights.
    pub score: f32,
    /// Task step ids done, in order.
    pub steps_done: Vec<String>,
    pub completed: bool,
    /// Contact force on each tool, newtons.
    pub force_n: [f32; 2],
    /// Whether each tool touches a vulnerable structure.
    pub touching: [bool; 2],
    /// The nearest vulnerable structure near each tool, and its distance, metres.
    pub near: [Option<(String, f32)>; 2],
    /// The procedure's live figures: a label and a formatted value.
    pub figures: Vec<(String, String)>,
    /// The dynamic assessment's newest instructions to the trainee, newest first.
    pub instructions: Vec<String>,
    /// The instructions given in the last `INSTRUCTION_CURRENT_S` (the session's) simulated seconds, newest
    /// first, words only: what the headset's panel shows.
    pub current_instructions: Vec<String>,
    /// The values the supervisor may tune, as they are now.
    pub tunables: Vec<Tunable>,
}
