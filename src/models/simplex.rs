//! The 2-simplex mesh: the topological dual of a closed triangle mesh. Each simplex vertex sits
//! at a triangle's centroid and has exactly three neighbours (the triangles across its edges).
//! The render triangulation is mapped back from it: each triangle-mesh vertex is the centroid
//! of the simplex vertices around it plus an offset measured at rest.

use crate::mesh::{MeshError, TriMesh};
use glam::Vec3;

/// One render vertex: a run of consecutive live faces around a triangle-mesh vertex. An uncut
/// vertex has one run (its whole fan); a cut through the fan splits it into several. The run
/// is stored as a (cyclic) stretch of its source vertex's fan, so it owns no list: 24 bytes.
#[derive(Debug, Clone, Copy)]
pub struct RenderVertex {
    /// The triangle-mesh vertex this came from.
    pub source: u32,
    /// Where the run starts in the source's fan.
    pub first: u16,
    /// How many faces of the fan (going round, wrapping) the run takes.
    pub count: u16,
    /// Rest offset along the run's normal, metres.
    pub height_m: f32,
    /// Rest offset in the tangent plane, metres.
    pub tangent_m: Vec3,
}

#[derive(Debug, Clone)]
pub struct SimplexMesh {
    /// Neighbour across edge k of face i; edge k joins corners k and k+1.
    pub neighbors: Vec<[u32; 3]>,
    /// The render triangulation (triangle-mesh faces, one per simplex vertex).
    pub faces: Vec<[u32; 3]>,
    /// Faces around each triangle-mesh vertex, counter-clockwise: vertex v's fan is
    /// `fan_faces[fan_start[v]..fan_start[v + 1]]` (see [`SimplexMesh::fan`]).
    pub fan_start: Vec<u32>,
    pub fan_faces: Vec<u32>,
    /// Triangle-mesh rest positions, metres.
    pub tri_rest: Vec<Vec3>,
    /// Simplex rest positions (face centroids), metres.
    pub rest: Vec<Vec3>,
    /// Render vertices, rebuilt where cuts split fans.
    pub render: Vec<RenderVertex>,
    /// For each face corner, its render vertex.
    pub corners: Vec<[u32; 3]>,
}

