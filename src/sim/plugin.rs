//! What every procedure's plug-in (`procedures/<name>/plugin.rs`) would otherwise write
//! again: its registry entry from what is its own (`procedure_info!`), the parts of
//! `impl Procedure` that follow from its fields and methods (`procedure_basics!`), its
//! scenario's plan (`scenario_plan!`), the checklist score most procedures keep
//! ([`ChecklistScore`]) and its pieces, and the short ways to write a model's report and an
//! instrument. Nothing here names an organ or a procedure.

use super::Hand;
use super::procedure::{MassSpring, ModelReport, TaskStep, ToolInfo, ToolKind};

/// A procedure's registry entry (`ProcedureInfo`) from what is its own, the rest from the
/// items beside the call, by their names there: `NAME`, `STEPS`, `Metrics` (its metrics,
/// blank by `Default`), `Scenario` (its `parse`), `scenario::PARAM_TABLES`, `scenario::plan`
/// and `field::field`. `build` makes the procedure of the file's name and its parsed
/// scenario (`?` passes errors on). `stem` names its assets: `assets/scenarios/<stem>.toml`,
/// `assets/traces/<stem>-demo.toml` and `assets/assessment/<stem>.toml`. The instruments are
/// the left hand's and the right hand's, `(name, kind, full scale in newtons)`; the view goes
/// from the eye to the target; the desktop's parking places are the left's and the right's;
/// what follows are [`super::Options`] fields, the rest of them `Options::NONE`'s.
#[macro_export]
macro_rules! procedure_info {
    (
        stem: $stem:literal, paper: $paper:expr,
        title: $title:expr,
        build: |$file:pat_param, $s:ident| $made:expr,
        tools: [
            ($lname:expr, $lkind:ident, $lfull:expr),
            ($rname:expr, $rkind:ident, $rfull:expr) $(,)?
        ],
        view: ($($eye:expr),+) -> ($($target:expr),+),
        desk_park: [($($left:expr),+), ($($right:expr),+) $(,)?],
        $($option:ident: $value:expr),* $(,)?
    ) => {
        $crate::sim::ProcedureInfo {
            name: NAME,
            title: $title,
            paper: $paper,
            scenario: include_str!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/assets/scenarios/",
                $stem,
                ".toml"
            )),
            demo_trace: include_str!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/assets/traces/",
                $stem,
                "-demo.toml"
            )),
            steps: &STEPS,
            tools: [
                $crate::sim::ToolInfo::left($lname, $crate::sim::ToolKind::$lkind, $lfull),
                $crate::sim::ToolInfo::right($rname, $crate::sim::ToolKind::$rkind, $rfull),
            ],
            view: $crate::sim::Viewpoint {
                eye: glam::Vec3::new($($eye),+),
                target: glam::Vec3::new($($target),+),
            },
            desk_park: [glam::Vec3::new($($left),+), glam::Vec3::new($($right),+)],
            param_tables: scenario::PARAM_TABLES,
            assessment: include_str!(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/assets/assessment/",
                $stem,
                ".toml"
            )),
            field: field::field,
            blank_metrics: || serde_json::to_value(Metrics::default()).unwrap_or_default(),
            plan: scenario::plan,
            build: |file: &str,
                    text: &str|
             -> Result<Box<dyn $crate::sim::Procedure>, $crate::sim::BuildError> {
                let $file = file;
                let $s = Scenario::parse(file, text)?;
                Ok(Box::new($made))
            },
            options: $crate::sim::Options {
                $($option: $value,)*
                ..$crate::sim::Options::NONE
            },
        }
    };
}

