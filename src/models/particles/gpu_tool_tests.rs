//! The instruments on the GPU against the CPU: an L-hook pressed into the pinned block from
//! below (two cylinders, a tapered profile), and a grasp pulling the block's lower corner
//! down; the reactions, the particles and the counts as the CPU makes them.

use super::solver::{solver, steps, still_on_gpu};
use super::*;
use crate::collision::Instrument;
use crate::models::particles::solver::{HandTool, ParticleSolver};

/// What a run gave: the reactions summed over its steps (an impulse over 1 ms, N), the most
/// particles pushed and held at once, and the particles at its end.
struct Run {
    impulse: [Vec3; 2],
    pushed: [usize; 2],
    held: [usize; 2],
    x: Vec<Vec3>,
}

/// `n` steps of the pinned block (2 sweeps, 2 substeps, its particles' radius 1 mm) with the
/// tools `at(step)` gives, on the GPU where asked.
fn run(on_gpu: bool, n: usize, at: impl Fn(usize) -> [Option<HandTool>; 2]) -> Run {
    let mut s: ParticleSolver = solver(false);
    if on_gpu {
        s.use_gpu(&gpu()).expect("the device takes the block");
    }
    let mut r = Run {
        impulse: [Vec3::ZERO; 2],
        pushed: [0; 2],
        held: [0; 2],
        x: Vec::new(),
    };
    for k in 0..n {
        s.set_tools(at(k));
        steps(&mut s, 1);
        let o = s.outcome();
        for h in 0..2 {
            r.impulse[h] += o.reactions[h];
            r.pushed[h] = r.pushed[h].max(o.pushed[h]);
            r.held[h] = r.held[h].max(o.held[h]);
        }
    }
    if on_gpu {
        still_on_gpu(&mut s);
    }
    r.x = s.particles.x.clone();
    r
}

/// An L-hook pointing up (+Y) under a column of particles, its hook along +Z under the next,
/// its tip rising from 3.5 mm below the block (the bottom layer at y = -24.5 mm) to 4 mm into
/// it over 150 steps, then held.
pub(super) fn hook(k: usize) -> [Option<HandTool>; 2] {
    let rise = (k.min(150) as f32 / 150.0) * 0.0075;
    let tip = Vec3::new(0.007, -0.028 + rise, 0.007);
    let q = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let instrument = Instrument::l_hook(tip, q).expect("a hook");
    [
        None,
        Some(HandTool {
            instrument,
            jaw: tip,
            closed: false,
        }),
    ]
}

#[test]
fn a_hook_pressed_into_the_block_pushes_alike_on_both_paths() {
    let (cpu, dev) = (run(false, 200, hook), run(true, 200, hook));
    let start = solver(false).particles.x;
    let moved = largest_gap(&cpu.x, &start);
    let apart = largest_gap(&cpu.x, &dev.x);
    assert!(
        moved > 1e-3 && apart < 0.02 * moved,
        "the hook moved the block {moved} m; GPU vs CPU {apart} m"
    );
    // The tissue pushes the hook down (-y): the same impulse on both paths.
    let (c, d) = (cpu.impulse[1], dev.impulse[1]);
    assert!(c.y < -0.01, "the CPU's reaction {c} N ms");
    assert!(
        c.distance(d) < 0.02 * c.length(),
        "reactions over the run: CPU {c}, GPU {d} (N ms)"
    );
    assert!(cpu.pushed[1] > 0 && cpu.impulse[0] == Vec3::ZERO);
    let (pc, pd) = (cpu.pushed[1] as f32, dev.pushed[1] as f32);
    assert!((pc - pd).abs() <= 0.1 * pc, "pushed {pc} vs {pd}");
    assert_eq!(dev.impulse[0], Vec3::ZERO, "the idle hand feels nothing");
}

/// A grasper's jaw closing at the block's lower front corner and pulling it 3 mm down over 100
/// steps, then holding.
fn pull(k: usize) -> [Option<HandTool>; 2] {
    let corner = Vec3::new(0.0, -0.0245, 0.0);
    let jaw = corner - Vec3::Y * (k.min(100) as f32 / 100.0 * 0.003);
    let hinge = jaw + Vec3::Y * 0.01;
    let q = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    let instrument = Instrument::grasper(hinge, q, 0.0).expect("a grasper");
    [
        Some(HandTool {
            instrument,
            jaw,
            closed: true,
        }),
        None,
    ]
}

#[test]
fn a_grasp_pulls_alike_on_both_paths() {
    let (cpu, dev) = (run(false, 160, pull), run(true, 160, pull));
    let start = solver(false).particles.x;
    let moved = largest_gap(&cpu.x, &start);
    let apart = largest_gap(&cpu.x, &dev.x);
    assert!(
        moved > 1e-3 && apart < 0.02 * moved,
        "the grasp moved the block {moved} m; GPU vs CPU {apart} m"
    );
    assert!(
        cpu.held[0] > 0 && cpu.held[0] == dev.held[0],
        "held {} vs {}",
        cpu.held[0],
        dev.held[0]
    );
    // The block holds the jaw up (+y).
    let (c, d) = (cpu.impulse[0], dev.impulse[0]);
    assert!(c.y > 0.01, "the CPU's reaction {c} N ms");
    assert!(
        c.distance(d) < 0.02 * c.length(),
        "reactions over the run: CPU {c}, GPU {d} (N ms)"
    );
}

#[test]
fn instruments_on_one_adapter_give_the_same_bytes() {
    let both = |k: usize| {
        let [a, _] = pull(k);
        let [_, b] = hook(k);
        [a, b]
    };
    let (one, two) = (run(true, 120, both), run(true, 120, both));
    let bits = |r: &Run| -> Vec<u32> {
        r.x.iter()
            .flat_map(|v| v.to_array())
            .chain(r.impulse.iter().flat_map(|v| v.to_array()))
            .map(f32::to_bits)
            .collect()
    };
    assert!(one.held[0] > 0 && one.pushed[1] > 0);
    assert_eq!(bits(&one), bits(&two));
}
