//! Triangle meshes: the render triangulation, its adjacency, and deterministic organ generators.

pub mod block;
mod generate;
pub mod gltf;
pub mod obj;
mod solid;
mod trimesh;

pub use generate::{KidneyShape, TubeSpec, icosphere, kidney, tube};
pub use gltf::GltfError;
pub use obj::ObjError;
pub use solid::Solid;
pub use trimesh::{MeshError, TriMesh};

/// Area-weighted vertex normals of a triangle list (`indices` into `positions`); a vertex
/// on no triangle (or only degenerate ones) gets +y.
pub fn vertex_normals(positions: &[glam::Vec3], indices: &[u32]) -> Vec<glam::Vec3> {
    let mut n = vec![glam::Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|k| k as usize);
        let f = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        for k in [a, b, c] {
            n[k] += f;
        }
    }
    n.iter().map(|v| v.normalize_or(glam::Vec3::Y)).collect()
}