impl SimplexMesh {
    /// Builds the dual of a closed triangle mesh.
    pub fn dual(mesh: &TriMesh) -> Result<Self, MeshError> {
        let neighbors = mesh.edge_adjacency()?;
        let fans = mesh.vertex_fans(&neighbors)?;
        let mut fan_start = Vec::with_capacity(fans.len() + 1);
        let mut fan_faces = Vec::with_capacity(3 * mesh.triangles.len());
        fan_start.push(0);
        for (v, fan) in fans.iter().enumerate() {
            if fan.len() > u16::MAX as usize {
                return Err(MeshError::CrowdedVertex(v, fan.len()));
            }
            fan_faces.extend_from_slice(fan);
            fan_start.push(fan_faces.len() as u32);
        }
        drop(fans);
        let rest: Vec<Vec3> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| mesh.positions[i as usize]).iter().sum::<Vec3>() / 3.0)
            .collect();
        let mut s = SimplexMesh {
            neighbors,
            faces: mesh.triangles.clone(),
            fan_start,
            fan_faces,
            tri_rest: mesh.positions.clone(),
            rest,
            render: Vec::new(),
            corners: vec![[u32::MAX; 3]; mesh.triangles.len()],
        };
        let alive = vec![true; s.faces.len()];
        let mut normals = vec![Vec3::ZERO; s.rest.len()];
        s.vertex_normals(&s.rest, &alive, &mut normals);
        s.rebuild_render(&alive, &normals);
        Ok(s)
    }

    /// The faces around triangle-mesh vertex `v`, counter-clockwise.
    pub fn fan(&self, v: usize) -> &[u32] {
        &self.fan_faces[self.fan_start[v] as usize..self.fan_start[v + 1] as usize]
    }

    /// Number of triangle-mesh vertices.
    pub fn vertex_count(&self) -> usize {
        self.fan_start.len().saturating_sub(1)
    }

    /// The simplex vertices of render vertex `r`'s run.
    pub fn run(&self, r: usize) -> impl Iterator<Item = u32> + '_ {
        let rv = self.render[r];
        let fan = self.fan(rv.source as usize);
        (0..rv.count as usize).map(move |j| fan[(rv.first as usize + j) % fan.len()])
    }

    /// Whether render vertex `r` is only part of its fan (a cut passes through the vertex).
    pub fn is_split(&self, r: usize) -> bool {
        let rv = self.render[r];
        (rv.count as usize) < self.fan(rv.source as usize).len()
    }

    pub fn len(&self) -> usize {
        self.rest.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Normal of simplex vertex `i` and the area it stands for: the triangle of its three
    /// neighbours (same size as its face on a regular mesh). A dead neighbour is replaced by the
    /// reflection of the other two through `i`.
    pub fn normal_area(&self, x: &[Vec3], alive: &[bool], i: usize) -> (Vec3, f32) {
        let p = x[i];
        let nb = self.neighbors[i];
        let live = nb.map(|n| alive[n as usize]);
        let q = match live {
            [true, true, true] => nb.map(|n| x[n as usize]),
            _ => {
                let mut q = nb.map(|n| x[n as usize]);
                let dead: Vec<usize> = (0..3).filter(|&k| !live[k]).collect();
                if dead.len() != 1 {
                    return (Vec3::ZERO, 0.0);
                }
                let k = dead[0];
                q[k] = 3.0 * p - q[(k + 1) % 3] - q[(k + 2) % 3];
                q
            }
        };
        let c = (q[1] - q[0]).cross(q[2] - q[0]);
        let len = c.length();
        if len > 0.0 {
            (c / len, 0.5 * len)
        } else {
            (Vec3::ZERO, 0.0)
        }
    }

    pub fn vertex_normals(&self, x: &[Vec3], alive: &[bool], out: &mut [Vec3]) {
        for i in 0..x.len() {
            out[i] = self.normal_area(x, alive, i).0;
        }
    }

    /// Splits every fan into runs of live faces and records each run's rest offset.
    pub fn rebuild_render(&mut self, alive: &[bool], rest_normals: &[Vec3]) {
        self.render.clear();
        // One run per vertex, plus one per extra run a cut makes (grown by an eighth at a time).
        let want = self.vertex_count();
        if self.render.capacity() < want {
            self.render.reserve_exact(want);
        }
        for c in &mut self.corners {
            *c = [u32::MAX; 3];
        }
        for v in 0..self.vertex_count() {
            let n = self.fan(v).len();
            let Some(dead_at) = (0..n).find(|&k| !alive[self.fan(v)[k] as usize]) else {
                self.push_run(v as u32, 0, n, rest_normals);
                continue;
            };
            // Walk once around, starting just after a dead face, collecting live runs.
            let mut first = 0;
            let mut count = 0;
            for step in 1..=n {
                let k = (dead_at + step) % n;
                if alive[self.fan(v)[k] as usize] {
                    if count == 0 {
                        first = k;
                    }
                    count += 1;
                } else if count > 0 {
                    self.push_run(v as u32, first, count, rest_normals);
                    count = 0;
                }
            }
            if count > 0 {
                self.push_run(v as u32, first, count, rest_normals);
            }
        }
    }

    fn push_run(&mut self, v: u32, first: usize, count: usize, rest_normals: &[Vec3]) {
        let id = self.render.len() as u32;
        if self.render.len() == self.render.capacity() {
            self.render.reserve_exact(self.render.capacity() / 8 + 16);
        }
        // Fan lengths are checked to fit u16 when the mesh is built.
        self.render.push(RenderVertex {
            source: v,
            first: first as u16,
            count: count as u16,
            height_m: 0.0,
            tangent_m: Vec3::ZERO,
        });
        let (c, n) = run_frame(&self.rest, rest_normals, self.run(id as usize));
        let d = self.tri_rest[v as usize] - c;
        let height = d.dot(n);
        for f in self.run(id as usize).collect::<Vec<_>>() {
            let k = self.faces[f as usize]
                .iter()
                .position(|&x| x == v)
                .unwrap_or(0);
            self.corners[f as usize][k] = id;
        }
        let rv = &mut self.render[id as usize];
        rv.height_m = height;
        rv.tangent_m = d - n * height;
    }

    /// Position of render vertex `r` given simplex positions and normals.
    pub fn render_position(&self, r: usize, x: &[Vec3], normals: &[Vec3]) -> Vec3 {
        let rv = self.render[r];
        let (c, n) = run_frame(x, normals, self.run(r));
        c + n * rv.height_m + rv.tangent_m
    }
}

