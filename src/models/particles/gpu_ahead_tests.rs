//! A step's two substeps in one submission split after the first, against a submission a
//! substep: the same bytes, whether the second substep is kept or run again because a
//! search, a weakened or a torn strand fell between the two.

use super::solver::{pulled, solver, stacked, steps, still_on_gpu, strands_scene};
use super::tools::hook;
use super::*;
use crate::models::particles::solver::ParticleSolver;

/// A scene, and what is done with it: a record of each step (whatever the scene tells).
type Scene = fn() -> ParticleSolver;
type Run = dyn Fn(&mut ParticleSolver) -> Vec<Vec<u32>>;

/// What a run left: the particles' bits, each step's record, and the steps whose second
/// substep ran ahead (kept, run again).
struct Ran {
    x: Vec<[u32; 3]>,
    record: Vec<Vec<u32>>,
    ahead: [u64; 2],
}

fn ran(gpu: &Gpu, make: Scene, ahead: bool, run: &Run) -> Ran {
    let mut s = make();
    s.use_gpu(gpu).expect("the device takes the scene");
    s.gpu_step_ahead(ahead);
    let record = run(&mut s);
    still_on_gpu(&mut s);
    let x = s.particles.x.iter().map(|p| p.to_array().map(f32::to_bits));
    Ran {
        x: x.collect(),
        record,
        ahead: s.gpu_ahead_counts(),
    }
}

/// The bits of a step's reactions (both hands) and the particles the hook pushed.
fn reactions(s: &ParticleSolver) -> Vec<u32> {
    let o = s.outcome();
    let mut r: Vec<u32> = o
        .reactions
        .iter()
        .flat_map(|f| f.to_array().map(f32::to_bits))
        .collect();
    r.push(o.pushed[1] as u32);
    r
}

#[test]
fn two_substeps_in_one_submission_give_the_bytes_of_a_submission_each() {
    let gpu = gpu();
    // Strands pulled until all 36 tear (weakening and tearing between substeps), two bodies
    // meeting (searches between substeps), and a hook pressed into a block whose particles
    // are in contacts (each substep's instruments' totals).
    let pull = |s: &mut ParticleSolver| {
        let torn = pulled(s, 0..300);
        assert_eq!(torn.iter().sum::<usize>(), 36);
        torn.into_iter().map(|t| vec![t as u32]).collect()
    };
    let meet = |s: &mut ParticleSolver| {
        steps(s, 120);
        Vec::new()
    };
    let press = |s: &mut ParticleSolver| {
        (0..200)
            .map(|k| {
                s.set_tools(hook(k));
                steps(s, 1);
                reactions(s)
            })
            .collect()
    };
    let hooked = || solver(true);
    let scenes: [(&str, Scene, &Run); 3] = [
        ("strands", strands_scene, &pull),
        ("contacts", stacked, &meet),
        ("hook", hooked, &press),
    ];
    for (name, make, run) in scenes {
        let each = ran(&gpu, make, false, run);
        let split = ran(&gpu, make, true, run);
        assert_eq!(
            each.ahead,
            [0, 0],
            "{name}: a submission a substep ran ahead"
        );
        assert!(
            each.x == split.x,
            "{name}: the particles differ from a submission a substep's"
        );
        assert!(
            each.record == split.record,
            "{name}: the steps' outcomes differ from a submission a substep's"
        );
        // Both ways were taken: second substeps kept, and run again (in the hook's block,
        // after the searches its push set off).
        let [kept, again] = split.ahead;
        assert!(
            kept > 0 && again > 0,
            "{name}: {kept} second substeps kept, {again} run again"
        );
        // The scene moved (a still scene would agree trivially).
        let start = make().particles.x;
        let moved = largest_move(&split.x, &start);
        assert!(moved > 1e-3, "{name}: moved {moved} m");
    }
}
