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
pub(crate) mod membrane_cases;
pub(crate) mod particle_cases;
mod skeleton_cases;
mod softbody_cases;
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

/// A registered case: its identity, its tolerance, and the function that measures it.
pub struct Case {
    pub model: &'static str,
    pub case: &'static str,
    pub description: &'static str,
    pub unit: &'static str,
    /// Relative tolerance; each case says in its description or source why this much.
    pub tolerance: f64,
    pub run: fn() -> Measured,
}

/// What a case's run produces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// The independent reference value.
    pub reference: f64,
    /// The simulator's value.
    pub measured: f64,
    /// Simulated time stepped, s (0 for a static case).
    pub simulated_s: f64,
    /// Smallest magnitude the error is taken relative to, so that a reference of zero still
    /// gives a relative error; 0 where the reference is far from zero.
    pub floor: f64,
}

impl Measured {
    /// A static case (no simulated time) with a reference far from zero.
    pub fn at_rest(reference: f64, measured: f64) -> Measured {
        Measured {
            reference,
            measured,
            simulated_s: 0.0,
            floor: 0.0,
        }
    }

    /// A case that could not be set up (say, a mesh that failed to build): its measured value
    /// is NaN, so it fails rather than passing silently.
    pub fn not_run(reference: f64) -> Measured {
        Measured::at_rest(reference, f64::NAN)
    }
}

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

/// Every registered case, in a fixed order (model by model). Each of these passes when the
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
    all.extend(bem_cases::cases());
    all.extend(skeleton_cases::cases());
    all
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

/// Runs every registered case (not the known failures), in order.
pub fn run_all() -> Vec<CaseResult> {
    run(&cases())
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

    #[test]
    fn every_registered_case_passes() {
        let results = run_all();
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
        for r in run_all() {
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
        let results = run_all();
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
        for case in &all {
            let m = (case.run)();
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
    fn known_failures_really_fail() {
        // If one of these starts passing, the model changed: move it into `cases`.
        for r in run(&known_failures()) {
            assert!(r.measured.is_finite(), "{}: {}", r.case, r.measured);
            assert!(!r.passed, "{} now passes: register it", r.case);
        }
    }
}
