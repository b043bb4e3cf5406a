use super::kelvin::integrate_off;
use super::system::blocks;
use super::*;
use glam::{DMat3, DVec3};
use std::f64::consts::{FRAC_PI_2, TAU};

fn quiet(_: &str, _: f64) {}

fn par() -> Par {
    Par::rayon(rayon::current_num_threads())
}

use super::reference::tube;

const TISSUE: Material = Material {
    young_pa: 5222.0,
    poisson: 0.3,
};

#[test]
fn a_sector_and_a_whole_tube_are_closed_and_enclose_their_volume() {
    for (span, around) in [(FRAC_PI_2, 6), (TAU, 24)] {
        let t = tube(span, around, 2, 3);
        let s = t.surface();
        assert!(s.is_watertight(), "span {span}");
        // The polygon's area is below the circle's by the chords' segments.
        let exact = 0.5 * span * (t.outer_m.powi(2) - t.inner_m.powi(2)) * t.length_m;
        let chord = (span / around as f64).sin() / (span / around as f64);
        let v = s.volume_m3();
        assert!(
            (v / (exact * chord) - 1.0).abs() < 1e-9,
            "span {span}: {v} vs {}",
            exact * chord
        );
        assert!(s.elements().iter().all(|e| e.area_m2 > 0.0));
    }
}

/// Somigliana's identity for a rigid translation: `int_Gamma P dGamma` is `-I` from a point
/// inside the solid and zero from one outside.
#[test]
fn the_traction_kernel_integrates_to_minus_identity_inside_and_zero_outside() {
    let s = tube(TAU, 24, 2, 4).surface();
    let elements = s.elements();
    for (point, expected) in [
        (DVec3::new(0.008, 0.0, 0.004), -1.0),
        (DVec3::new(0.0, 0.0, 0.004), 0.0),
        (DVec3::new(0.0, 0.02, 0.004), 0.0),
    ] {
        let mut sum = DMat3::ZERO;
        for e in &elements {
            sum += integrate_off(&TISSUE, point, e).1;
        }
        let err = sum - DMat3::IDENTITY * expected;
        let worst = err
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst < 0.01, "{point}: {sum:?}");
    }
}

/// The same at the collocation points, where the free term `c = 1/2` and the element's own
/// principal value enter: every row block of `H` sums to zero (a rigid translation makes no
/// traction).
#[test]
fn every_row_of_h_sums_to_zero() {
    let s = tube(TAU, 24, 2, 4).surface();
    let elements = s.elements();
    let mut worst = 0.0f64;
    for i in (0..elements.len()).step_by(7) {
        let mut sum = DMat3::ZERO;
        for j in 0..elements.len() {
            sum += blocks(&TISSUE, &elements, i, j).0;
        }
        worst = sum
            .to_cols_array()
            .iter()
            .fold(worst, |m, v| m.max(v.abs()));
    }
    assert!(worst < 0.02, "largest row sum {worst}");
}

/// Lamé's thick cylinder in plane strain, within 5 % on both walls.
#[test]
fn a_thick_cylinder_under_internal_pressure_expands_as_lame_says() {
    let walls = reference::lame_cylinder(8, 3, 4).expect("solves");
    for (got, want) in walls {
        assert!((got / want - 1.0).abs() < 0.05, "{got} m vs Lame {want} m");
    }
}

/// Both ends moved by the same vector and nothing else pressing: the whole tube moves with
/// them and the ends feel no traction.
#[test]
fn a_rigid_translation_of_the_ends_moves_everything_and_makes_no_traction() {
    let (du, dp) =
        reference::rigid_translation(DVec3::new(0.001, -0.0005, 0.0002)).expect("solves");
    assert!(du < 0.01, "displacement off by {du} of the translation");
    assert!(dp < 0.01, "traction {dp} of E |d| / L");
}

fn small_problem() -> Problem {
    reference::pressurised_tube(0.3).0
}

#[test]
fn one_and_two_threads_precompute_the_same_bytes() {
    let problem = small_problem();
    let field = [0, 5, 40];
    let run = |threads| {
        crate::sim::on_threads(threads, || {
            problem
                .precompute(&field, Par::rayon(threads), &quiet)
                .expect("solves")
        })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.y0, b.y0);
    assert_eq!(a.response, b.response);
}

/// A field element's response column is what a second solve with that traction added gives.
#[test]
fn a_response_column_is_the_solution_with_that_traction_added() {
    let problem = small_problem();
    let field = [30usize];
    let pre = problem.precompute(&field, par(), &quiet).expect("solves");
    let mut pushed = problem.clone();
    let extra = DVec3::new(0.0, 0.0, 150.0);
    pushed.conditions[30].value += extra;
    let again = pushed.precompute(&[], par(), &quiet).expect("solves");
    for row in 0..pre.n {
        let predicted = pre.y0[row] + pre.response[2 * pre.n + row] * extra.z;
        let tol = 1e-9 * (again.y0[row].abs() + 1e-9);
        assert!(
            (predicted - again.y0[row]).abs() <= tol.max(1e-15),
            "row {row}"
        );
    }
}

