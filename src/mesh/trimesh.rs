use glam::Vec3;
use std::collections::HashMap;

/// Topology problems that make a mesh unusable as a closed simplex-mesh surface.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("edge ({0}, {1}) is shared by {2} triangles; a closed surface needs exactly 2")]
    NonManifoldEdge(u32, u32, usize),
    #[error("triangle {0} refers to vertex {1}, but the mesh has {2} vertices")]
    BadIndex(usize, u32, usize),
    #[error("triangle {0} is degenerate (repeated vertex or zero area)")]
    Degenerate(usize),
    #[error("vertex {0} has an open or pinched fan of triangles")]
    BadFan(u32),
    #[error("vertex {0} is shared by {1} triangles; at most 65535 are supported")]
    CrowdedVertex(usize, usize),
}

/// An indexed triangle mesh, counter-clockwise (outward) winding. Positions in metres.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    pub fn triangle_area(&self, f: usize) -> f32 {
        let [a, b, c] = self.triangles[f].map(|i| self.positions[i as usize]);
        0.5 * (b - a).cross(c - a).length()
    }

    pub fn area(&self) -> f32 {
        (0..self.triangles.len())
            .map(|f| self.triangle_area(f))
            .sum()
    }

    /// Signed volume enclosed (divergence theorem); positive for outward winding.
    pub fn volume(&self) -> f32 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Checks indices and area of every triangle.
    pub fn validate(&self) -> Result<(), MeshError> {
        let n = self.positions.len();
        for (f, t) in self.triangles.iter().enumerate() {
            for &i in t {
                if i as usize >= n {
                    return Err(MeshError::BadIndex(f, i, n));
                }
            }
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || self.triangle_area(f) <= 0.0 {
                return Err(MeshError::Degenerate(f));
            }
        }
        Ok(())
    }

    /// For each triangle, the triangle across each of its edges; edge k runs from corner k to
    /// corner k+1. Fails unless every edge has exactly two triangles (closed 2-manifold).
    pub fn edge_adjacency(&self) -> Result<Vec<[u32; 3]>, MeshError> {
        self.validate()?;
        let mut owners: HashMap<(u32, u32), Vec<(u32, u8)>> =
            HashMap::with_capacity(self.triangles.len() * 2);
        for (f, t) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                owners
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((f as u32, k as u8));
            }
        }
        let mut adj = vec![[u32::MAX; 3]; self.triangles.len()];
        for (&(a, b), list) in &owners {
            if list.len() != 2 {
                return Err(MeshError::NonManifoldEdge(a, b, list.len()));
            }
            let (f0, k0) = list[0];
            let (f1, k1) = list[1];
            adj[f0 as usize][k0 as usize] = f1;
            adj[f1 as usize][k1 as usize] = f0;
        }
        Ok(adj)
    }

    /// The triangles around each vertex in counter-clockwise order (seen from outside).
    pub fn vertex_fans(&self, adj: &[[u32; 3]]) -> Result<Vec<Vec<u32>>, MeshError> {
        let mut first: Vec<u32> = vec![u32::MAX; self.positions.len()];
        let mut count = vec![0usize; self.positions.len()];
        for (f, t) in self.triangles.iter().enumerate() {
            for &v in t {
                if first[v as usize] == u32::MAX {
                    first[v as usize] = f as u32;
                }
                count[v as usize] += 1;
            }
        }
        let mut fans = Vec::with_capacity(self.positions.len());
        for v in 0..self.positions.len() as u32 {
            let start = first[v as usize];
            if start == u32::MAX {
                fans.push(Vec::new());
                continue;
            }
            let mut fan = vec![start];
            let mut f = start;
            loop {
                // Across the edge that leaves v: corner k == v, edge (v, next) is edge k. The
                // triangle across it continues the fan counter-clockwise around v.
                let t = self.triangles[f as usize];
                let k = t.iter().position(|&x| x == v).ok_or(MeshError::BadFan(v))?;
                let next = adj[f as usize][(k + 2) % 3];
                if next == start {
                    break;
                }
                if fan.len() > count[v as usize] {
                    return Err(MeshError::BadFan(v));
                }
                fan.push(next);
                f = next;
            }
            if fan.len() != count[v as usize] {
                return Err(MeshError::BadFan(v));
            }
            fans.push(fan);
        }
        Ok(fans)
    }

    /// Appends another mesh, renumbering its vertices.
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
    }
}
