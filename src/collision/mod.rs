//! Collision queries between instruments and tissue surfaces. Detection produces contacts and
//! hits; the models consume them.

mod collider;
mod face_bvh;
mod point_blocks;
mod primitives;
mod ray_mesh;
mod sphere_vertices;
mod tool_cylinder;

pub use collider::{Collider, MeshSurface, TriangleSource};
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

/// What the collision tests share.
#[cfg(test)]
pub(crate) mod test_support {
    /// A fixed-seed generator of numbers in [0, 1) (Knuth's MMIX linear congruential
    /// generator, top 24 bits).
    pub struct Lcg(pub u64);

    impl Lcg {
        pub fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }

        /// Uniform in [lo, hi).
        pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.next()
        }
    }
}