/// The part of `impl Procedure` every plug-in writes alike: its description `$info`, the step
/// of its `scenario` field's `dt_s`, and step and snapshot by its own methods of those names.
/// With `report(errors: ...)` also the report and the status of its `metrics` (scored by the
/// `score` function beside it; the status's live part from its own `panel` method), and the
/// reactions, state hash and completion by its own methods of those names; with `models:`
/// also the `world()` of the field it names (`[]`: its own) as its models.
#[macro_export]
macro_rules! procedure_basics {
    (
        $info:expr,
        report(errors: $($errors:ident).+),
        models: [$($owner:ident).*] $(,)?
    ) => {
        $crate::procedure_basics!($info, report(errors: $($errors).+));

        fn models(&self) -> Option<&dyn $crate::sim::ModelSet> {
            Some(self$(.$owner)*.world())
        }

        fn models_mut(&mut self) -> Option<&mut dyn $crate::sim::ModelSet> {
            Some(self$(.$owner)*.world_mut())
        }
    };
    ($info:expr, report(errors: $($errors:ident).+)) => {
        $crate::procedure_basics!($info);

        /// How the task stands: the checklist, the score and the errors of its `metrics`,
        /// and the live part of the panel (paths, figures, what the instruments touch or
        /// near) from its own `panel` method.
        fn status(&self, near_m: f32) -> $crate::sim::TaskStatus {
            let (score, _) = score(&self.scenario, &self.metrics);
            $crate::sim::TaskStatus {
                steps_done: self.metrics.steps_done.clone(),
                completed: Self::is_completed(self),
                score,
                errors: self.$($errors).+,
                ..Self::panel(self, near_m)
            }
        }

        fn reactions(&self) -> [glam::Vec3; 2] {
            Self::reactions(self)
        }

        fn state_hash(&self) -> u64 {
            Self::state_hash(self)
        }

        fn is_completed(&self) -> bool {
            Self::is_completed(self)
        }

        /// The report of the procedure's `metrics`, scored by the `score` function beside
        /// it, with `errors` counted.
        fn report(&self) -> $crate::sim::ProcedureReport {
            let (score, parts) = score(&self.scenario, &self.metrics);
            $crate::sim::ProcedureReport::of(
                Self::is_completed(self),
                self.$($errors).+,
                &self.metrics,
                &parts,
                score,
            )
        }
    };
    ($info:expr) => {
        fn info(&self) -> &'static $crate::sim::ProcedureInfo {
            &$info
        }

        fn dt_s(&self) -> f32 {
            self.scenario.dt_s
        }

        fn step(
            &mut self,
            input: &$crate::sim::InputFrame,
            step: u64,
            events: &mut Vec<$crate::sim::SimEvent>,
        ) {
            Self::step(self, input, step, events);
        }

        fn snapshot(&mut self, step: u64) -> $crate::sim::Snapshot {
            Self::snapshot(self, step)
        }
    };
}

/// The `plan` function of a procedure's scenario module (`INFO.plan`): what a run of
/// scenario text needs before it is built, its step, snapshot rate and model size (the
/// scenario's method `$nodes`). `scenario_tables!` writes it.
#[macro_export]
macro_rules! scenario_plan {
    ($nodes:ident) => {
        /// What a run of scenario text needs before it is built: its step, snapshot rate
        /// and model size (`INFO.plan`).
        pub fn plan(
            file: &str,
            text: &str,
        ) -> Result<$crate::sim::Plan, $crate::scenario::InputError> {
            let s = Scenario::parse(file, text)?;
            Ok($crate::sim::Plan {
                dt_s: s.dt_s,
                publish_hz: s.publish_hz,
                nodes: s.$nodes(),
            })
        }
    };
}

/// A score out of 100: each `(points, share)` pair's points times its share (0-1), summed
/// in order, less `penalty` points, clamped to 0-100.
pub fn weighted_score(weighted: &[(f32, f32)], penalty: f32) -> f32 {
    let total = weighted
        .iter()
        .fold(0.0, |sum, (points, share)| sum + points * share);
    (total - penalty).clamp(0.0, 100.0)
}

/// The share of a checklist of `steps` done when `done` are, 0-1.
pub fn completion_share(done: usize, steps: usize) -> f32 {
    done.min(steps) as f32 / steps.max(1) as f32
}

/// An expert's `target_s` over the completion time, at most 1; zero until completed.
pub fn time_efficiency(target_s: f64, completion_s: Option<f64>) -> f32 {
    completion_s.map_or(0.0, |t| (target_s / t.max(1e-9)).min(1.0) as f32)
}

