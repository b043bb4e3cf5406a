//! Cases for the boundary-element model (`crate::models::bem`, the myotomy paper's eqs 1-2
//! with James and Pai's contact update): Lamé's thick cylinder, a rigid translation, the
//! capacitance update against a full solve, and the Prony relaxation of a held contact.

use super::{Case, Measured};
use crate::models::bem::contact::{Contacts, Prony};
use crate::models::bem::reference::{lame_cylinder, pressurised_tube, rigid_translation};
use crate::models::bem::{Condition, Known};
use faer::Par;
use glam::DVec3;

const MODEL: &str = "boundary elements";

/// The myotomy paper's relaxation (tau 6.372 s, g1 0.363).
pub const PAPER_PRONY: Prony = Prony {
    g1: 0.363,
    tau_s: 6.372,
};

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "bem_lame_inner",
            description: "mean radial displacement of the inner wall of a thick cylinder (a 6 mm, \
                          b 10 mm, E 5222 Pa, nu 0.3) in plane strain under 4 kPa inside, a \
                          quarter on rollers, 272 constant elements, vs Lame's solution; \
                          tolerance 5 %",
            unit: "m",
            tolerance: 0.05,
            run: || lame(0),
        },
        Case {
            model: MODEL,
            case: "bem_lame_outer",
            description: "the same cylinder's outer wall vs Lame's solution; tolerance 5 %",
            unit: "m",
            tolerance: 0.05,
            run: || lame(1),
        },
        Case {
            model: MODEL,
            case: "bem_rigid_translation",
            description: "a free tube whose ends are moved by 1.14 mm: the largest displacement \
                          error over its elements (reference 0, relative to the translation) \
                          and no traction; tolerance 1 %",
            unit: "",
            tolerance: 0.01,
            run: rigid,
        },
        Case {
            model: MODEL,
            case: "bem_capacitance",
            description: "force on two outer elements held 2 mm in by the capacitance update \
                          (precomputed responses) vs a full solve with their displacements \
                          prescribed; tolerance 1e-6",
            unit: "N",
            tolerance: 1e-6,
            run: capacitance,
        },
        Case {
            model: MODEL,
            case: "bem_prony_tau",
            description: "force of a held 1 mm indentation after tau = 6.372 s over its first \
                          step's (1 ms steps) vs the paper's Prony series 1 - g1 (1 - e^-1), \
                          g1 0.363; tolerance 2 %",
            unit: "",
            tolerance: 0.02,
            run: prony,
        },
    ]
}

fn lame(wall: usize) -> Measured {
    match lame_cylinder(8, 3, 4) {
        Some(w) => Measured::at_rest(w[wall].1, w[wall].0),
        None => Measured::not_run(1.0),
    }
}

fn rigid() -> Measured {
    match rigid_translation(DVec3::new(0.001, -0.0005, 0.0002)) {
        Some((du, dp)) => Measured {
            reference: 0.0,
            measured: du.max(dp),
            simulated_s: 0.0,
            floor: 1.0,
        },
        None => Measured::not_run(0.0),
    }
}

fn capacitance() -> Measured {
    let quiet = |_: &str, _: f64| {};
    let (p, field) = pressurised_tube(0.45);
    let Ok(pre) = p.precompute(&field, Par::Seq, &quiet) else {
        return Measured::not_run(1.0);
    };
    let base = pre.solution(&p);
    let held = [field[3], field[10]];
    let targets = [
        base.displacement[held[0]] + DVec3::new(0.0, -0.002, 0.0),
        base.displacement[held[1]] + DVec3::new(0.0, -0.002, 0.0),
    ];
    let mut contacts = Contacts::new(pre, &p.elements, None);
    let force = contacts
        .set_contacts(&held)
        .and_then(|_| contacts.update(&targets, 0.001));
    let mut direct = p.clone();
    for (&e, t) in held.iter().zip(&targets) {
        direct.conditions[e] = Condition {
            known: [Known::Displacement; 3],
            value: *t,
        };
    }
    match (force, direct.solve(Par::Seq, &quiet)) {
        (Ok(f), Ok((sol, _))) => {
            let want: DVec3 = held
                .iter()
                .map(|&e| sol.traction[e] * p.elements[e].area_m2)
                .sum();
            Measured::at_rest(want.length(), f.length())
        }
        _ => Measured::not_run(1.0),
    }
}

fn prony() -> Measured {
    let dt = 0.001;
    match crate::models::bem::reference::prony_relaxation(PAPER_PRONY, PAPER_PRONY.tau_s, dt) {
        Some((got, want)) => Measured {
            reference: want,
            measured: got,
            simulated_s: PAPER_PRONY.tau_s,
            floor: 0.0,
        },
        None => Measured::not_run(1.0),
    }
}