#[test]
fn the_cache_reads_back_what_was_written_and_rebuilds_a_corrupt_or_stale_file() {
    let dir = crate::testing::Scratch::new("bem", "cache");
    let path = dir.join("small.bem");
    let _ = std::fs::remove_file(&path);
    let problem = small_problem();
    let field = [3usize, 4];
    let (first, why) = problem
        .precompute_cached(&field, &path, par(), &quiet)
        .expect("builds");
    assert!(matches!(why, Some(cache::CacheError::Missing { .. })));
    let (again, why) = problem
        .precompute_cached(&field, &path, par(), &quiet)
        .expect("reads");
    assert!(why.is_none() && again.from_cache);
    assert_eq!(again.y0, first.y0);
    assert_eq!(again.response, first.response);
    // One flipped bit in the middle: the checksum catches it, and the file is rebuilt.
    let mut bytes = std::fs::read(&path).expect("cache");
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(&path, &bytes).expect("write");
    let (rebuilt, why) = problem
        .precompute_cached(&field, &path, par(), &quiet)
        .expect("rebuilds");
    assert!(
        matches!(why, Some(cache::CacheError::Checksum { .. })),
        "{why:?}"
    );
    assert!(!rebuilt.from_cache);
    assert_eq!(rebuilt.y0, first.y0);
    // Cut short: corrupt. Other inputs: stale.
    let bytes = std::fs::read(&path).expect("cache");
    std::fs::write(&path, &bytes[..bytes.len() / 3]).expect("write");
    let (_, why) = problem
        .precompute_cached(&field, &path, par(), &quiet)
        .expect("rebuilds");
    assert!(
        matches!(
            why,
            Some(cache::CacheError::Checksum { .. } | cache::CacheError::Corrupt { .. })
        ),
        "{why:?}"
    );
    let mut stiffer = problem.clone();
    stiffer.material.young_pa *= 2.0;
    let (_, why) = stiffer
        .precompute_cached(&field, &path, par(), &quiet)
        .expect("rebuilds");
    assert!(
        matches!(why, Some(cache::CacheError::Stale { .. })),
        "{why:?}"
    );
}

/// Threads writing one cache at once each go through a temporary file of their own: every
/// write succeeds, and the file left reads back whole (one of theirs).
#[test]
fn threads_writing_one_cache_at_once_leave_a_whole_file() {
    let dir = crate::testing::Scratch::new("bem", "racing");
    let path = dir.join("shared.bem");
    let arrays = |k: usize| -> cache::Arrays { vec![("y0".into(), vec![k as f64; 50_000])] };
    let written: Vec<bool> = std::thread::scope(|s| {
        let writers: Vec<_> = (0..4)
            .map(|k| {
                let path = &path;
                s.spawn(move || (0..5).all(|_| cache::write(path, 7, &arrays(k)).is_ok()))
            })
            .collect();
        writers
            .into_iter()
            .map(|w| w.join().unwrap_or(false))
            .collect()
    });
    assert_eq!(written, vec![true; 4]);
    let back = cache::read(&path, 7).expect("a whole file");
    assert!((0..4).any(|k| back == arrays(k)), "{:?}", &back[0].1[..2]);
    let left: Vec<_> = std::fs::read_dir(&*dir).expect("dir").flatten().collect();
    assert_eq!(left.len(), 1, "no temporary file is left");
}

#[test]
fn bad_inputs_are_refused_with_what_is_wrong() {
    let mut p = small_problem();
    p.conditions.pop();
    assert!(matches!(
        p.solve(par(), &quiet),
        Err(BemError::Lengths { .. })
    ));
    let p = small_problem();
    let n = p.elements.len();
    for field in [vec![n], vec![2, 2]] {
        assert!(matches!(
            p.precompute(&field, par(), &quiet),
            Err(BemError::Field { .. })
        ));
    }
    let mut p = small_problem();
    p.material.poisson = 0.5;
    assert!(matches!(
        p.solve(par(), &quiet),
        Err(BemError::Material { .. })
    ));
}

/// Far from an element its integral is the kernels at its centroid times its area (the
/// one-point rule), so the written-out arithmetic of the integration matches `kernels`.
#[test]
fn far_integrals_are_the_kernels_at_the_centroid_times_the_area() {
    let s = tube(TAU, 12, 1, 3).surface();
    let e = &s.elements()[5];
    let xi = e.centroid + DVec3::new(0.3, -0.2, 0.1);
    let (u, p) = integrate_off(&TISSUE, xi, e);
    let (ku, kp) = kelvin::kernels(&TISSUE, xi, e.centroid, e.normal);
    for (a, b) in [(u, ku * e.area_m2), (p, kp * e.area_m2)] {
        let scale = b.to_cols_array().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let err = (a - b)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(err <= 1e-12 * scale, "{a:?} vs {b:?}");
    }
}