/// The score of a checklist procedure, out of 100: 60 x the share of its checklist done +
/// 20 x its time efficiency + 20 x a quality of its own (its share, 0-1), less its penalty
/// points. Reports show it as an object of `completion`, `efficiency`, the quality by its
/// name, and `penalty`.
#[derive(Debug, Clone, PartialEq)]
pub struct ChecklistScore {
    /// Fraction of the checklist done.
    pub completion: f32,
    /// Target time / completion time, at most 1; zero until completed.
    pub efficiency: f32,
    /// The procedure's own quality: its name in reports, and its share, 0-1.
    pub quality: (&'static str, f32),
    /// Points taken off (for errors, alarms, punctures).
    pub penalty: f32,
}

impl ChecklistScore {
    /// Points for the checklist done, for the speed and for the procedure's own quality.
    pub const POINTS: [f32; 3] = [60.0, 20.0, 20.0];

    /// The parts of a score: `done` of the checklist `steps` done, an expert's time over the
    /// time taken (`(target_s, completion_s)`, see [`time_efficiency`]), the procedure's
    /// `quality` (its name and share) and `penalty` points.
    pub fn new(
        done: &[String],
        steps: &[TaskStep],
        (target_s, completion_s): (f64, Option<f64>),
        quality: (&'static str, f32),
        penalty: f32,
    ) -> Self {
        Self {
            completion: completion_share(done.len(), steps.len()),
            efficiency: time_efficiency(target_s, completion_s),
            quality,
            penalty,
        }
    }

    /// The score these parts make (see [`weighted_score`]), with the parts.
    pub fn scored(self) -> (f32, Self) {
        let [completion, efficiency, quality] = Self::POINTS;
        let weighted = [
            (completion, self.completion),
            (efficiency, self.efficiency),
            (quality, self.quality.1),
        ];
        (weighted_score(&weighted, self.penalty), self)
    }
}

impl serde::Serialize for ChecklistScore {
    /// An object of `completion`, `efficiency`, the quality by its name, and `penalty`.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(4))?;
        map.serialize_entry("completion", &self.completion)?;
        map.serialize_entry("efficiency", &self.efficiency)?;
        map.serialize_entry(self.quality.0, &self.quality.1)?;
        map.serialize_entry("penalty", &self.penalty)?;
        map.end()
    }
}

impl ModelReport {
    /// A model's report by its `name`, its `kind`, its `vertices` and its `constraints`: no
    /// triangles, no mass-spring particulars (the `with_` methods add them).
    pub fn new(name: &str, kind: &str, vertices: usize, constraints: usize) -> Self {
        Self {
            name: name.to_string(),
            kind: kind.to_string(),
            vertices,
            triangles: 0,
            constraints,
            mass_spring: MassSpring::default(),
            gpu: None,
        }
    }

    /// The same, stepped on the GPU `adapter` names (none: on the CPU).
    pub fn on_gpu(self, adapter: Option<String>) -> Self {
        Self {
            gpu: adapter,
            ..self
        }
    }

    /// The same, with `triangles` triangles.
    pub fn with_triangles(self, triangles: usize) -> Self {
        Self { triangles, ..self }
    }

    /// The same, with `nodes` mass points (and whatever else its mass-spring part says).
    pub fn with_nodes(self, nodes: usize) -> Self {
        let mass_spring = MassSpring {
            nodes: Some(nodes),
            ..self.mass_spring
        };
        Self {
            mass_spring,
            ..self
        }
    }

    /// The same as a mass-spring model: its vertices the mass points, its constraints the
    /// springs, stepped by `integrator`.
    pub fn with_springs(self, integrator: &'static str) -> Self {
        let mass_spring = MassSpring {
            nodes: Some(self.vertices),
            springs: Some(self.constraints),
            integrator: Some(integrator),
            ..self.mass_spring
        };
        Self {
            mass_spring,
            ..self
        }
    }
}

impl ToolInfo {
    /// The left hand's instrument: its `name`, its `kind` and its full-scale force, newtons.
    pub const fn left(name: &'static str, kind: ToolKind, full_scale_n: f32) -> Self {
        Self {
            hand: Hand::Left,
            name,
            kind,
            full_scale_n,
        }
    }

    /// The right hand's instrument: its `name`, its `kind` and its full-scale force, newtons.
    pub const fn right(name: &'static str, kind: ToolKind, full_scale_n: f32) -> Self {
        Self {
            hand: Hand::Right,
            name,
            kind,
            full_scale_n,
        }
    }
}
