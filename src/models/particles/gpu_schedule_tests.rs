//! The scheduled sweep against the colour-by-colour one on the device: the same bytes.

use super::solver::{pulled, sheet, stacked, steps, still_on_gpu, strands_scene};
use super::*;
use crate::models::particles::gpu::Sweeps;
use crate::models::particles::solver::ParticleSolver;

/// A scene, and what is done with it.
type Scene = fn() -> ParticleSolver;
type Run = dyn Fn(&mut ParticleSolver);

/// `run` on a fresh scene on the device with its sweeps dispatched as `sweeps`: the
/// particles' bits after it, and the sweep's dispatches and levels.
fn bits(gpu: &Gpu, make: Scene, sweeps: Sweeps, run: &Run) -> (Vec<[u32; 3]>, (usize, [usize; 2])) {
    let mut s = make();
    s.use_gpu_with(gpu, sweeps)
        .expect("the device takes the scene");
    run(&mut s);
    still_on_gpu(&mut s);
    let dispatches = s.gpu_sweep_dispatches().expect("on the device");
    let x = s.particles.x.iter().map(|p| p.to_array().map(f32::to_bits));
    (x.collect(), dispatches)
}

#[test]
fn a_scheduled_sweep_gives_the_bytes_of_the_colour_by_colour_one() {
    let gpu = gpu();
    // Strands pulled until they all tear (the constraints go up again at each tear), a sheet
    // of cloth cut across, and two bodies meeting (contacts searched and coloured).
    let pull = |s: &mut ParticleSolver| {
        let torn: usize = pulled(s, 0..300).iter().sum();
        assert_eq!(torn, 36);
    };
    let cut = |s: &mut ParticleSolver| {
        steps(s, 50);
        let mid = s.particles.x[4 * 10 + 5];
        assert!(s.dissect(mid, 0.012).cloth > 0);
        steps(s, 50);
    };
    let meet = |s: &mut ParticleSolver| {
        steps(s, 120);
    };
    let scenes: [(&str, Scene, &Run); 3] = [
        ("strands", strands_scene, &pull),
        ("cloth", sheet, &cut),
        ("contacts", stacked, &meet),
    ];
    for (name, make, run) in scenes {
        let (by_colour, (colour_dispatches, none)) = bits(&gpu, make, Sweeps::ByColour, run);
        let (scheduled, (dispatches, levels)) = bits(&gpu, make, Sweeps::Scheduled, run);
        assert_eq!(none, [0, 0], "{name}: no levels when dispatched by colour");
        assert!(
            by_colour == scheduled,
            "{name}: the scheduled sweep's particles differ from the colour-by-colour one's"
        );
        assert!(
            dispatches <= 2 && dispatches < colour_dispatches,
            "{name}: {dispatches} dispatches a sweep against {colour_dispatches} by colour"
        );
        assert!(levels[0] + levels[1] > 0, "{name}: nothing was scheduled");
        // The scene moved (a still scene would agree trivially).
        let start = make().particles.x;
        let moved = largest_move(&scheduled, &start);
        assert!(moved > 1e-3, "{name}: moved {moved} m");
    }
}
