use super::shape::{ClusterSpec, ShapeMatching, lattice_clusters, rotation_of};
use super::*;
use glam::{Mat3, Quat};

/// A block of `n x n x n` particles `h` apart from the origin, each of `mass` kg, body 0.
fn block(n: usize, h: f32, mass: f32) -> Particles {
    let mut p = Particles::new();
    for a in 0..n {
        for b in 0..n {
            for c in 0..n {
                p.add(Vec3::new(a as f32, b as f32, c as f32) * h, mass, 0);
            }
        }
    }
    p
}

fn one_cluster(p: &Particles, frequency_hz: f32) -> ShapeMatching {
    let n = p.len();
    // Weights that vary, so the weighted centre and matrix are really weighted.
    let weights = (0..n)
        .map(|i| 0.25 + 0.75 * ((i * 7) % 11) as f32 / 10.0)
        .collect();
    ShapeMatching::new(
        p,
        vec![ClusterSpec {
            members: (0..n as u32).collect(),
            weights,
            frequency_hz,
        }],
    )
    .expect("cluster")
}

#[test]
fn a_rigid_rotation_and_translation_is_reproduced_by_the_goals() {
    let mut p = block(4, 0.01, 1e-3);
    let mut s = one_cluster(&p, 10.0);
    let r = Quat::from_axis_angle(Vec3::new(1.0, -2.0, 0.5).normalize(), 2.3);
    let t = Vec3::new(0.05, -0.02, 0.3);
    for x in &mut p.x {
        *x = r * *x + t;
    }
    s.match_goals(&p.x);
    // The rotation found is the one applied, and every goal is where its particle is (eq 4),
    // to a few ulps of the coordinates.
    let found = s.rotation(0);
    assert!(found.angle_between(r) < 2e-6, "{found:?} vs {r:?}");
    let worst =
        p.x.iter()
            .enumerate()
            .map(|(slot, x)| s.goal(0, slot).distance(*x))
            .fold(0.0f32, f32::max);
    // f32 spacing at 0.3 m is 3e-8 m; the sums over 64 particles round to some of them.
    assert!(worst < 5e-7, "{worst}");
}

#[test]
fn the_rotation_of_a_stretched_and_turned_matrix_is_the_turn() {
    let r = Quat::from_axis_angle(Vec3::Z, -1.1) * Quat::from_axis_angle(Vec3::X, 0.4);
    // A symmetric positive stretch after the turn: polar decomposition gives the turn back.
    let stretch = Mat3::from_cols(
        Vec3::new(2.0, 0.3, 0.0),
        Vec3::new(0.3, 0.5, 0.1),
        Vec3::new(0.0, 0.1, 1.2),
    );
    let a = Mat3::from_quat(r) * stretch;
    let q = rotation_of(&a, Quat::IDENTITY, 30);
    assert!(q.angle_between(r) < 1e-5, "{q:?} vs {r:?}");
    // A flat matrix (all particles in a plane) still gives a rotation.
    let flat = Mat3::from_cols(Vec3::X, Vec3::Y, Vec3::ZERO);
    let q = rotation_of(&(Mat3::from_quat(r) * flat), Quat::IDENTITY, 30);
    assert!((q.length() - 1.0).abs() < 1e-6);
    assert!(q.angle_between(r) < 1e-4, "{q:?}");
}

/// Steps a world of one shape-matching body (no gravity) for `steps` of `dt` with `iters`.
fn run(p: &mut Particles, s: &mut ShapeMatching, dt: f32, iters: usize, steps: usize) {
    for _ in 0..steps {
        p.predict(dt, Vec3::ZERO);
        s.begin_step();
        for _ in 0..iters {
            s.project(p, dt);
        }
        p.finish(dt, 0.0);
    }
}

