//! Cases for the skeleton-spring model (`crate::models::skeleton`, the catheter paper's eqs
//! 1-16): a hanging chain's springs against the weight they carry, the active bend's balls
//! against the constant-curvature arc, and a scripted contact against the paper's law.

use super::{Case, Measured};
use crate::models::skeleton::contact::ContactLaw;
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
    ]
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
