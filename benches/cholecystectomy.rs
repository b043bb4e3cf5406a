//! Criterion benchmarks of the cholecystectomy's particle models at the size: 20,736
//! particles (a 48 x 27 x 16 block at 3 mm, the size of a liver) in overlapping
//! shape-matching clusters, one 1 ms step (predict, iterations of every cluster, finish).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use vesalius::models::particles::Particles;
use vesalius::models::particles::shape::{ShapeMatching, lattice_clusters};

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

criterion_group!(benches, cholecystectomy);
criterion_main!(benches);
