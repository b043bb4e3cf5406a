use super::catheter::{Catheter, CatheterParams, Drive};
use super::collision::{Hit, detect};
use super::contact::ContactLaw;
use super::vessel::{Vessel, VesselParams};
use super::*;

const G: DVec3 = DVec3::new(0.0, -9.81, 0.0);

/// A chain of 10 of the paper's balls (2 g) hanging from a held top ball on its springs
/// (100 N/m, 0.3 N s/m) settles with each spring stretched by the weight below it, `(n - 1 -
/// j) m g / k`, within 2 %.
#[test]
fn a_hanging_chain_settles_to_the_analytic_elongation() {
    let (n, m, k, c, rest) = (10usize, 0.002, 100.0, 0.3, 0.005);
    let mut balls = Balls::default();
    for i in 0..n {
        balls.push(DVec3::new(0.0, -rest * i as f64, 0.0), m, 0.001);
    }
    balls.fixed[0] = true;
    let springs: Vec<LinearSpring> = (0..n - 1)
        .map(|i| LinearSpring::between(&balls, i as u32, i as u32 + 1, k, c))
        .collect();
    let dt = 1e-4;
    for _ in 0..150_000 {
        balls.start_forces(G);
        add_spring_forces(&mut balls, &springs);
        balls.integrate(dt);
    }
    for j in 0..n - 1 {
        let stretch = balls.x[j].distance(balls.x[j + 1]) - rest;
        let want = (n - 1 - j) as f64 * m * 9.81 / k;
        assert!(
            (stretch - want).abs() <= 0.02 * want,
            "spring {j}: {stretch} m, analytic {want} m"
        );
    }
}

/// Three balls, the first two held: the third pushed sideways swings back to the spring's
/// rest (straight, then a rest turn of 0.4 rad), and the forces sum to zero.
#[test]
fn an_angle_spring_returns_to_rest() {
    for rest in [0.0, 0.4] {
        let mut balls = Balls::default();
        for i in 0..3 {
            balls.push(DVec3::new(0.01 * i as f64, 0.0, 0.0), 0.002, 0.001);
        }
        balls.fixed[0] = true;
        balls.fixed[1] = true;
        balls.x[2] += DVec3::new(0.0, 0.004, 0.002);
        let link = LinearSpring {
            a: 1,
            b: 2,
            rest_m: 0.01,
            stiffness_n_per_m: 200.0,
            damping_n_s_per_m: 0.3,
        };
        let spring = AngleSpring {
            prev: 0,
            mid: 1,
            next: 2,
            stiffness_n_m_per_rad: 0.01,
            damping_n_m_s_per_rad: 0.0,
            rest_turn: DVec3::Z * rest,
        };
        let sum: DVec3 = spring.forces(&balls).iter().sum();
        assert!(sum.length() < 1e-12, "{sum}");
        for _ in 0..50_000 {
            balls.start_forces(DVec3::ZERO);
            add_spring_forces(&mut balls, &[link]);
            add_angle_forces(&mut balls, &[spring]);
            // Some drag so it settles.
            for i in 0..3 {
                let v = balls.v[i];
                balls.f[i] -= v * 0.01;
            }
            balls.integrate(1e-4);
        }
        let turn = spring.turn(&balls);
        assert!(
            (turn - DVec3::Z * rest).length() < 1e-3,
            "rest {rest}: {turn}"
        );
    }
}

/// Eqs 11-16: every ball of the bent part lies on the circle of radius `L / (2 theta)`
/// tangent to the straight axis at the first ball, neighbours `s` apart, the last ball's
/// chord at `theta` to the axis; straight, no offsets.
#[test]
fn the_bending_offsets_lie_on_the_constant_curvature_arc() {
    let (n, l) = (7, 0.03);
    for theta in [0.2f64, 0.6, 0.785] {
        let (beta, s, r) = bending::arc(n, l, theta);
        assert!((beta - theta / 6.0).abs() < 1e-15);
        let pts: Vec<(f64, f64)> = bending::offsets(n, l, theta)
            .iter()
            .enumerate()
            .map(|(i, (dx, dy))| (*dx, dy + i as f64 * l / 6.0))
            .collect();
        for (i, &(x, y)) in pts.iter().enumerate() {
            let from_centre = ((x - r).powi(2) + y * y).sqrt();
            assert!(
                (from_centre - r).abs() < 1e-12,
                "ball {i}: {from_centre} vs {r}"
            );
            if i > 0 {
                let (px, py) = pts[i - 1];
                let chord = ((x - px).powi(2) + (y - py).powi(2)).sqrt();
                assert!((chord - s).abs() < 1e-12, "chord {i}");
            }
        }
        let (x, y) = pts[n - 1];
        assert!((x.atan2(y) - theta).abs() < 1e-12);
        // The arc through them is the axis's length.
        assert!((r * 2.0 * theta - l).abs() < 1e-12);
    }
    assert!(
        bending::offsets(n, l, 0.0)
            .iter()
            .all(|&(x, y)| x == 0.0 && y.abs() < 1e-15)
    );
}

