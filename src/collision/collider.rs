//! What tools, rays, cutting and rendering see of a model, whatever the model is: a collider.
//! A deforming triangle surface with its BVH (soft bodies), a set of spheres (mass-spring and
//! shape-matching clusters), capsules (shafts, jaws) or a generalized cylinder (rods and
//! tubes: a centreline with a radius per point). Every answer names a *feature*: a face,
//! a sphere, a capsule or a centreline segment, with the region the model gave it.

use super::{
    CapsuleSet, FaceBvh, GeneralizedCylinder, PrimitiveHit, RayHit, SphereSet, cast_ray,
    nearest_within,
};
use glam::Vec3;

/// Where each face of a deforming triangle surface is now.
pub trait TriangleSource: Sync {
    /// The corners of face `f`, metres, counter-clockwise seen from outside.
    fn triangle(&self, f: u32) -> [Vec3; 3];
}

/// A deforming triangle surface: one feature per face.
pub struct MeshSurface<'a> {
    pub triangles: &'a dyn TriangleSource,
    /// One point per face (its centre, or the simplex point it is dual to), metres: what
    /// "near" is measured from.
    pub points: &'a [Vec3],
    /// Faces still present (cut faces are gone).
    pub alive: &'a [bool],
    /// Region per face (names are the model's).
    pub regions: &'a [u8],
    /// BVH over the faces, refit as they move.
    pub bvh: &'a FaceBvh,
}

impl MeshSurface<'_> {
    pub fn triangle(&self, f: u32) -> [Vec3; 3] {
        self.triangles.triangle(f)
    }
}

/// A model's surface as collision sees it. A primitive set's regions hold one entry per
/// feature; an empty slice puts every feature in region 0.
pub enum Collider<'a> {
    Mesh(MeshSurface<'a>),
    Spheres(SphereSet<'a>, &'a [u8]),
    Capsules(CapsuleSet<'a>, &'a [u8]),
    Tube(GeneralizedCylinder<'a>, &'a [u8]),
}

impl Collider<'static> {
    /// Nothing rays or tools meet: a model whose owner brings the instruments to it in its
    /// own terms (tips pressing boundary elements, penalties on a grid's nodes).
    pub fn none() -> Self {
        Collider::Spheres(
            SphereSet {
                centers: &[],
                radii: &[],
            },
            &[],
        )
    }
}

fn from_primitive(h: PrimitiveHit) -> RayHit {
    RayHit {
        feature: h.feature,
        distance_m: h.distance_m,
        point: h.point,
        normal: h.normal,
    }
}

impl Collider<'_> {
    /// The first feature a ray from `origin` along unit `dir` meets within `max_m`.
    pub fn cast_ray(&self, origin: Vec3, dir: Vec3, max_m: f32) -> Option<RayHit> {
        match self {
            Collider::Mesh(m) => cast_ray(m, origin, dir, max_m),
            Collider::Spheres(s, _) => s.cast_ray(origin, dir, max_m).map(from_primitive),
            Collider::Capsules(c, _) => c.cast_ray(origin, dir, max_m).map(from_primitive),
            Collider::Tube(t, _) => t.cast_ray(origin, dir, max_m).map(from_primitive),
        }
    }

    /// Features within `radius_m` of `center`, nearest first (ties by feature id), with their
    /// distance, metres: from a face's point for a mesh, from the surface for primitives.
    pub fn nearest_within(&self, center: Vec3, radius_m: f32) -> Vec<(f32, u32)> {
        match self {
            Collider::Mesh(m) => nearest_within(m, center, radius_m),
            Collider::Spheres(s, _) => s.nearest_within(center, radius_m),
            Collider::Capsules(c, _) => c.nearest_within(center, radius_m),
            Collider::Tube(t, _) => t.nearest_within(center, radius_m),
        }
    }

    /// The region of `feature` (0 where the model gave none).
    pub fn region(&self, feature: u32) -> u8 {
        let regions = match self {
            Collider::Mesh(m) => m.regions,
            Collider::Spheres(_, r) | Collider::Capsules(_, r) | Collider::Tube(_, r) => r,
        };
        regions.get(feature as usize).copied().unwrap_or(0)
    }

    /// How many features there are (ids `0..feature_count()`).
    pub fn feature_count(&self) -> usize {
        match self {
            Collider::Mesh(m) => m.points.len(),
            Collider::Spheres(s, _) => s.feature_count(),
            Collider::Capsules(c, _) => c.feature_count(),
            Collider::Tube(t, _) => t.feature_count(),
        }
    }
}
