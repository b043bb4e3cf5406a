//! Triangle meshes: the render triangulation, its adjacency, and deterministic organ generators.

mod generate;
mod trimesh;

pub use generate::{KidneyShape, TubeSpec, icosphere, kidney, tube};
pub use trimesh::{MeshError, TriMesh};
