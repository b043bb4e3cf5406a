//! Verification cases: every model's reference values as data.
//!
//! Researchers judge a simulator by a table of reference cases: for each, a reference value
//! worked out independently of the simulator (analytic, hand-computed, or a conservation law),
//! the value the simulator produced, their relative error, the tolerance the case is held to,
//! and how fast the case ran. [`run_all`] produces that table as data (serialisable for
//! `--json`), [`table`] as aligned text.
//!
//! Each model keeps its cases in its own file; a new model adds a file and one line to
//! [`cases`]. A case that shows the model disagreeing with physics is not bent to pass: it
//! goes into [`known_failures`], which [`run_all`] leaves out, with its real error.

use std::time::Instant;

mod bem_cases;
mod collision_cases;
mod cosserat_cases;
mod forces_cases;
pub mod hertz_cases;
mod membrane_cases;
pub mod particle_cases;
mod particle_solver_cases;
mod skeleton_cases;
pub mod softbody_cases;
pub mod softbody_contact_cases;
mod xpbd_cases;

/// One case's outcome: a row of the verification table.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CaseResult {
    /// The model the case exercises: "simplex soft body", "xpbd", "forces", "ray-mesh",
    /// "cosserat rod", "mass-spring membrane", "generalized cylinder", "rectum scene".
    pub model: &'static str,
    /// Short id, unique over all cases.
    pub case: &'static str,
    /// What is compared with what, and the source of the reference (eq N / analytic).
    pub description: &'static str,
    /// Unit of `reference` and `measured` ("N", "m", "rad", "" for ratios).
    pub unit: &'static str,
    pub reference: f64,
    pub measured: f64,
    /// |measured - reference| / max(|reference|, floor); the floor is the case's own, for
    /// references at or near zero.
    pub rel_error: f64,
    /// Largest relative error the case accepts.
    pub tolerance: f64,
    /// `rel_error` is finite and within `tolerance`.
    pub passed: bool,
    /// Simulated time the case stepped, s (0 for a static case).
    pub simulated_s: f64,
    /// Wall-clock time the case took, s.
    pub wall_s: f64,
    /// Simulated seconds per wall second; None for a static case.
    pub sim_s_per_wall_s: Option<f64>,
}

pub use crate::sim::{Case, Measured};

/// Relative error of `measured` against `reference`, taken relative to at least `floor`.
/// NaN when either value is not finite or both the reference and the floor are zero.
pub fn relative_error(reference: f64, measured: f64, floor: f64) -> f64 {
    let scale = reference.abs().max(floor);
    if !(reference.is_finite() && measured.is_finite()) || scale <= 0.0 {
        return f64::NAN;
    }
    (measured - reference).abs() / scale
}

/// The pass rule of every case: a finite relative error within the tolerance.
pub fn passes(rel_error: f64, tolerance: f64) -> bool {
    rel_error.is_finite() && rel_error <= tolerance
}

impl CaseResult {
    /// Judges a measurement against its case: the one place pass or fail is decided.
    pub fn judge(case: &Case, m: Measured, wall_s: f64) -> CaseResult {
        let rel_error = relative_error(m.reference, m.measured, m.floor);
        let stepped = m.simulated_s > 0.0 && wall_s > 0.0;
        CaseResult {
            model: case.model,
            case: case.case,
            description: case.description,
            unit: case.unit,
            reference: m.reference,
            measured: m.measured,
            rel_error,
            tolerance: case.tolerance,
            passed: passes(rel_error, case.tolerance),
            simulated_s: m.simulated_s,
            wall_s,
            sim_s_per_wall_s: stepped.then(|| m.simulated_s / wall_s),
        }
    }
}

/// Every model's case, in a fixed order (model by model). Each of these passes when the
/// models follow their own equations; a new model adds one line here.
pub fn cases() -> Vec<Case> {
    let mut all = Vec::new();
    all.extend(forces_cases::cases());
    all.extend(softbody_cases::cases());
    all.extend(softbody_contact_cases::cases());
    all.extend(hertz_cases::cases());
    all.extend(xpbd_cases::cases());
    all.extend(collision_cases::cases());
    all.extend(cosserat_cases::cases());
    all.extend(membrane_cases::cases());
    all.extend(particle_cases::cases());
    all.extend(particle_solver_cases::cases());
    all.extend(bem_cases::cases());
    all.extend(skeleton_cases::cases());
    all
}