/// Eqs 8-10 for scripted contacts: `|F_N| = k D + c v + t` along the wall's normal,
/// friction `mu |F_N|` against the sliding, nothing without depth, never a pull.
#[test]
fn the_contact_force_follows_the_papers_law() {
    let law = ContactLaw {
        stiffness_n_per_m: 500.0,
        damping_n_s_per_m: 0.3,
        preload_n: 0.5,
        friction: 0.1,
    };
    let n = DVec3::Y;
    // 2 mm deep, moving into the wall at 10 mm/s and along it at 20 mm/s.
    let v = DVec3::new(0.02, -0.01, 0.0);
    let f = law.force(0.002, n, v);
    let want = 500.0 * 0.002 + 0.3 * 0.01 + 0.5;
    assert!((f.normal - n * want).length() < 1e-12, "{:?}", f.normal);
    assert!((f.friction.length() - 0.1 * want).abs() < 1e-12);
    assert!(f.friction.dot(DVec3::X) < 0.0 && f.friction.y.abs() < 1e-15);
    assert_eq!(law.force(0.0, n, v).total(), DVec3::ZERO);
    assert_eq!(law.force(-0.001, n, v).total(), DVec3::ZERO);
    // Leaving fast: the damping would pull; the force stops at zero.
    assert_eq!(law.force(0.0001, n, DVec3::Y * 10.0).normal, DVec3::ZERO);
}

/// The paper's vessel: 20 mm across with a 2 mm wall, a trunk and two branches; its balls
/// at the wall's mid-radius, the inlet ring held, the lumen open along every tube's axis
/// (no ball within a catheter ball's reach of it), the bifurcation's openings carved.
#[test]
fn the_vessel_is_a_bifurcating_wall_of_balls_with_an_open_lumen() {
    let v = Vessel::new(&VesselParams::default());
    eprintln!(
        "vessel: {} balls, {} springs",
        v.balls.len(),
        v.springs.len()
    );
    assert!(
        v.balls.len() > 600 && v.balls.len() < 1200,
        "{}",
        v.balls.len()
    );
    assert!(
        v.tubes
            .iter()
            .all(|t| (t.mid_radius_m - 0.009).abs() < 1e-12)
    );
    assert_eq!(v.balls.fixed.iter().filter(|&&f| f).count(), 16);
    for tube in &v.tubes {
        for k in 0..=20 {
            let p = tube.start + tube.dir * tube.length_m * k as f64 / 20.0;
            let nearest = v
                .balls
                .x
                .iter()
                .map(|x| x.distance(p))
                .fold(f64::MAX, f64::min);
            assert!(nearest > 0.005 + 0.001, "{nearest} m from the axis at {p}");
        }
    }
}

/// The collision looks only at the sections near each catheter ball: the pairs it tests do
/// not grow (within 20 %) when the vessel is made 4 times longer, and it finds the same hits.
#[test]
fn collision_cost_does_not_grow_with_the_vessels_length() {
    let short = Vessel::new(&VesselParams::default());
    let long = Vessel::new(&VesselParams {
        trunk_m: 0.24,
        branch_m: 0.24,
        ..VesselParams::default()
    });
    let place = |c: &mut Catheter| {
        // The tip pressed 1 mm into the trunk's wall 30 mm in.
        let last = c.balls.len() - 1;
        c.balls.x[last] = DVec3::new(0.03, 0.009 - 0.006 + 0.001, 0.0);
    };
    let mut c = Catheter::new(
        &CatheterParams::default(),
        DVec3::new(0.02, 0.0, 0.0),
        DVec3::X,
    );
    place(&mut c);
    let holes = vec![false; long.balls.len()];
    let (mut a, mut b): (Vec<Hit>, Vec<Hit>) = (Vec::new(), Vec::new());
    let ta = detect(&c.balls, 0, &short, &holes, &mut a);
    let tb = detect(&c.balls, 0, &long, &holes, &mut b);
    eprintln!("pair tests: {ta} short, {tb} four times longer");
    assert!(ta > 0 && (tb as f64) <= 1.2 * ta as f64, "{ta} vs {tb}");
    assert!(!a.is_empty() && a.len() == b.len());
    assert!(a.iter().all(|h| h.depth_m > 0.0 && h.normal.y < 0.0));
}

