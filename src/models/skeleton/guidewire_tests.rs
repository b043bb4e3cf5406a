use super::*;
use crate::models::skeleton::catheter::CatheterParams;

/// A cantilever's tip deflection under a tip load `f_n`, for a chain of `n` balls `lambda`
/// apart clamped at its first two, each inner joint an angle spring of `k_t`: joint `i`
/// carries the moment `f (n - 1 - i) lambda` and turns by it over `k_t`, which moves the tip
/// by that angle times the same lever: `f lambda^2 sum(m^2) / k_t`, `m` from 1 to `n - 2`.
fn cantilever_m(n: usize, lambda: f64, k_t: f64, f_n: f64) -> f64 {
    let sum: f64 = (1..=n - 2).map(|m| (m * m) as f64).sum();
    f_n * lambda * lambda * sum / k_t
}

/// Half a segment behind the entry: the first two balls held on the axis (clamped).
fn clamp_insertion(length_m: f64, lambda: f64) -> f64 {
    length_m - 1.5 * lambda
}

const LOAD_N: f64 = 8.0e-5;
const DT: f64 = 1.0e-4;
const SETTLE_STEPS: usize = 30_000;

fn catheter() -> Catheter {
    Catheter::new(&CatheterParams::default(), DVec3::ZERO, DVec3::X)
}

/// A viscous bath that settles the chains (`BATH_PER_S` times each ball's mass and speed
/// against its motion): it sets how fast they come to rest, not where.
const BATH_PER_S: f64 = 10.0;

fn with_bath(load: &[DVec3], balls: &Balls) -> Vec<DVec3> {
    load.iter()
        .zip(balls.v.iter().zip(&balls.mass_kg))
        .map(|(f, (v, m))| *f - *v * (BATH_PER_S * m))
        .collect()
}

/// A wire as long as the catheter, balls at the catheter's spacing (so that the two chains'
/// joints coincide), all core, straight.
fn wire(spacing: f64) -> Guidewire {
    let p = GuidewireParams {
        length_m: CatheterParams::default().length_m,
        spacing_m: spacing,
        tip_ei_n_m2: GuidewireParams::default().core_ei_n_m2,
        ..GuidewireParams::default()
    };
    Guidewire::new(&p, DVec3::ZERO, DVec3::X)
}

fn tip_load(n: usize) -> Vec<DVec3> {
    let mut f = vec![DVec3::ZERO; n];
    f[n - 1] = DVec3::new(0.0, -LOAD_N, 0.0);
    f
}

/// The catheter alone, the wire alone and the wire inside the catheter, each clamped and
/// loaded at its tip, settle to the discrete cantilever's deflection for their joints'
/// stiffness; inside, the two bend as one with the sum of their stiffnesses (each within
/// 3 %), and the lumen holds every free wire ball.
#[test]
fn wire_in_catheter_bends_with_the_sum_of_their_stiffnesses() {
    let mut c = catheter();
    let lambda = c.spacing_m();
    let n = c.balls.len();
    let k_c = c.angles[0].stiffness_n_m_per_rad;
    let drive = Drive {
        insertion_m: clamp_insertion(c.params.length_m, lambda),
        ..Drive::default()
    };
    c.orient(&drive);
    let load = tip_load(n);
    for _ in 0..SETTLE_STEPS {
        let f = with_bath(&load, &c.balls);
        c.step(&drive, &f, DT);
    }
    let alone_c = -c.tip().y;
    let want_c = cantilever_m(n, lambda, k_c, LOAD_N);
    assert!(
        (alone_c - want_c).abs() < 0.03 * want_c,
        "catheter {alone_c} m, analytic {want_c} m"
    );

    let mut w = wire(lambda);
    assert_eq!(w.balls.len(), n);
    let k_w = w.angles[0].stiffness_n_m_per_rad;
    let wd = WireDrive {
        insertion_m: clamp_insertion(w.params.length_m, lambda),
        twist_rad: 0.0,
    };
    w.orient(0.0);
    for _ in 0..SETTLE_STEPS {
        let f = with_bath(&load, &w.balls);
        w.step(&wd, &f, DT);
    }
    let alone_w = -w.tip().y;
    let want_w = cantilever_m(n, lambda, k_w, LOAD_N);
    assert!(
        (alone_w - want_w).abs() < 0.03 * want_w,
        "wire {alone_w} m, analytic {want_w} m"
    );

    // Together: the load on the catheter's tip, nothing on the wire's.
    let (mut c, mut w) = (catheter(), wire(lambda));
    c.orient(&drive);
    w.orient(0.0);
    let none = vec![DVec3::ZERO; n];
    let mut held = 0;
    for _ in 0..SETTLE_STEPS {
        let (fc, fw) = (with_bath(&load, &c.balls), with_bath(&none, &w.balls));
        held = step_together(&mut c, (&drive, &fc), &mut w, (&wd, &fw), DT);
    }
    let both = -c.tip().y;
    let want = cantilever_m(n, lambda, k_c + k_w, LOAD_N);
    eprintln!(
        "tip deflection: catheter {alone_c:.4e} m ({want_c:.4e}), wire {alone_w:.4e} m \
         ({want_w:.4e}), together {both:.4e} m ({want:.4e})"
    );
    assert!(
        (both - want).abs() < 0.03 * want,
        "together {both} m, with the summed stiffness {want} m (catheter alone {alone_c}, \
         wire alone {alone_w})"
    );
    // The wire follows the catheter: its tip within a tenth of a millimetre of the
    // catheter's, every ball but the held handle in the lumen.
    assert!(w.tip().distance(c.tip()) < 1e-4, "{} {}", w.tip(), c.tip());
    assert_eq!(held, n - 1);
}

