use super::MeshSurface;
use glam::Vec3;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::Triangle;

/// Where a ray met a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// The feature hit: a face of a mesh, a sphere, a capsule or a centreline segment.
    pub feature: u32,
    /// Distance along the (unit) ray, metres.
    pub distance_m: f32,
    pub point: Vec3,
    /// Outward normal of the face hit.
    pub normal: Vec3,
}

/// Casts a ray (unit `dir`) against the live render triangles of a surface, using the
/// surface's BVH to find candidates and parry's ray-triangle test on each.
pub fn cast_ray(surface: &MeshSurface, origin: Vec3, dir: Vec3, max_m: f32) -> Option<RayHit> {
    let ray = Ray::new(origin, dir);
    let (face, toi) = surface.bvh.cast_ray(&ray, max_m, |f, best| {
        if !surface.alive[f as usize] {
            return None;
        }
        let [a, b, c] = surface.triangle(f);
        Triangle::new(a, b, c).cast_local_ray(&ray, best, true)
    })?;
    let [a, b, c] = surface.triangle(face);
    let normal = (b - a).cross(c - a).normalize_or_zero();
    Some(RayHit {
        feature: face,
        distance_m: toi,
        point: origin + dir * toi,
        normal,
    })
}
