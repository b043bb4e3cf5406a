//! Collision queries between instruments and tissue surfaces. Detection produces contacts and
//! hits; the models consume them.

mod face_bvh;
mod point_blocks;
mod primitives;
mod ray_mesh;
mod sphere_vertices;
mod tool_cylinder;

pub use face_bvh::{FaceBvh, PATCH_FACES};
pub use point_blocks::{BLOCK_POINTS, PointBlocks, PointCloud};
pub use primitives::{
    CapsuleSet, GeneralizedCylinder, PrimitiveError, PrimitiveHit, SphereSet, SurfaceContact,
};
pub use ray_mesh::{RayHit, cast_ray};
pub use sphere_vertices::nearest_within;
pub use tool_cylinder::{
    Instrument, QueryStats, ToolContact, ToolCylinder, ToolError, ToolReaction, VertexAreas,
    penalty_forces, tip_contacts,
};
