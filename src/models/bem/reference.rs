//! Reference cases of the boundary-element model, shared by its tests and `vesalius verify`:
//! Lamé's thick cylinder, a rigid translation, and the Prony relaxation of a held contact.

use super::contact::{Contacts, Prony};
use super::{Condition, Face, Known, Material, Problem, Sector};
use faer::Par;
use glam::DVec3;

fn quiet(_: &str, _: f64) {}

fn par() -> Par {
    Par::rayon(rayon::current_num_threads())
}

/// The cylinders' material (the esophagus's modulus; a compressible Poisson's ratio so that
/// the plane-strain solution is far from its incompressible limit).
pub const MATERIAL: Material = Material {
    young_pa: 5222.0,
    poisson: 0.3,
};

/// A tube of 6 mm inner and 10 mm outer radius, 8 mm long, or a sector of it.
pub fn tube(span_rad: f64, around: usize, through: usize, along: usize) -> Sector {
    Sector {
        inner_m: 0.006,
        outer_m: 0.010,
        length_m: 0.008,
        span_rad,
        around,
        through,
        along,
    }
}

/// A roller: the displacement along `axis` held at zero, the other tractions zero.
fn roller(axis: usize) -> Condition {
    let mut known = [Known::Traction; 3];
    known[axis] = Known::Displacement;
    Condition {
        known,
        value: DVec3::ZERO,
    }
}

/// A quarter of the thick cylinder in plane strain (rollers on its ends and cut faces)
/// under `pressure_pa` inside: the mean radial displacement of its inner and of its outer
/// wall's elements, `[(measured, Lamé), (measured, Lamé)]`, m, with Lamé's
/// `u_r = (1 + nu) P a^2 ((1 - 2 nu) r + b^2 / r) / (E (b^2 - a^2))` at each centroid's radius.
pub fn lame_cylinder(around: usize, through: usize, along: usize) -> Option<[(f64, f64); 2]> {
    let pressure = 4000.0;
    let t = tube(std::f64::consts::FRAC_PI_2, around, through, along);
    let s = t.surface();
    let elements = s.elements();
    let conditions = s
        .faces
        .iter()
        .zip(&elements)
        .map(|(f, e)| match f {
            Face::Inner => Condition::traction(-e.normal * pressure),
            Face::Outer => Condition::traction(DVec3::ZERO),
            Face::End(_) => roller(2),
            // theta = 0 is the plane y = 0; theta = pi/2 the plane x = 0.
            Face::Side(0) => roller(1),
            Face::Side(_) => roller(0),
        })
        .collect();
    let problem = Problem {
        elements: elements.clone(),
        material: MATERIAL,
        conditions,
    };
    let (sol, _) = problem.solve(par(), &quiet).ok()?;
    let (a, b, nu, e) = (t.inner_m, t.outer_m, MATERIAL.poisson, MATERIAL.young_pa);
    let lame = |r: f64| {
        (1.0 + nu) * pressure * a * a * ((1.0 - 2.0 * nu) * r + b * b / r) / (e * (b * b - a * a))
    };
    let mut out = [(0.0, 0.0); 2];
    for (slot, face) in [Face::Inner, Face::Outer].into_iter().enumerate() {
        let (mut got, mut want, mut count) = (0.0, 0.0, 0.0);
        for ((f, el), u) in s.faces.iter().zip(&elements).zip(&sol.displacement) {
            if *f != face {
                continue;
            }
            let radial = DVec3::new(el.centroid.x, el.centroid.y, 0.0);
            let r = radial.length();
            got += u.dot(radial / r);
            want += lame(r);
            count += 1.0;
        }
        out[slot] = (got / count, want / count);
    }
    Some(out)
}

/// A whole tube whose two ends are moved by `d` with nothing else pressing: the largest
/// displacement error over the elements relative to `|d|`, and the largest traction
/// relative to `E |d| / L`.
pub fn rigid_translation(d: DVec3) -> Option<(f64, f64)> {
    let t = tube(std::f64::consts::TAU, 16, 1, 6);
    let s = t.surface();
    let elements = s.elements();
    let conditions = s
        .faces
        .iter()
        .map(|f| match f {
            Face::End(_) => Condition {
                known: [Known::Displacement; 3],
                value: d,
            },
            _ => Condition::traction(DVec3::ZERO),
        })
        .collect();
    let problem = Problem {
        elements,
        material: MATERIAL,
        conditions,
    };
    let (sol, _) = problem.solve(par(), &quiet).ok()?;
    let worst_u = sol
        .displacement
        .iter()
        .map(|u| (*u - d).length())
        .fold(0.0f64, f64::max);
    let scale = MATERIAL.young_pa * d.length() / t.length_m;
    let worst_p = sol
        .traction
        .iter()
        .map(|p| p.length())
        .fold(0.0f64, f64::max);
    Some((worst_u / d.length(), worst_p / scale))
}

/// A small pressurised tube held at its ends, its outer wall the field.
pub fn pressurised_tube(poisson: f64) -> (Problem, Vec<usize>) {
    let s = Sector {
        inner_m: 0.006,
        outer_m: 0.010,
        length_m: 0.012,
        span_rad: std::f64::consts::TAU,
        around: 12,
        through: 1,
        along: 4,
    }
    .surface();
    let elements = s.elements();
    let conditions = s
        .faces
        .iter()
        .zip(&elements)
        .map(|(f, e)| match f {
            Face::End(_) => Condition::fixed(),
            Face::Inner => Condition::traction(-e.normal * 4000.0),
            _ => Condition::traction(DVec3::ZERO),
        })
        .collect();
    let field = s
        .faces
        .iter()
        .enumerate()
        .filter(|(_, f)| **f == Face::Outer)
        .map(|(k, _)| k)
        .collect();
    let problem = Problem {
        elements,
        material: Material {
            young_pa: 5222.0,
            poisson,
        },
        conditions,
    };
    (problem, field)
}

/// An element of the pressurised tube pushed 1 mm in and held for `hold_s` in steps of
/// `dt_s`: the force then over the force after the first step, and the Prony series'
/// `E(t) / E(dt)` at the same time.
pub fn prony_relaxation(prony: Prony, hold_s: f64, dt_s: f64) -> Option<(f64, f64)> {
    let (problem, field) = pressurised_tube(0.45);
    let pre = problem.precompute(&field, Par::Seq, &quiet).ok()?;
    let e = *field.get(7)?;
    let target = pre.solution(&problem).displacement[e] + DVec3::new(0.0, 0.0, -0.001);
    let mut contacts = Contacts::new(pre, &problem.elements, Some(prony));
    contacts.set_contacts(&[e]).ok()?;
    let first = contacts.update(&[target], dt_s).ok()?.length();
    let steps = (hold_s / dt_s).round() as usize;
    let mut f = first;
    for _ in 1..steps {
        f = contacts.update(&[target], dt_s).ok()?.length();
    }
    let t = steps as f64 * dt_s;
    Some((f / first, prony.relaxation(t) / prony.relaxation(dt_s)))
}