/// The cases of the models' GPU compute path (`vesalius verify --compute gpu`): the same
/// references as their CPU cases, stepped by the GPU kernels.
pub fn gpu_cases() -> Vec<Case> {
    let mut all = membrane_cases::gpu_cases();
    all.extend(particle_cases::gpu_cases());
    all.extend(particle_solver_cases::gpu_cases());
    all
}

/// The GPU path's cases of the models, then each procedure's of `catalog` (`vesalius verify
/// --compute gpu`'s table).
pub fn gpu_cases_in(catalog: &crate::sim::Catalog) -> Vec<Case> {
    with_procedures(gpu_cases(), catalog, |o| o.gpu_cases)
}

/// The cases at the sizes of the procedures' CPU presets (`vesalius verify --preset cpu`):
/// each procedure's own, where it has a preset.
pub fn preset_cases_in(catalog: &crate::sim::Catalog) -> Vec<Case> {
    with_procedures(Vec::new(), catalog, |o| o.preset_cases)
}

/// `models`' cases, then those that `of` picks from each procedure of `catalog`, in the
/// catalog's order.
fn with_procedures(
    mut models: Vec<Case>,
    catalog: &crate::sim::Catalog,
    of: impl Fn(&crate::sim::Options) -> fn() -> Vec<Case>,
) -> Vec<Case> {
    for p in catalog.iter() {
        models.extend(of(&p.options)());
    }
    models
}

/// Cases where the model, while following its paper, disagrees with physics. Kept apart
/// from [`cases`] so that the registered table stays green; run them with [`run`] to see
/// by how much.
pub fn known_failures() -> Vec<Case> {
    let mut all = Vec::new();
    all.extend(softbody_cases::known_failures());
    all.extend(softbody_contact_cases::known_failures());
    all
}

/// Runs one case, timing it.
pub fn run_case(case: &Case) -> CaseResult {
    let start = Instant::now();
    let m = (case.run)();
    let wall_s = start.elapsed().as_secs_f64();
    CaseResult::judge(case, m, wall_s)
}

/// Runs the given cases in order.
pub fn run(cases: &[Case]) -> Vec<CaseResult> {
    cases.iter().map(run_case).collect()
}

/// The models' cases, then each procedure's of `catalog` that needs its whole scene, in
/// the catalog's order: `vesalius verify`'s table.
pub fn cases_in(catalog: &crate::sim::Catalog) -> Vec<Case> {
    with_procedures(cases(), catalog, |o| o.cases)
}

/// Runs every case of [`cases_in`] (not the known failures), in order.
pub fn run_all(catalog: &crate::sim::Catalog) -> Vec<CaseResult> {
    run(&cases_in(catalog))
}

