//! The myotomy as the session, window and headset see every procedure: its registry entry,
//! its build from a scenario (the precomputation read from the cache, or built and cached on
//! the first run), and its score.

use super::anatomy::Esophagus;
use super::field;
use super::procedure::{Metrics, Myotomy, STEPS};
use super::scenario::{self, NAME, Scenario};
use crate::models::bem::cache;
use crate::models::bem::contact::Contacts;
use crate::models::bem::palpation::Palpation;
use crate::procedures::{BuildError, ModelReport, Procedure, ProcedureInfo};
use crate::sim::ChecklistScore;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// The registry's entry.
pub const INFO: ProcedureInfo = crate::procedure_info! {
    stem: "myotomy", paper: "esophageal-myotomy.txt",
    title: "Laparoscopic Heller myotomy (esophagogastric junction)",
    build: |_, s| build_procedure(s, &cache::default_dir())?,
    // Palpating the sphincter takes a few hundred millinewtons at most.
    tools: [("grasper", Grasper, 0.5), ("hook", Hook, 0.5)],
    // The laparoscope above the anterior wall of the abdominal esophagus, looking down at
    // the junction, the diaphragm at the top of the view.
    view: (0.0, 0.075, 0.045) -> (0.0, 0.008, 0.035),
    // Above the field, to either side.
    desk_park: [(-0.03, 0.04, 0.03), (0.03, 0.04, 0.03)],
    bench_extra: Some(super::bench::extra),
    precompute: Some(&super::PRECOMPUTE),
};

/// The cache file in `dir` for this esophagus (named by its key: esophagi of other sizes or
/// tissues keep their own files).
pub fn cache_file(dir: &Path, e: &Esophagus) -> PathBuf {
    dir.join(format!("myotomy-{:016x}.bem", e.problem.key(&e.field)))
}

/// The procedure for a checked scenario, its precomputation read from (or built into) the
/// cache in `cache_dir`. Building shows its progress on standard error.
pub fn build_procedure(s: Scenario, cache_dir: &Path) -> Result<Myotomy, BuildError> {
    let e = Esophagus::new(&s.esophagus_params());
    let path = cache_file(cache_dir, &e);
    let bar = crate::progress::Bar::new();
    let announced = std::sync::Once::new();
    let progress = |stage: &str, f: f64| {
        announced.call_once(|| {
            eprintln!(
                "myotomy: precomputing the esophagus's responses into {} (once per mesh and \
                 tissue; `vesalius precompute myotomy` does it ahead)",
                path.display()
            );
        });
        bar.show(stage, f);
    };
    let par = faer::Par::rayon(rayon::current_num_threads());
    let (pre, _) = e
        .problem
        .precompute_cached(&e.field, &path, par, &progress)?;
    let base = pre.solution(&e.problem);
    let contacts = Contacts::new(pre, &e.problem.elements, s.prony());
    let palpation = Palpation::new(contacts, &e.problem.elements, &base);
    Ok(Myotomy::new(s, e, palpation))
}

impl Procedure for Myotomy {
    crate::procedure_basics!(INFO, report(errors: metrics.errors), models: []);

    fn instrument_tips(&self) -> Option<[Vec3; 2]> {
        Some([self.tool_tip(0), self.tool_tip(1)])
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let r = Myotomy::reactions(self);
        let tips = [self.tool_tip(0), self.tool_tip(1)];
        [0, 1].map(|k| (r[k].length() > 0.0).then(|| (tips[k], r[k].normalize_or(Vec3::Y))))
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        let e = &self.esophagus;
        let pre = self.palpation().contacts.precomputed();
        vec![
            // Its step is the contact update from the precomputed responses; its
            // constraints are the dense system's unknowns.
            ModelReport::new(
                "esophagus",
                "boundary_elements",
                e.surface.vertices.len(),
                pre.n,
            )
            .with_triangles(e.surface.triangles.len()),
            // What the incision added to the surface.
            ModelReport::new(
                "incision",
                "surface_subdivision",
                self.incision.vertices.len() - e.surface.vertices.len(),
                self.incision.cuts().len(),
            )
            .with_triangles(self.incision.triangles.len() - e.surface.triangles.len()),
        ]
    }

    fn model_times(&self) -> Vec<f64> {
        self.times.to_vec()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        let pre = self.palpation().contacts.precomputed();
        let f3 = 3 * pre.field.len();
        vec![
            ("responses", 8 * (pre.response.len() + pre.y0.len())),
            ("capacitance", 8 * f3 * f3),
            (
                "incision",
                24 * self.incision.vertices.len() + 12 * self.incision.triangles.len(),
            ),
        ]
    }
}

/// Points taken off per error (a perforation).
const ERROR_PENALTY: f32 = 20.0;

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x division (the share of the
/// myotomy's span with its muscle divided; all of it where none is required), less 20 per
/// perforation (a flat score until the assessment trees of #12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ChecklistScore) {
    let time = (s.task.target_time_s, m.completion_time_s);
    let penalty = ERROR_PENALTY * m.errors as f32;
    let divided = if m.required_m > 0.0 {
        (m.divided_m / m.required_m).min(1.0) as f32
    } else {
        1.0
    };
    let division = ("division", divided);
    ChecklistScore::new(&m.steps_done, &STEPS, time, division, penalty).scored()
}
