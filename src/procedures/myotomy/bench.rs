//! The myotomy's own lines of `vesalius bench`: the boundary-element precomputation built
//! afresh at the scenario's size (never read from the cache: `bem_assembly`, `bem_factor`
//! with the factorisation's GFLOP/s beside the machine's peak, `bem_responses`), and the
//! haptic-rate contact update with the most contacts it takes (64): `contact_update` with a
//! set that stays, `contact_update_changing` with one whose capacitance matrix is factorised
//! again every update.

use super::anatomy::Esophagus;
use super::plugin::INFO;
use super::scenario::Scenario;
use crate::models::bem::contact::{Contacts, MOST_CONTACTS};
use crate::models::bem::system::lu_flops;
use crate::procedures::BuildError;
use crate::sim::bench::{BenchError, BenchLine, Once, peak_gflops};
use glam::DVec3;
use std::time::Instant;

/// Updates timed with a steady set, and with a changing one.
const STEADY_UPDATES: u64 = 20_000;
const CHANGING_UPDATES: u64 = 400;

/// The extra lines (about half a minute at the paper's size, most of it the factorisation).
pub fn extra() -> Result<Vec<BenchLine>, BenchError> {
    let s = Scenario::parse("builtin myotomy scenario", INFO.scenario)?;
    let e = Esophagus::new(&s.esophagus_params());
    let par = faer::Par::rayon(rayon::current_num_threads());
    let pre = e
        .problem
        .precompute(&e.field, par, &|_, _| {})
        .map_err(|x| BuildError::from(crate::models::bem::PrecomputeError::from(x)))?;
    let n = pre.n;
    let t = pre.timings;
    let peak = peak_gflops();
    let stage = |name: &str, seconds: f64, gflops: Option<f64>| BenchLine {
        vertices: e.surface.vertices.len(),
        triangles: e.surface.triangles.len(),
        constraints: n,
        once: Once {
            seconds: Some(seconds),
            n: Some(n),
            gflops,
            peak_gflops: gflops.and(peak),
        },
        ..BenchLine::repeated(name, 1, seconds)
    };
    let mut out = vec![
        stage("bem_assembly", t.assembly_s, None),
        stage(
            "bem_factor",
            t.factor_s,
            Some(lu_flops(n) / t.factor_s.max(1e-12) / 1e9),
        ),
        stage("bem_responses", t.solve_s, None),
    ];
    // The 64 field elements nearest the field's middle, pushed 1 mm in along their normals.
    let field = pre.field.clone();
    let els = &e.problem.elements;
    let middle = field.iter().map(|&i| els[i].centroid).sum::<DVec3>() / field.len() as f64;
    let mut near: Vec<usize> = field.clone();
    near.sort_by(|&a, &b| {
        (els[a].centroid - middle)
            .length_squared()
            .total_cmp(&(els[b].centroid - middle).length_squared())
            .then(a.cmp(&b))
    });
    let spare = near.get(MOST_CONTACTS).copied();
    near.truncate(MOST_CONTACTS);
    near.sort_unstable();
    let targets = |set: &[usize], y0: &[f64]| -> Vec<DVec3> {
        set.iter()
            .map(|&i| DVec3::new(y0[3 * i], y0[3 * i + 1], y0[3 * i + 2]) - els[i].normal * 1e-3)
            .collect()
    };
    let mut contacts = Contacts::new(pre, els, s.prony());
    contacts.set_contacts(&near)?;
    let steady = targets(&near, &contacts.precomputed().y0);
    let t0 = Instant::now();
    for _ in 0..STEADY_UPDATES {
        contacts.update(&steady, 0.001)?;
    }
    let line = |name: &str, count: u64, secs: f64| BenchLine {
        constraints: near.len(),
        ..BenchLine::repeated(name, count, secs)
    };
    out.push(line(
        "contact_update",
        STEADY_UPDATES,
        t0.elapsed().as_secs_f64(),
    ));
    // The same set with its last element swapped in and out: a new factorisation each time.
    if let Some(spare) = spare {
        let mut other = near.clone();
        other.pop();
        other.push(spare);
        other.sort_unstable();
        let other_targets = targets(&other, &contacts.precomputed().y0);
        let t0 = Instant::now();
        for k in 0..CHANGING_UPDATES {
            let (set, tg) = if k % 2 == 0 {
                (&other, &other_targets)
            } else {
                (&near, &steady)
            };
            contacts.set_contacts(set)?;
            contacts.update(tg, 0.001)?;
        }
        out.push(line(
            "contact_update_changing",
            CHANGING_UPDATES,
            t0.elapsed().as_secs_f64(),
        ));
    }
    Ok(out)
}
