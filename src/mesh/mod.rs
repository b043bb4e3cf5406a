//! Triangle meshes: the render triangulation, its adjacency, and deterministic organ generators.

mod generate;
pub mod gltf;
pub mod obj;
mod trimesh;

pub use generate::{KidneyShape, TubeSpec, icosphere, kidney, tube};
pub use gltf::GltfError;
pub use obj::ObjError;
pub use trimesh::{MeshError, TriMesh};
