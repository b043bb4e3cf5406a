use crate::sim::MeshSurface;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::icosphere;
    use crate::models::{SimplexMesh, SoftBody, SoftBodyParams};
    use crate::sim::TissueModel;

    #[test]
    fn ray_hits_the_near_side_of_a_sphere_at_its_radius() {
        let mut m = icosphere(3);
        for p in &mut m.positions {
            *p *= 0.05;
        }
        let s = SimplexMesh::dual(&m).expect("dual");
        let n = s.len();
        let body = SoftBody::new("ball", s, vec![0; n], SoftBodyParams::default());
        let view = body.collider();
        let hit = view
            .cast_ray(Vec3::new(0.0, 0.0, 0.2), Vec3::NEG_Z, 1.0)
            .expect("hit");
        // The flat facets sit just inside the sphere: 0.15 m to 0.1503 m away.
        assert!(
            hit.distance_m > 0.1495 && hit.distance_m < 0.151,
            "{}",
            hit.distance_m
        );
        assert!(hit.normal.z > 0.9);
        assert!(
            view.cast_ray(Vec3::new(0.0, 0.2, 0.2), Vec3::NEG_Z, 1.0)
                .is_none()
        );
    }
}
