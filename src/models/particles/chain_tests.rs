use super::*;

/// A vertical chain of `n` particles `h` apart hanging down from a pinned top, each of
/// `mass`, with `load` kg more on the last.
fn hanging(n: usize, h: f32, mass: f32, load: f32) -> (Particles, Vec<u32>) {
    let mut p = Particles::new();
    let ids: Vec<u32> = (0..n)
        .map(|k| {
            let m = if k + 1 == n { mass + load } else { mass };
            p.add(Vec3::new(0.0, -(k as f32) * h, 0.0), m, 0)
        })
        .collect();
    p.pin(0);
    (p, ids)
}

fn settle(p: &mut Particles, c: &mut Chains, dt: f32, iterations: usize, steps: usize) {
    for _ in 0..steps {
        p.predict(dt, Vec3::new(0.0, -9.81, 0.0));
        c.begin_step();
        for _ in 0..iterations {
            c.project(p, dt);
        }
        p.finish(dt, 30.0);
    }
}

#[test]
fn a_hanging_chain_stretches_by_the_weight_below_each_segment() {
    // 12 light particles (0.1 g, a duct's) and 20 g at the end, stiff segments (500 N/m):
    // segment k carries the weight below it and stretches by it over k.
    let (n, h, m, load, k) = (12usize, 0.003, 1e-4, 0.02, 500.0);
    let (mut p, ids) = hanging(n, h, m, load);
    let mut c = Chains::new();
    c.add(&p, &ids, k, 0.0);
    settle(&mut p, &mut c, 1e-3, 2, 1500);
    let g = 9.81;
    let mut expected = 0.0;
    for s in 0..n - 1 {
        let below = (n - 1 - s) as f32 * m + load;
        expected += below * g / k;
        let tension = c.tension_n(0, s);
        assert!(
            (tension - below * g).abs() < 0.01 * below * g,
            "segment {s}: {tension} N vs {}",
            below * g
        );
    }
    let stretch = -p.x[n - 1].y - (n - 1) as f32 * h;
    assert!(
        (stretch - expected).abs() < 0.02 * expected,
        "{stretch} vs {expected}"
    );
}

#[test]
fn a_cut_chain_lets_its_lower_part_fall() {
    let (mut p, ids) = hanging(10, 0.003, 1e-4, 0.0);
    let mut c = Chains::new();
    c.add(&p, &ids, 500.0, 5.0);
    settle(&mut p, &mut c, 1e-3, 2, 500);
    assert!(c.cut(0, 4));
    assert!(!c.cut(0, 4), "already cut");
    assert!(!c.is_intact(0, 4) && c.is_intact(0, 3) && c.is_intact(0, 5));
    let top = p.x[4];
    let below = p.x[5];
    // 50 ms of free fall: g t^2 / 2 = 12.3 mm (the point damping of 30/s takes some).
    for _ in 0..50 {
        p.predict(1e-3, Vec3::new(0.0, -9.81, 0.0));
        c.begin_step();
        c.project(&mut p, 1e-3);
        p.finish(1e-3, 0.0);
    }
    let fell = below.y - p.x[5].y;
    assert!((fell - 0.0123).abs() < 0.1 * 0.0123, "{fell}");
    assert!(top.distance(p.x[4]) < 0.001, "the upper part stays");
}

#[test]
fn the_nearest_segment_is_the_one_beside_the_point() {
    let (p, ids) = hanging(6, 0.01, 1e-4, 0.0);
    let mut c = Chains::new();
    c.add(&p, &ids, 100.0, 0.0);
    let (k, d) = c
        .nearest_segment(&p, 0, Vec3::new(0.002, -0.025, 0.0))
        .expect("segment");
    assert_eq!(k, 2);
    assert!((d - 0.002).abs() < 1e-6);
    assert_eq!(c.segments(0), 5);
}
