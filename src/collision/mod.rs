//! Collision queries between instruments and tissue surfaces. Detection produces contacts and
//! hits; the models consume them.

mod face_bvh;
mod primitives;
mod ray_mesh;
mod sphere_vertices;

pub use face_bvh::{FaceBvh, PATCH_FACES};
pub use primitives::{
    CapsuleSet, GeneralizedCylinder, PrimitiveError, PrimitiveHit, SphereSet, SurfaceContact,
};
pub use ray_mesh::{RayHit, cast_ray};
pub use sphere_vertices::nearest_within;