/// A twist at the handle reaches the tip; the active bend turns the tip's last segment as
/// the arc's last chord turns, towards its "up", which the twist has turned.
#[test]
fn twisting_transmits_and_the_tip_bends_along_the_arc() {
    let p = CatheterParams::default();
    let mut c = Catheter::new(&p, DVec3::ZERO, DVec3::X);
    let dt = 1e-4;
    let zero = vec![DVec3::ZERO; c.balls.len()];
    let quarter = std::f64::consts::FRAC_PI_2;
    for k in 0..20_000 {
        let drive = Drive {
            insertion_m: 0.05 * (k as f64 / 5000.0).min(1.0),
            twist_rad: quarter * (k as f64 / 2000.0).min(1.0),
            bend: (k as f64 / 5000.0).min(1.0),
        };
        c.orient(&drive);
        c.step(&drive, &zero, dt);
    }
    let tip_twist = c.twist[c.balls.len() - 1];
    assert!((tip_twist - quarter).abs() < 0.01 * quarter, "{tip_twist}");
    let n = c.balls.len();
    let last = (c.balls.x[n - 1] - c.balls.x[n - 2]).normalize();
    let turned = last.angle_between(DVec3::X);
    // The last chord of the arc: `2 theta - beta` from the axis (the tangent there is at
    // `2 theta`).
    let theta = p.max_bend_deg.to_radians();
    let want = 2.0 * theta - theta / (c.bend_balls - 1) as f64;
    assert!(
        (turned - want).abs() < 0.05 * want,
        "{turned} rad vs {want}"
    );
    // Twisted a quarter turn from +y: the tip bends towards +z.
    assert!(last.z > 0.5 && last.y.abs() < 0.1, "{last}");
}

/// The paper's vessel and contact law (k 500 N/m, c 0.3 N s/m, t 0.5 N, mu 0.1) with the
/// default catheter, 10 sub-steps a 1 ms step.
fn scene(puncture_n: f64, entry: DVec3, axis: DVec3) -> in_vessel::CatheterInVessel {
    let vessel = Vessel::new(&VesselParams::default());
    let catheter = Catheter::new(&CatheterParams::default(), entry, axis);
    let law = ContactLaw {
        stiffness_n_per_m: 500.0,
        damping_n_s_per_m: 0.3,
        preload_n: 0.5,
        friction: 0.1,
    };
    in_vessel::CatheterInVessel::new(catheter, vessel, law, puncture_n, 10)
}

/// Pushed at 20 mm/s with its tip bent towards +y from the bifurcation on, the catheter
/// enters the +y branch; the largest force on its head meanwhile lies within the paper's
/// 0.5-3.5 N, and the wall holds (no puncture at 3 N).
#[test]
fn the_bent_catheter_enters_the_branch_it_points_to_within_the_papers_forces() {
    let mut s = scene(3.0, DVec3::ZERO, DVec3::X);
    let mut largest = 0.0f64;
    let mut touched = 0;
    // 5.5 s: 110 mm in, the tip well into the 60 mm branch (beyond its end the model has
    // no wall).
    for k in 0..5500 {
        let t = k as f64 * 0.001;
        let insertion = 0.02 * t;
        let drive = Drive {
            insertion_m: insertion,
            twist_rad: 0.0,
            bend: if insertion > 0.045 { 1.0 } else { 0.0 },
        };
        let out = s.step(
            (&drive, &Default::default()),
            0.001,
            k as u64,
            &mut Vec::new(),
        );
        assert!(out.punctures.is_empty(), "punctured at {t} s");
        if out.head_normal_n > 0.0 {
            touched += 1;
        }
        largest = largest.max(out.head_normal_n);
    }
    eprintln!("largest head force {largest} N over {touched} steps in contact");
    assert!(touched > 0 && (0.5..=3.5).contains(&largest), "{largest} N");
    let tip = s.catheter().tip();
    let branch = &s.vessel().tubes[1];
    assert!(
        branch.along(tip) > 0.01 && branch.from_axis(tip) < branch.mid_radius_m,
        "tip at {tip}"
    );
}

/// Pushed from the trunk's axis straight up into its wall at 30 mm/s, the wall gives way
/// above the puncture force and not below it: with the threshold over the largest push
/// seen, nothing; under it, a puncture reported with a force above the threshold.
#[test]
fn a_puncture_fires_above_its_threshold_and_not_below() {
    let push = |threshold: f64| {
        let mut s = scene(threshold, DVec3::new(0.03, 0.0, 0.0), DVec3::Y);
        let mut largest = 0.0f64;
        let mut punctures = Vec::new();
        for k in 0..6000 {
            let drive = Drive {
                insertion_m: 0.03 * k as f64 * 0.001,
                twist_rad: 0.0,
                bend: 0.0,
            };
            let out = s.step(
                (&drive, &Default::default()),
                0.001,
                k as u64,
                &mut Vec::new(),
            );
            largest = largest.max(out.largest_push_n);
            punctures.extend(out.punctures);
        }
        (largest, punctures)
    };
    let (largest, none) = push(f64::INFINITY);
    assert!(none.is_empty() && largest > 1.0, "{largest} N");
    let (_, below) = push(1.1 * largest);
    assert!(below.is_empty());
    let (_, fired) = push(0.6 * largest);
    assert!(!fired.is_empty());
    assert!(fired.iter().all(|p| p.force_n > 0.6 * largest));
}
