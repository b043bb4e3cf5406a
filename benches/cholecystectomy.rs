//! Criterion benchmarks of the cholecystectomy's particle models at the size: 20,736
//! particles (a 48 x 27 x 16 block at 3 mm, the size of a liver) in overlapping
//! shape-matching clusters, one 1 ms step (predict, iterations of every cluster, finish); and
//! the whole scene's 1 ms step (21,000 organ particles, vessels, fascia, adhesions, contacts),
//! every particle awake.

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use vesalius::models::particles::Particles;
use vesalius::models::particles::shape::{ShapeMatching, lattice_clusters};
use vesalius::procedures::cholecystectomy::scene::{CholeScene, SceneParams};
use vesalius::procedures::cholecystectomy::{Anatomy, AnatomyParams};

fn liver_block() -> (Particles, ShapeMatching) {
    let h = 0.003;
    let mut p = Particles::new();
    // Mass: liver density 1060 kg/m^3 times the particle's cube.
    let m = 1060.0 * h * h * h;
    for a in 0..48 {
        for b in 0..27 {
            for c in 0..16 {
                p.add(Vec3::new(a as f32, b as f32, c as f32) * h, m, 0);
            }
        }
    }
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let specs = lattice_clusters(&p.x, &all, h, 3, 2.5 * h, 8.0);
    let s = ShapeMatching::new(&p, specs).expect("clusters");
    // Pinned along one face, as the liver hangs from its ligaments.
    for i in 0..p.len() {
        if p.x[i].y == 0.0 {
            p.pin(i);
        }
    }
    (p, s)
}

fn cholecystectomy(c: &mut Criterion) {
    let mut g = c.benchmark_group("cholecystectomy");
    g.sample_size(20);
    for iterations in [1usize, 2, 4] {
        let (mut p, mut s) = liver_block();
        eprintln!(
            "{} particles, {} clusters, {} memberships",
            p.len(),
            s.clusters(),
            s.memberships()
        );
        g.bench_function(
            format!("shape_matching_20736_particles_1ms_step_{iterations}_iterations"),
            |b| {
                b.iter(|| {
                    p.predict(1e-3, Vec3::new(0.0, -9.81, 0.0));
                    s.begin_step();
                    for _ in 0..iterations {
                        s.project(&mut p, 1e-3);
                    }
                    p.finish(1e-3, 5.0);
                })
            },
        );
    }
}

fn scene(c: &mut Criterion) {
    let mut g = c.benchmark_group("cholecystectomy");
    g.sample_size(20);
    let a = Anatomy::generate(&AnatomyParams::default()).expect("anatomy");
    let organs = a.organ_particles();
    let mut s = CholeScene::new(a, SceneParams::default()).expect("scene");
    s.settle(0.2, 8, 60.0);
    eprintln!(
        "scene: {} particles, {organs} in {} clusters",
        s.solver().particles.len(),
        s.solver().shape.clusters()
    );
    g.bench_function("scene_step_1ms_all_awake", |b| {
        b.iter(|| s.step(1e-3, [None, None], 0, &mut Vec::new()))
    });
}

criterion_group!(benches, cholecystectomy, scene);
criterion_main!(benches);