#[test]
fn a_squeezed_block_returns_to_its_rest_shape() {
    let h = 0.004;
    let mut p = block(6, h, 1e-4);
    let rest = p.x.clone();
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let specs = lattice_clusters(&p.x, &all, h, 2, 2.0 * h, 20.0);
    assert!(specs.len() > 4, "{}", specs.len());
    let mut s = ShapeMatching::new(&p, specs).expect("clusters");
    assert_eq!(s.particles_in_clusters(), p.len());
    // Squeezed to 70 % along x about the block's middle.
    let mid = 2.5 * h;
    for x in &mut p.x {
        x.x = mid + 0.7 * (x.x - mid);
    }
    let squeezed: f32 = p.x.iter().zip(&rest).map(|(a, b)| a.distance(*b)).sum();
    // With point damping, 0.5 s (10 periods of the clusters' 20 Hz) brings it back.
    for _ in 0..500 {
        p.predict(1e-3, Vec3::ZERO);
        s.begin_step();
        for _ in 0..4 {
            s.project(&mut p, 1e-3);
        }
        p.finish(1e-3, 20.0);
    }
    let back: f32 = p.x.iter().zip(&rest).map(|(a, b)| a.distance(*b)).sum();
    assert!(p.is_finite());
    assert!(back < 0.01 * squeezed, "{back} of {squeezed}");
}

#[test]
fn the_clusters_stiffness_does_not_change_with_iterations_or_the_step() {
    // One cluster, swollen 2 % about its centre: its centre and rotation stay, every goal is
    // at rest, and each particle swings on its spring at the cluster's frequency. The swell
    // first passes through zero a quarter period later, whatever the step's iterations (5 or
    // 20) or dt (1 or 0.5 ms).
    let f = 5.0f32;
    let first_crossing = |dt: f32, iters: usize| {
        let mut p = block(3, 0.01, 1e-3);
        let mut s = one_cluster(&p, f);
        let centre = Vec3::splat(0.01);
        let size = |p: &Particles| p.x.iter().map(|x| x.distance(centre)).sum::<f32>();
        let rest = size(&p);
        for x in &mut p.x {
            *x = centre + (*x - centre) * 1.02;
        }
        let mut t = 0.0;
        loop {
            run(&mut p, &mut s, dt, iters, 1);
            t += dt;
            if size(&p) < rest || t > 1.0 {
                return t;
            }
        }
    };
    let t5 = first_crossing(1e-3, 5);
    let t20 = first_crossing(1e-3, 20);
    let t_half = first_crossing(5e-4, 5);
    let quarter = 0.25 / f;
    for t in [t5, t20, t_half] {
        assert!((t - quarter).abs() < 0.1 * quarter, "{t} vs {quarter}");
    }
    assert!((t5 - t20).abs() <= 0.05 * t20, "{t5} vs {t20}");
}

#[test]
fn bad_clusters_are_refused_with_what_is_wrong() {
    let p = block(2, 0.01, 1e-3);
    let spec = |members: Vec<u32>, weights: Vec<f32>, f: f32| ClusterSpec {
        members,
        weights,
        frequency_hz: f,
    };
    let e = ShapeMatching::new(&p, vec![spec(vec![0, 1], vec![1.0], 5.0)]).unwrap_err();
    assert!(e.to_string().contains("2 members but 1 weights"), "{e}");
    let e = ShapeMatching::new(&p, vec![spec(vec![0, 99], vec![1.0, 1.0], 5.0)]).unwrap_err();
    assert!(e.to_string().contains("particle 99"), "{e}");
    let e = ShapeMatching::new(&p, vec![spec(vec![0, 1], vec![1.0, 1.5], 5.0)]).unwrap_err();
    assert!(e.to_string().contains("weight 1.5"), "{e}");
    let e = ShapeMatching::new(&p, vec![spec(vec![0, 1], vec![1.0, 1.0], 0.0)]).unwrap_err();
    assert!(e.to_string().contains("frequency"), "{e}");
}

#[test]
fn one_or_two_threads_give_the_same_bytes() {
    let h = 0.003;
    let make = || {
        let mut p = block(12, h, 1e-4);
        let all: Vec<u32> = (0..p.len() as u32).collect();
        let specs = lattice_clusters(&p.x, &all, h, 3, 2.5 * h, 10.0);
        let s = ShapeMatching::new(&p, specs).expect("clusters");
        for (i, x) in p.x.iter_mut().enumerate() {
            x.y += 0.0005 * ((i * 13 % 17) as f32 / 17.0);
        }
        (p, s)
    };
    let hash = |threads: usize| {
        crate::sim::on_threads(threads, || {
            let (mut p, mut s) = make();
            run(&mut p, &mut s, 1e-3, 3, 50);
            p.state_hash()
        })
    };
    assert_eq!(hash(1), hash(2));
}
