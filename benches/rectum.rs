//! Criterion benchmarks of the rectum's models at the paper's sizes: the four-layer membrane
//! (600 x 400 x 4 = 960,000 nodes) with every node stepping (one explicit step), the Cosserat
//! rod (30 elements, 1 ms), the L-hook as generalized cylinders against every membrane node,
//! and the coupled scene's 1 ms step while the hook cuts the dissection plane (the active
//! set on; its awake share is printed).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Quat, Vec3};
use vesalius::collision::{Instrument, PointCloud};
use vesalius::models::membrane::Membrane;
use vesalius::procedures::rectum::scene::membrane_params;
use vesalius::procedures::rectum::{Anatomy, AnatomyParams, RectumScene, SceneParams, ToolState};

fn anatomy() -> Anatomy {
    Anatomy::generate(AnatomyParams::default()).expect("anatomy")
}

/// The hook's corner 6 mm beside the plane on top of the rectum at row `i`, shaft from above.
fn hook_at(m: &Membrane, i: usize) -> (Vec3, Quat) {
    let plane = 0.5 * (m.position(m.node(1, i, 0)) + m.position(m.node(2, i, 0)));
    (
        plane + Vec3::new(0.0, 0.0, 0.006),
        Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2),
    )
}

fn rectum(c: &mut Criterion) {
    let a = anatomy();
    let mut g = c.benchmark_group("rectum");
    g.sample_size(10);
    let mut m = Membrane::new(a.membrane.clone(), membrane_params()).expect("membrane");
    let dt = 0.9 * m.step_limit();
    g.bench_function("membrane_960k_all_awake_one_explicit_step", |b| {
        b.iter(|| m.step(dt))
    });
    let (corner, q) = hook_at(&m, 300);
    let hook = Instrument::l_hook(corner, q).expect("hook");
    let points: Vec<Vec3> = (0..m.len()).map(|n| m.position(n)).collect();
    let mut contacts = Vec::new();
    g.bench_function("hook_vs_960k_membrane_nodes_brute_force", |b| {
        b.iter(|| hook.contacts_all(PointCloud::from_points(&points), &mut contacts))
    });
    let mut scene = RectumScene::new(&a, SceneParams::default()).expect("scene");
    g.bench_function("rod_step_1ms", |b| b.iter(|| scene.rod_mut().advance(1e-3)));
    let mut row = 200usize;
    g.bench_function("scene_step_1ms_hook_cutting", |b| {
        b.iter(|| {
            // The hook sweeps along the top of the rectum, one row (0.25 mm) per 5 steps.
            row = 200 + (row - 200 + 1) % 1000;
            let (corner, q) = hook_at(scene.membrane(), 200 + (row - 200) / 5);
            scene.step(
                1e-3,
                &ToolState {
                    hook: Some((corner, q)),
                    cutting: true,
                    grasper: None,
                    grasper_right: None,
                },
                0,
                &mut Vec::new(),
            )
        })
    });
    eprintln!(
        "scene: awake share {:.4} of {} membrane nodes",
        scene.membrane().awake_fraction(),
        scene.membrane().len()
    );
    g.finish();
}

criterion_group!(benches, rectum);
criterion_main!(benches);
