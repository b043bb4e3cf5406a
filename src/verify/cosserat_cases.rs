//! Cases for the Cosserat rod (`crate::models::cosserat`, the rectum paper's appendix A): a
//! cantilever under its own weight in the linear regime and far outside it, and pure torsion.

use super::{Case, Measured};
use crate::models::cosserat::reference::{
    Cantilever, heavy_params, reference_for, settled_cantilever,
};
use crate::models::cosserat::{CosseratRod, RodParams, so3};
use glam::DVec3;

const MODEL: &str = "cosserat rod";

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "rod_cantilever_linear",
            description: "tip drop of a clamped rod under its own weight (L 0.2 m, r 10 mm, E 1e7 \
                          Pa, 1000 kg/m^3, 40 elements, q L^3 / EI = 0.31), settled, vs the \
                          linear beam q L^4 / (8 E I); tolerance 5 % (the beam's own shear adds \
                          0.7 %)",
            unit: "m",
            tolerance: 0.05,
            run: cantilever_linear,
        },
        Case {
            model: MODEL,
            case: "rod_cantilever_heavy",
            description: "tip drop of the heavy cantilever (E 1e5 Pa, L 0.2 m, r 10 mm, 1000 \
                          kg/m^3, 200 elements, q L^3 / EI = 31.4), settled from straight by \
                          backward Euler at 5 ms, vs the Reissner elastica (stretch and shear as \
                          the rod's) solved by shooting; tolerance 2 %",
            unit: "m",
            tolerance: 0.02,
            run: cantilever_heavy,
        },
        Case {
            model: MODEL,
            case: "rod_torsion",
            description: "twist of a clamped rod (L 0.2 m, r 10 mm, G 3.3e4 Pa, 100 elements) \
                          under a torque of 1e-4 N m at its free end, vs T L / (G J); tolerance \
                          5 %",
            unit: "rad",
            tolerance: 0.05,
            run: torsion,
        },
    ]
}

fn cantilever_linear() -> Measured {
    let params = RodParams {
        youngs_modulus_pa: 1e7,
        ..heavy_params()
    };
    let (length, n, dt) = (0.2, 40, 2e-3);
    let (rod, t) = settled_cantilever(params, n, length, dt, 1e-6, 20.0);
    let r: Cantilever = reference_for(&params, length);
    Measured {
        reference: r.load_n_per_m * length.powi(4) / (8.0 * r.bend_n_m2),
        measured: -rod.positions()[n].y,
        simulated_s: t,
        floor: 0.0,
    }
}

fn cantilever_heavy() -> Measured {
    let params = heavy_params();
    let (length, n) = (0.2, 200);
    let (rod, t) = settled_cantilever(params, n, length, 5e-3, 1e-6, 30.0);
    Measured {
        reference: reference_for(&params, length).tip_drop(),
        measured: -rod.positions()[n].y,
        simulated_s: t,
        floor: 0.0,
    }
}

fn torsion() -> Measured {
    let params = RodParams {
        gravity: DVec3::ZERO,
        ..heavy_params()
    };
    let (length, n, dt, torque) = (0.2, 100, 5e-3, 1e-4);
    let mut rod = CosseratRod::straight(n, length, DVec3::ZERO, DVec3::X, params);
    rod.fix_node(0, true);
    let clamp = rod.frames()[0];
    let steps = 400;
    for _ in 0..steps {
        rod.add_torque(n - 1, DVec3::X * torque);
        rod.step(dt);
    }
    let twist = so3::log(rod.frames()[n - 1] * clamp.transpose()).x;
    let (_, _, j) = params.section();
    Measured {
        reference: torque * length / (params.shear_modulus_pa() * j),
        measured: twist,
        simulated_s: steps as f64 * dt,
        floor: 0.0,
    }
}