/// A J tip: the soft tip's rest curve turns the wire's end through the J's angle, in the
/// plane its twist sets; a straight wire stays straight.
#[test]
fn a_j_tip_curls_in_the_plane_its_twist_turns() {
    let p = GuidewireParams {
        j_angle_deg: 90.0,
        ..GuidewireParams::default()
    };
    let run = |twist: f64, p: &GuidewireParams| {
        let mut w = Guidewire::new(p, DVec3::ZERO, DVec3::X);
        // All of it past the entry but the handle's two balls.
        let lambda = p.length_m / (w.balls.len() - 1) as f64;
        let drive = WireDrive {
            insertion_m: clamp_insertion(p.length_m, lambda),
            twist_rad: twist,
        };
        let none = vec![DVec3::ZERO; w.balls.len()];
        for _ in 0..SETTLE_STEPS {
            w.orient(twist);
            let f = with_bath(&none, &w.balls);
            w.step(&drive, &f, DT);
        }
        let n = w.balls.len();
        (w.balls.x[n - 1] - w.balls.x[n - 2]).normalize()
    };
    // Untwisted, the curve is towards the entry's "up" (+y for an axis along x): the last
    // segment turned about 90 degrees from the axis towards +y (the first tip segment
    // leaves the core turned by one joint's share already).
    let end = run(0.0, &p);
    let turned = end.dot(DVec3::X).clamp(-1.0, 1.0).acos().to_degrees();
    assert!((turned - 90.0).abs() < 10.0, "turned {turned} deg: {end}");
    assert!(end.y > 0.9, "{end}");
    // A quarter turn of the handle puts the curve in the x-z plane, towards -z (+y turned
    // about +x).
    let end = run(std::f64::consts::FRAC_PI_2, &p);
    assert!(end.z > 0.9 && end.y.abs() < 0.1, "{end}");
    let straight = run(
        0.0,
        &GuidewireParams {
            j_angle_deg: 0.0,
            ..p
        },
    );
    assert!(straight.dot(DVec3::X) > 1.0 - 1e-9, "{straight}");
}

/// The world (the catheter and the wire in its stage, the wall contact and the lumen as its
/// coupling) steps the two as `step_together` does, bit for bit, while neither touches the
/// wall: the catheter's tip at the inlet, the wire fed 6 mm past it and twisted, its tip
/// angled.
#[test]
fn the_world_steps_wire_and_catheter_as_step_together_does() {
    use crate::models::skeleton::contact::ContactLaw;
    use crate::models::skeleton::in_vessel::CatheterInVessel;
    use crate::models::skeleton::vessel::{Vessel, VesselParams};
    let law = ContactLaw {
        stiffness_n_per_m: 500.0,
        damping_n_s_per_m: 0.3,
        preload_n: 0.5,
        friction: 0.1,
    };
    let p = GuidewireParams {
        j_angle_deg: 45.0,
        ..GuidewireParams::default()
    };
    let substeps = 10u32;
    let mut scene = CatheterInVessel::new(
        catheter(),
        Vessel::new(&VesselParams::default()),
        law,
        3.0,
        substeps,
    )
    .with_wire(Guidewire::new(&p, DVec3::ZERO, DVec3::X), law, 0.27);
    let (mut c, mut w) = (catheter(), Guidewire::new(&p, DVec3::ZERO, DVec3::X));
    let drive = Drive::default();
    let wd = WireDrive {
        insertion_m: 0.006,
        twist_rad: 1.0,
    };
    let dt_s = 0.001f32;
    let h = f64::from(dt_s) / f64::from(substeps);
    let (none_c, none_w) = (
        vec![DVec3::ZERO; c.balls.len()],
        vec![DVec3::ZERO; w.balls.len()],
    );
    for step in 0..40 {
        let out = scene.step((&drive, &wd), dt_s, step, &mut Vec::new());
        let wire_out = scene.wire_outcome();
        assert_eq!(
            (out.reaction, wire_out.reaction),
            (DVec3::ZERO, DVec3::ZERO),
            "step {step}"
        );
        c.orient(&drive);
        for _ in 0..substeps {
            step_together(&mut c, (&drive, &none_c), &mut w, (&wd, &none_w), h);
        }
    }
    let got = scene.guidewire().expect("a wire");
    assert_eq!(got.balls.x, w.balls.x);
    assert_eq!(got.balls.v, w.balls.v);
    assert_eq!(scene.catheter().balls.x, c.balls.x);
    // The wire came out ahead of the catheter, and the lumen held it inside.
    assert!(w.tip().x > c.tip().x + 0.004, "{} {}", w.tip(), c.tip());
    assert!(scene.wire_outcome().held > 10, "{:?}", scene.wire_outcome());
}

/// The catheter shields the wire's balls inside it from the wall: those along its length
/// are marked, those past its tip and behind its handle are not.
#[test]
fn the_catheter_shields_the_wire_inside_it() {
    let c = catheter();
    let w = Guidewire::new(&GuidewireParams::default(), DVec3::ZERO, DVec3::X).inserted(0.02);
    let inside = shielded(&c, &w);
    let (handle, tip) = (c.balls.x[0].x, c.tip().x);
    for (x, s) in w.balls.x.iter().zip(&inside) {
        let within = (handle..=tip).contains(&x.x);
        assert_eq!(*s, within, "{x} (catheter {handle} to {tip})");
    }
    assert!(inside.iter().filter(|s| **s).count() >= 19, "{inside:?}");
    assert!(!inside[inside.len() - 1]);
}
