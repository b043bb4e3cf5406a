//! Cases for ray casting against a tissue surface (`crate::collision::cast_ray`).
//!
//! The surface is a sphere of radius 5 cm tessellated as an icosphere of level 3, seen
//! through a soft body at rest (render triangles mapped back from its simplex mesh). Its flat
//! facets lie inside the sphere by at most the chord sag, so a ray meets a facet a little
//! later than it would meet the sphere. Each case's tolerance is that lateness at the
//! largest sag of the mesh, computed from the mesh when the cases are listed, plus 2 um for
//! the simplex-to-render mapping and f32 rounding, over the distance to the sphere.

use super::{Case, Measured};
use crate::mesh::{TriMesh, icosphere};
use crate::models::{SimplexMesh, SoftBody, SoftBodyParams};
use crate::sim::TissueModel;
use glam::DVec3;

const MODEL: &str = "ray-mesh";
const RADIUS_M: f64 = 0.05;
const LEVEL: u32 = 3;
/// The render vertices are rebuilt from the simplex points to about 1e-6 m, and the ray
/// arithmetic in f32 at 0.2 m adds about 1e-7 m: allow 2e-6 m.
const SLACK_M: f64 = 2e-6;

/// A ray: origin and (unit) direction, metres.
struct Ray {
    origin: DVec3,
    dir: DVec3,
}

fn axis_ray() -> Ray {
    Ray {
        origin: DVec3::new(0.0, 0.0, 0.2),
        dir: DVec3::NEG_Z,
    }
}

fn oblique_ray() -> Ray {
    // Through the centre from a direction that lines up with no vertex or face.
    let from = DVec3::new(1.0, 2.0, 3.0).normalize();
    Ray {
        origin: from * 0.2,
        dir: -from,
    }
}

fn off_centre_ray() -> Ray {
    // Parallel to the axis, 0.6 R off it: meets the sphere 37 degrees from head-on.
    Ray {
        origin: DVec3::new(0.6 * RADIUS_M, 0.0, 0.2),
        dir: DVec3::NEG_Z,
    }
}

pub(super) fn cases() -> Vec<Case> {
    let sag_m = max_chord_sag_m(&sphere_mesh());
    let tolerance = |ray: Ray| tolerance_for(&ray, sag_m);
    vec![
        Case {
            model: MODEL,
            case: "ray_sphere_axis",
            description: "ray down the z axis from 20 cm vs sphere geometry |o - c| - r = 15 cm \
                          (the pole is a mesh vertex, so on the sphere); tolerance: facet \
                          lateness at the icosphere's largest chord sag",
            unit: "m",
            tolerance: tolerance(axis_ray()),
            run: ray_sphere_axis,
        },
        Case {
            model: MODEL,
            case: "ray_sphere_oblique",
            description: "ray toward the centre from 20 cm along (1,2,3) vs |o - c| - r = 15 cm; \
                          tolerance: facet lateness at the largest chord sag",
            unit: "m",
            tolerance: tolerance(oblique_ray()),
            run: ray_sphere_oblique,
        },
        Case {
            model: MODEL,
            case: "ray_sphere_off_centre",
            description: "ray parallel to the axis 0.6 r off it vs z0 - sqrt(r^2 - b^2) = 16 cm; \
                          tolerance: lateness at the largest sag along a ray 37 deg off the normal",
            unit: "m",
            tolerance: tolerance(off_centre_ray()),
            run: ray_sphere_off_centre,
        },
    ]
}

fn sphere_mesh() -> TriMesh {
    let mut m = icosphere(LEVEL);
    for p in &mut m.positions {
        *p *= RADIUS_M as f32;
    }
    m
}

/// The largest depth of a facet inside the sphere: r minus the smallest distance from the
/// centre to a triangle's plane (the triangles' vertices lie on the sphere).
fn max_chord_sag_m(m: &TriMesh) -> f64 {
    let nearest_plane_m = m
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| m.positions[i as usize].as_dvec3());
            (b - a).cross(c - a).normalize().dot(a).abs()
        })
        .fold(f64::INFINITY, f64::min);
    RADIUS_M - nearest_plane_m
}

/// Distance along the ray to the sphere of radius `rho` about the origin (near side), or NaN
/// when the ray misses it.
fn distance_to_sphere_m(ray: &Ray, rho: f64) -> f64 {
    let b = ray.origin.dot(ray.dir);
    let disc = b * b - ray.origin.length_squared() + rho * rho;
    if disc < 0.0 {
        return f64::NAN;
    }
    -b - disc.sqrt()
}

/// A facet hit lies between the sphere of radius r and the one of radius r - sag, so the
/// hit comes at most (distance to r - sag) - (distance to r) late.
fn tolerance_for(ray: &Ray, sag_m: f64) -> f64 {
    let exact = distance_to_sphere_m(ray, RADIUS_M);
    let late = distance_to_sphere_m(ray, RADIUS_M - sag_m) - exact;
    (late + SLACK_M) / exact
}

fn cast(ray: &Ray) -> Measured {
    let reference = distance_to_sphere_m(ray, RADIUS_M);
    let m = sphere_mesh();
    let Ok(s) = SimplexMesh::dual(&m) else {
        return Measured::not_run(reference);
    };
    let n = s.len();
    let body = SoftBody::new("sphere", s, vec![0; n], SoftBodyParams::default());
    let hit = body
        .collider()
        .cast_ray(ray.origin.as_vec3(), ray.dir.as_vec3().normalize(), 1.0);
    let measured = hit.map_or(f64::NAN, |h| h.distance_m as f64);
    Measured::at_rest(reference, measured)
}

fn ray_sphere_axis() -> Measured {
    cast(&axis_ray())
}

fn ray_sphere_oblique() -> Measured {
    cast(&oblique_ray())
}

fn ray_sphere_off_centre() -> Measured {
    cast(&off_centre_ray())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sag_is_that_of_a_level_3_icosphere() {
        // Edges of a level-3 icosphere subtend about 0.13 rad: sag ~ r (1 - cos(0.075)).
        let sag = max_chord_sag_m(&sphere_mesh());
        assert!(sag > 1e-4 && sag < 3e-4, "{sag}");
    }
}
