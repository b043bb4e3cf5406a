//! Cases for the force terms of the soft body (`crate::models::forces`, paper eqs 1-8).
//!
//! The force functions are evaluated in f32; each reference is worked out in f64 from the
//! equation by hand. Unless a case says otherwise its tolerance is 1e-6: a handful of f32
//! operations, each rounding by at most 2^-24 (6e-8) relative.

use super::{Case, Measured};
use crate::models::forces;
use glam::Vec3;

const MODEL: &str = "forces";

/// A few f32 roundings (2^-24 each), with room to spare.
const F32_FEW_OPS: f64 = 1e-6;

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "spring_hooke",
            description: "spring force toward rest vs Hooke k |x0 - x| (eq 1/2 spring term), \
                          k = 40 N/m, 13 mm off-axis (3,-4,12) mm",
            unit: "N",
            tolerance: F32_FEW_OPS,
            run: spring_hooke,
        },
        Case {
            model: MODEL,
            case: "pressure_area_eq4",
            description: "pressure force along the normal vs P dA (eqs 3-4), \
                          1500 Pa on 1 cm^2, normal (1,2,2)/3",
            unit: "N",
            tolerance: F32_FEW_OPS,
            run: pressure_area_eq4,
        },
        Case {
            model: MODEL,
            case: "falloff_half_at_one_length",
            description: "contact falloff at d = l vs F / 2 (eq 6: F / (1 + d^2), d in falloff \
                          lengths), F = 2 N, l = 6 mm",
            unit: "N",
            tolerance: F32_FEW_OPS,
            run: falloff_half,
        },
        Case {
            model: MODEL,
            case: "falloff_fifth_at_two_lengths",
            description: "contact falloff at d = 2 l vs F / 5 (eq 6), F = 2 N, l = 6 mm",
            unit: "N",
            tolerance: F32_FEW_OPS,
            run: falloff_fifth,
        },
        Case {
            model: MODEL,
            case: "contact_force_normal_share",
            description: "contact force on a vertex 2 mm beside the contact, along its normal, \
                          vs -F / (1 + 8) cos 45 deg (eq 6 from the point lifted 2 mm, l = 1 mm)",
            unit: "N",
            tolerance: F32_FEW_OPS,
            run: contact_force_normal_share,
        },
        Case {
            model: MODEL,
            case: "volume_pressure_compressed",
            description: "gas pressure of a body squeezed to 97 % of its rest volume vs \
                          k_v (V0 - V) / V0 = +60 Pa (k_v = 2000 Pa); tolerance 1e-5 from the \
                          f32 cancellation in V0 - V (ulp(V0) / 0.03 V0 = 4e-6)",
            unit: "Pa",
            tolerance: 1e-5,
            run: volume_pressure_compressed,
        },
        Case {
            model: MODEL,
            case: "volume_pressure_expanded",
            description: "gas pressure of a body swollen to 102 % of its rest volume vs \
                          k_v (V0 - V) / V0 = -40 Pa (pulls in); tolerance as for compressed",
            unit: "Pa",
            tolerance: 1e-5,
            run: volume_pressure_expanded,
        },
        Case {
            model: MODEL,
            case: "drag_terminal_velocity",
            description: "unit mass under a constant 1 N with damping 8 /s stepped 0.5 s \
                          (eqs 7, 5, 8) vs the closed form of that recurrence, \
                          v_n = F a h (1 - a^n) / (1 - a), a = 1 - d h; tolerance 1e-5 for \
                          250 steps of f32 rounding",
            unit: "m/s",
            tolerance: 1e-5,
            run: drag_terminal_velocity,
        },
    ]
}

fn spring_hooke() -> Measured {
    let k_n_per_m = 40.0f32;
    let rest = Vec3::new(0.01, 0.02, -0.005);
    let offset_m = [0.003, -0.004, 0.012];
    let x = rest + Vec3::from_array(offset_m.map(|c| c as f32));
    let f = forces::spring_force(k_n_per_m, x, rest);
    // Hooke: |F| = k |x - x0|, here 40 * 0.013 = 0.52 N; measured as the component of the
    // force toward rest, so a wrongly directed force shows up too.
    let distance_m = offset_m.iter().map(|c| c * c).sum::<f64>().sqrt();
    let toward_rest = (rest - x).normalize();
    Measured::at_rest(40.0 * distance_m, f.dot(toward_rest) as f64)
}

fn pressure_area_eq4() -> Measured {
    let normal = Vec3::new(1.0, 2.0, 2.0) / 3.0;
    let f = forces::pressure_force(1500.0, normal, 1e-4);
    // Eq 4: F = P dA = 1500 Pa * 1e-4 m^2 = 0.15 N along n.
    Measured::at_rest(0.15, f.dot(normal) as f64)
}

fn falloff_half() -> Measured {
    Measured::at_rest(1.0, forces::falloff(2.0, 0.006, 0.006) as f64)
}

fn falloff_fifth() -> Measured {
    Measured::at_rest(0.4, forces::falloff(2.0, 0.012, 0.006) as f64)
}

fn contact_force_normal_share() -> Measured {
    // Surface z = 0 (normal +z), contact at the origin lifted 2 mm: the force comes from
    // (0, 0, 2 mm). A vertex 2 mm aside is sqrt(8) mm away, 2.83 falloff lengths of 1 mm:
    // |F_v| = 0.3 / (1 + 8) N, directed 45 degrees into the surface.
    let from = forces::offset_point(Vec3::ZERO, Vec3::Z, 0.002);
    let c = forces::contact_force(Vec3::new(0.002, 0.0, 0.0), Vec3::Z, from, 0.3, 0.001);
    let reference = -0.3 / 9.0 * std::f64::consts::FRAC_1_SQRT_2;
    Measured::at_rest(reference, c.pressure.dot(Vec3::Z) as f64)
}

/// Rest volume of a 3 cm sphere, m^3.
const REST_VOLUME_M3: f32 = 1.131e-4;

fn volume_pressure_compressed() -> Measured {
    let p = forces::volume_pressure(2000.0, REST_VOLUME_M3, 0.97 * REST_VOLUME_M3);
    Measured::at_rest(2000.0 * 0.03, p as f64)
}

fn volume_pressure_expanded() -> Measured {
    let p = forces::volume_pressure(2000.0, REST_VOLUME_M3, 1.02 * REST_VOLUME_M3);
    Measured::at_rest(-2000.0 * 0.02, p as f64)
}

fn drag_terminal_velocity() -> Measured {
    let (force_n, damping_per_s, dt_s, steps) = (1.0f32, 8.0f32, 0.002f32, 250);
    let (mut x, mut v) = (Vec3::ZERO, Vec3::ZERO);
    for _ in 0..steps {
        (x, v) = forces::integrate(x, v, Vec3::X * force_n, damping_per_s, dt_s);
    }
    // v_{n+1} = (v_n + F h) a: a geometric series summing to F a h (1 - a^n) / (1 - a),
    // which tends to the terminal velocity F a / d (drag m d v balancing F).
    let (f, d, h) = (1.0f64, 8.0f64, 0.002f64);
    let a = 1.0 - d * h;
    let reference = f * a * h * (1.0 - a.powi(steps)) / (1.0 - a);
    Measured {
        reference,
        measured: v.x as f64,
        simulated_s: steps as f64 * h,
        floor: 0.0,
    }
}