/// Centroid and mean normal of a run of simplex vertices.
fn run_frame(x: &[Vec3], normals: &[Vec3], faces: impl Iterator<Item = u32>) -> (Vec3, Vec3) {
    let mut c = Vec3::ZERO;
    let mut n = Vec3::ZERO;
    let mut count = 0u32;
    for f in faces {
        c += x[f as usize];
        n += normals[f as usize];
        count += 1;
    }
    (c / count.max(1) as f32, n.normalize_or_zero())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{KidneyShape, icosphere, kidney};

    #[test]
    fn every_simplex_vertex_has_three_distinct_neighbours_and_symmetric_links() {
        let s = SimplexMesh::dual(&kidney(&KidneyShape::default(), 3)).expect("dual");
        assert_eq!(s.len(), 1280);
        for (i, nb) in s.neighbors.iter().enumerate() {
            assert!(nb[0] != nb[1] && nb[1] != nb[2] && nb[0] != nb[2]);
            assert!(nb.iter().all(|&n| n as usize != i));
            for &n in nb {
                assert!(
                    s.neighbors[n as usize].contains(&(i as u32)),
                    "link {i}-{n}"
                );
            }
        }
    }

    #[test]
    fn render_triangulation_maps_back_to_the_triangle_mesh_at_rest() {
        let mesh = kidney(&KidneyShape::default(), 3);
        let s = SimplexMesh::dual(&mesh).expect("dual");
        let alive = vec![true; s.len()];
        let mut normals = vec![Vec3::ZERO; s.len()];
        s.vertex_normals(&s.rest, &alive, &mut normals);
        assert_eq!(s.render.len(), mesh.vertex_count());
        for r in 0..s.render.len() {
            let p = s.render_position(r, &s.rest, &normals);
            let q = mesh.positions[s.render[r].source as usize];
            assert!((p - q).length() < 1e-6, "vertex {r}: {p} vs {q}");
        }
        for (f, t) in s.faces.iter().enumerate() {
            for k in 0..3 {
                assert_eq!(s.render[s.corners[f][k] as usize].source, t[k]);
            }
        }
    }

    #[test]
    fn normals_point_outward() {
        let s = SimplexMesh::dual(&icosphere(2)).expect("dual");
        let alive = vec![true; s.len()];
        for i in 0..s.len() {
            let (n, a) = s.normal_area(&s.rest, &alive, i);
            assert!(n.dot(s.rest[i].normalize()) > 0.95);
            assert!(a > 0.0);
        }
    }

    #[test]
    fn a_dead_face_splits_the_render_vertices_around_it() {
        let mut s = SimplexMesh::dual(&icosphere(2)).expect("dual");
        let mut alive = vec![true; s.len()];
        let before = s.render.len();
        // Kill two faces of one fan that are not adjacent: that vertex splits in two runs.
        let fan = s.fan(0).to_vec();
        alive[fan[0] as usize] = false;
        alive[fan[2] as usize] = false;
        let normals: Vec<Vec3> = (0..s.len())
            .map(|i| s.normal_area(&s.rest, &alive, i).0)
            .collect();
        s.rebuild_render(&alive, &normals);
        let runs_of_0 = s.render.iter().filter(|r| r.source == 0).count();
        assert_eq!(runs_of_0, 2);
        assert_eq!(s.render.len(), before + 1);
    }
}
