//! Cases for the skeleton-spring model (`crate::models::skeleton`, the catheter paper's eqs
//! 1-16): a hanging chain's springs against the weight they carry, the active bend's balls
//! against the constant-curvature arc, a scripted contact against the paper's law, and a
//! guidewire in the catheter bending with the sum of their stiffnesses.

use super::{Case, Measured};
use crate::models::skeleton::catheter::{Catheter, CatheterParams, Drive};
use crate::models::skeleton::contact::ContactLaw;
use crate::models::skeleton::guidewire::{Guidewire, GuidewireParams, WireDrive, step_together};
use crate::models::skeleton::{Balls, LinearSpring, add_spring_forces, bending};
use glam::DVec3;

const MODEL: &str = "skeleton springs";

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "skeleton_hanging_chain",
            description: "the top spring of a chain of 10 balls of 2 g (100 N/m, 0.3 N s/m) \
                          hanging from a held ball, settled for 15 s, vs the weight it \
                          carries over k: 9 m g / k; tolerance 2 %",
            unit: "m",
            tolerance: 0.02,
            run: chain,
        },
        Case {
            model: MODEL,
            case: "skeleton_bend_arc",
            description: "the bent tip's last ball (7 balls over 30 mm, theta 45 deg, eqs \
                          11-16) from the arc's centre vs its radius L / (2 theta); \
                          tolerance 1e-9",
            unit: "m",
            tolerance: 1e-9,
            run: arc,
        },
        Case {
            model: MODEL,
            case: "skeleton_contact_law",
            description: "the normal force 2 mm deep moving in at 10 mm/s (k 500 N/m, c 0.3 \
                          N s/m, t 0.5 N) vs k D + c v + t (eq 9); tolerance 1e-12",
            unit: "N",
            tolerance: 1e-12,
            run: contact,
        },
        Case {
            model: MODEL,
            case: "skeleton_wire_in_catheter",
            description: "a guidewire (EI 2e-5 N m^2) in the catheter (k_t 0.005 N m/rad), \
                          both 100 mm in 5 mm segments, clamped and loaded with 80 uN at \
                          the catheter's tip, settled for 3 s: the tip's deflection vs the \
                          discrete cantilever's F lambda^2 sum(m^2) / (k_t,catheter + \
                          k_t,wire); tolerance 3 %",
            unit: "m",
            tolerance: 0.03,
            run: wire_in_catheter,
        },
    ]
}

/// The catheter with the wire in its lumen, both clamped (their first two balls behind the
/// entry) and the catheter's tip loaded, settled in a viscous bath (ten times each ball's
/// mass per second: it sets how fast they come to rest, not where).
fn wire_in_catheter() -> Measured {
    const LOAD_N: f64 = 8.0e-5;
    let (dt, steps) = (1.0e-4, 30_000);
    let cp = CatheterParams::default();
    let mut c = Catheter::new(&cp, DVec3::ZERO, DVec3::X);
    let (n, lambda) = (c.balls.len(), c.spacing_m());
    let wp = GuidewireParams {
        length_m: cp.length_m,
        spacing_m: lambda,
        tip_ei_n_m2: GuidewireParams::default().core_ei_n_m2,
        ..GuidewireParams::default()
    };
    let mut w = Guidewire::new(&wp, DVec3::ZERO, DVec3::X);
    let insertion_m = cp.length_m - 1.5 * lambda;
    let drive = Drive {
        insertion_m,
        ..Drive::default()
    };
    let wd = WireDrive {
        insertion_m,
        twist_rad: 0.0,
    };
    c.orient(&drive);
    w.orient(0.0);
    let bath = |b: &Balls, load: f64| -> Vec<DVec3> {
        let mut f: Vec<DVec3> =
            b.v.iter()
                .zip(&b.mass_kg)
                .map(|(v, m)| -*v * (10.0 * m))
                .collect();
        if let Some(tip) = f.last_mut() {
            *tip -= DVec3::Y * load;
        }
        f
    };
    for _ in 0..steps {
        let (fc, fw) = (bath(&c.balls, LOAD_N), bath(&w.balls, 0.0));
        step_together(&mut c, (&drive, &fc), &mut w, (&wd, &fw), dt);
    }
    let k_t = c.angles[0].stiffness_n_m_per_rad + w.angles[0].stiffness_n_m_per_rad;
    let sum: f64 = (1..=n - 2).map(|m| (m * m) as f64).sum();
    Measured {
        reference: LOAD_N * lambda * lambda * sum / k_t,
        measured: -c.tip().y,
        simulated_s: dt * steps as f64,
        floor: 0.0,
    }
}

fn chain() -> Measured {
    let (n, m, k, rest) = (10usize, 0.002, 100.0, 0.005);
    let mut balls = Balls::default();
    for i in 0..n {
        balls.push(DVec3::new(0.0, -rest * i as f64, 0.0), m, 0.001);
    }
    balls.fixed[0] = true;
    let springs: Vec<LinearSpring> = (0..n - 1)
        .map(|i| LinearSpring::between(&balls, i as u32, i as u32 + 1, k, 0.3))
        .collect();
    let dt = 1e-4;
    for _ in 0..150_000 {
        balls.start_forces(DVec3::new(0.0, -9.81, 0.0));
        add_spring_forces(&mut balls, &springs);
        balls.integrate(dt);
    }
    Measured {
        reference: (n - 1) as f64 * m * 9.81 / k,
        measured: balls.x[0].distance(balls.x[1]) - rest,
        simulated_s: 15.0,
        floor: 0.0,
    }
}

fn arc() -> Measured {
    let (n, l, theta) = (7, 0.03, 45f64.to_radians());
    let (_, _, r) = bending::arc(n, l, theta);
    let (dx, dy) = bending::offsets(n, l, theta)[n - 1];
    let y = dy + l;
    Measured::at_rest(r, ((dx - r).powi(2) + y * y).sqrt())
}

fn contact() -> Measured {
    let law = ContactLaw {
        stiffness_n_per_m: 500.0,
        damping_n_s_per_m: 0.3,
        preload_n: 0.5,
        friction: 0.1,
    };
    let f = law.force(0.002, DVec3::Y, DVec3::new(0.0, -0.01, 0.0));
    Measured::at_rest(500.0 * 0.002 + 0.3 * 0.01 + 0.5, f.normal.length())
}