/// An aligned text table: a header, one row per result, and a last line
/// "N passed, M failed".
pub fn table(results: &[CaseResult]) -> String {
    const HEADER: [&str; 10] = [
        "model",
        "case",
        "unit",
        "reference",
        "measured",
        "rel_error",
        "tolerance",
        "result",
        "sim_s/wall_s",
        "description",
    ];
    let rows: Vec<[String; 10]> = results
        .iter()
        .map(|r| {
            [
                r.model.to_string(),
                r.case.to_string(),
                if r.unit.is_empty() { "-" } else { r.unit }.to_string(),
                format!("{:.6e}", r.reference),
                format!("{:.6e}", r.measured),
                format!("{:.2e}", r.rel_error),
                format!("{:.1e}", r.tolerance),
                if r.passed { "pass" } else { "FAIL" }.to_string(),
                r.sim_s_per_wall_s
                    .map_or_else(|| "static".to_string(), |s| format!("{s:.1}")),
                r.description.to_string(),
            ]
        })
        .collect();
    let mut width = HEADER.map(str::len);
    for row in &rows {
        for (w, cell) in width.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: &[String]| -> String {
        let mut s = String::new();
        for (k, cell) in cells.iter().enumerate() {
            if k + 1 == cells.len() {
                // The description runs on; padding it would only add trailing blanks.
                s.push_str(cell);
            } else {
                // Numbers right-aligned so their exponents line up, words left-aligned.
                let numeric = (3..=6).contains(&k) || k == 8;
                if numeric {
                    s.push_str(&format!("{cell:>w$}  ", w = width[k]));
                } else {
                    s.push_str(&format!("{cell:<w$}  ", w = width[k]));
                }
            }
        }
        s.trim_end().to_string()
    };
    let mut out = line(&HEADER.map(String::from));
    out.push('\n');
    for row in &rows {
        out.push_str(&line(row));
        out.push('\n');
    }
    let passed = results.iter().filter(|r| r.passed).count();
    out.push_str(&format!(
        "{passed} passed, {} failed\n",
        results.len() - passed
    ));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;
    use std::sync::OnceLock;

    /// Every model case measured once, with its wall time: the tests that judge, tabulate
    /// or perturb the measurements share the one run.
    fn measured() -> &'static [(Measured, f64)] {
        static RUN: OnceLock<Vec<(Measured, f64)>> = OnceLock::new();
        RUN.get_or_init(|| {
            cases()
                .iter()
                .map(|c| {
                    let start = Instant::now();
                    let m = (c.run)();
                    (m, start.elapsed().as_secs_f64())
                })
                .collect()
        })
    }

    /// The shared run's results, judged as [`run`] judges them.
    fn results() -> Vec<CaseResult> {
        cases()
            .iter()
            .zip(measured())
            .map(|(c, &(m, wall_s))| CaseResult::judge(c, m, wall_s))
            .collect()
    }

    #[test]
    fn every_models_case_passes() {
        let results = results();
        let failed: Vec<String> = results
            .iter()
            .filter(|r| !r.passed)
            .map(|r| {
                format!(
                    "{}/{}: reference {} measured {} error {} tolerance {}",
                    r.model, r.case, r.reference, r.measured, r.rel_error, r.tolerance
                )
            })
            .collect();
        assert!(failed.is_empty(), "{failed:#?}\n{}", table(&results));
        assert!(results.len() >= 10, "{} cases", results.len());
    }

    #[test]
    fn every_result_field_is_finite() {
        for r in results() {
            for (name, v) in [
                ("reference", r.reference),
                ("measured", r.measured),
                ("rel_error", r.rel_error),
                ("tolerance", r.tolerance),
                ("simulated_s", r.simulated_s),
                ("wall_s", r.wall_s),
            ] {
                assert!(v.is_finite(), "{}: {name} = {v}", r.case);
            }
            assert!(r.tolerance > 0.0 && r.tolerance < 1.0, "{}", r.case);
            match r.sim_s_per_wall_s {
                Some(s) => assert!(s.is_finite() && s > 0.0 && r.simulated_s > 0.0),
                None => assert_eq!(r.simulated_s, 0.0, "{}", r.case),
            }
            assert!(!r.description.is_empty(), "{}", r.case);
        }
    }

    #[test]
    fn case_ids_are_unique_across_registered_and_known_failures() {
        let mut seen = HashSet::new();
        for c in cases().iter().chain(known_failures().iter()) {
            assert!(seen.insert(c.case), "duplicate case id {}", c.case);
        }
    }

    #[test]
    fn the_table_has_a_header_one_row_per_case_and_a_summary() {
        let results = results();
        let text = table(&results);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), results.len() + 2, "{text}");
        assert!(lines[0].starts_with("model"));
        for (line, r) in lines[1..].iter().zip(&results) {
            assert!(line.starts_with(r.model), "{line}");
            assert!(line.contains(r.case), "{line}");
            assert!(line.contains("pass"), "{line}");
        }
        assert_eq!(
            lines.last().copied(),
            Some(format!("{} passed, 0 failed", results.len()).as_str())
        );
        // Columns line up: every row's case id starts where the header's does.
        let at = lines[0].find("case").unwrap_or(0);
        for (line, r) in lines[1..].iter().zip(&results) {
            assert_eq!(line.find(r.case), Some(at), "{line}");
        }
    }

    #[test]
    fn a_perturbed_measurement_fails_through_the_same_judge() {
        let all = cases();
        for (case, &(m, _)) in all.iter().zip(measured()) {
            let good = CaseResult::judge(case, m, 1.0);
            assert!(good.passed, "{}", case.case);
            // Off by three tolerances (relative to the same scale the case uses).
            let scale = m.reference.abs().max(m.floor);
            let off = Measured {
                measured: m.reference + 3.0 * case.tolerance * scale,
                ..m
            };
            let bad = CaseResult::judge(case, off, 1.0);
            assert!(!bad.passed, "{} passed off by 3 tolerances", case.case);
            let nan = CaseResult::judge(case, Measured::not_run(m.reference), 1.0);
            assert!(!nan.passed && nan.sim_s_per_wall_s.is_none());
        }
        let t = table(&[CaseResult::judge(&all[0], Measured::not_run(1.0), 0.0)]);
        assert!(
            t.contains("FAIL") && t.ends_with("0 passed, 1 failed\n"),
            "{t}"
        );
    }

    #[test]
    fn relative_error_uses_the_floor_only_near_zero() {
        assert!((relative_error(2.0, 2.2, 0.5) - 0.1).abs() < 1e-15);
        assert!((relative_error(0.0, 1e-3, 0.1) - 1e-2).abs() < 1e-15);
        assert!(relative_error(0.0, 1e-3, 0.0).is_nan());
        assert!(relative_error(1.0, f64::INFINITY, 0.0).is_nan());
        assert!(!passes(f64::NAN, 1.0));
        assert!(passes(0.01, 0.01));
    }

    #[test]
    fn the_gpu_cases_pass_on_the_adapter_there_is() {
        // CI: lavapipe. The same references and tolerances as the CPU's cases.
        let results = run(&gpu_cases());
        assert!(!results.is_empty());
        for r in results {
            assert!(r.passed, "{}: {} vs {}", r.case, r.measured, r.reference);
        }
    }

    #[test]
    fn known_failures_really_fail() {
        // If one of these starts passing, the model changed: move it into `cases`.
        for r in run(&known_failures()) {
            assert!(r.measured.is_finite(), "{}: {}", r.case, r.measured);
            assert!(!r.passed, "{} now passes: register it", r.case);
        }
    }

    /// The shape-matching column of the verify case sags as the continuum does at the
    /// liver's and gallbladder's sizes (20 and 30 lattice steps), within 10 %.
    #[test]
    fn a_hanging_column_sags_as_the_continuum_does() {
        // A bar of height H hanging from its top under its own weight stretches by
        // rho g H^2 / (2 E).
        for ny in [20usize, 30] {
            let (sag, continuum) =
                particle_cases::column_sag_of(0.0035, 1060.0, 5000.0, ny, 2, false)
                    .expect("clusters");
            assert!(
                (sag / continuum - 1.0).abs() < 0.1,
                "{ny} steps: {sag} m vs {continuum} m"
            );
        }
    }

    #[test]
    fn a_free_sheet_under_residual_strain_shrinks_by_it() {
        // Overdamped: the sheet draws in without overshooting. (Structural springs alone
        // resist neither shear nor bending: a row that overshot would stay folded at zero
        // energy.) The same sheet is the membrane's residual-shrink case.
        let (rows, cols, spacing) = membrane_cases::FREED;
        let (m, _) = membrane_cases::freed_sheet().expect("a sheet");
        let span = |l: usize| {
            let (a, b) = (m.node(l, 0, cols / 2), m.node(l, rows - 1, cols / 2));
            m.position(b).distance(m.position(a))
        };
        let rest = (rows - 1) as f32 * spacing;
        let across = m
            .position(m.node(1, 10, cols - 1))
            .distance(m.position(m.node(1, 10, 0)));
        let across = 1.0 - across / ((cols - 1) as f32 * spacing);
        assert!((across - 0.1).abs() < 0.015, "shrank across by {across}");
        let shrink = 1.0 - span(1) / rest;
        assert!((shrink - 0.1).abs() < 0.015, "shrank by {shrink}");
        // The layers without residual strain keep their size.
        assert!((span(2) / rest - 1.0).abs() < 1e-4, "{}", span(2));
    }
}
