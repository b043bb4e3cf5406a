//! Tissue models. Each implements [`crate::sim::TissueModel`].

pub mod bem;
pub mod cosserat;
pub mod forces;
pub mod membrane;
pub mod particles;
mod simplex;
pub mod skeleton;
mod softbody;
pub mod xpbd;

pub use simplex::{RenderVertex, SimplexMesh};
pub use softbody::{Fnv, SoftBody, SoftBodyParams, Tie, Tuning};

#[cfg(test)]
mod world_tests;
