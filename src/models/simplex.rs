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
        s.rebuild_render(&vec![true; s.faces.len()]);
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
    pub fn rebuild_render(&mut self, alive: &[bool]) {
        let all: Vec<u32> = (0..self.vertex_count() as u32).collect();
        self.update_render(alive, &all);
    }

    /// The triangle-mesh vertices whose runs change when `faces` die: those of the faces and
    /// of their neighbours (whose normals at rest depend on them), sorted, each once.
    pub fn vertices_around(&self, faces: &[u32]) -> Vec<u32> {
        let mut changed: Vec<u32> = faces
            .iter()
            .flat_map(|&f| std::iter::once(f).chain(self.neighbors[f as usize]))
            .flat_map(|f| self.faces[f as usize])
            .collect();
        changed.sort_unstable();
        changed.dedup();
        changed
    }

    /// Brings the render runs up to date after faces died: the vertices `changed` (sorted,
    /// each once: those with a dead face in their fan, or a face whose rest normal changed)
    /// are split into runs again; every other vertex keeps its runs, renumbered. The runs stay
    /// in vertex order.
    pub fn update_render(&mut self, alive: &[bool], changed: &[u32]) {
        // One run per vertex, plus one per extra run a cut makes (grown by an eighth at a time).
        let want = self.vertex_count();
        let old = std::mem::take(&mut self.render);
        self.render.reserve_exact(old.capacity().max(want));
        for c in &mut self.corners {
            *c = [u32::MAX; 3];
        }
        let mut at = 0;
        let mut changed = changed.iter().copied().peekable();
        for v in 0..self.vertex_count() {
            let start = at;
            while at < old.len() && old[at].source as usize == v {
                at += 1;
            }
            if changed.next_if_eq(&(v as u32)).is_some() {
                self.split_fan(v, alive);
            } else {
                for &rv in &old[start..at] {
                    self.push_run(rv);
                }
            }
        }
    }

    /// Splits vertex `v`'s fan into runs of live faces.
    fn split_fan(&mut self, v: usize, alive: &[bool]) {
        let n = self.fan(v).len();
        let Some(dead_at) = (0..n).find(|&k| !alive[self.fan(v)[k] as usize]) else {
            self.new_run(v as u32, 0, n, alive);
            return;
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
                self.new_run(v as u32, first, count, alive);
                count = 0;
            }
        }
        if count > 0 {
            self.new_run(v as u32, first, count, alive);
        }
    }

    /// A new run of `count` faces of `v`'s fan from `first`, with its rest offset measured
    /// against the run's rest frame.
    fn new_run(&mut self, v: u32, first: usize, count: usize, alive: &[bool]) {
        // Fan lengths are checked to fit u16 when the mesh is built.
        let id = self.push_run(RenderVertex {
            source: v,
            first: first as u16,
            count: count as u16,
            height_m: 0.0,
            tangent_m: Vec3::ZERO,
        });
        let rest = &self.rest;
        let (mut c, mut n) = (Vec3::ZERO, Vec3::ZERO);
        for f in self.run(id as usize) {
            c += rest[f as usize];
            n += self.normal_area(rest, alive, f as usize).0;
        }
        let (c, n) = (c / count.max(1) as f32, n.normalize_or_zero());
        let d = self.tri_rest[v as usize] - c;
        let height = d.dot(n);
        let rv = &mut self.render[id as usize];
        rv.height_m = height;
        rv.tangent_m = d - n * height;
    }

    /// Appends a run and points its faces' corners at it; returns its id.
    fn push_run(&mut self, rv: RenderVertex) -> u32 {
        let id = self.render.len() as u32;
        if self.render.len() == self.render.capacity() {
            self.render.reserve_exact(self.render.capacity() / 8 + 16);
        }
        self.render.push(rv);
        let fan = &self.fan_faces[self.fan_start[rv.source as usize] as usize
            ..self.fan_start[rv.source as usize + 1] as usize];
        for j in 0..rv.count as usize {
            let f = fan[(rv.first as usize + j) % fan.len()] as usize;
            let k = self.faces[f]
                .iter()
                .position(|&x| x == rv.source)
                .unwrap_or(0);
            self.corners[f][k] = id;
        }
        id
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
        s.rebuild_render(&alive);
        let runs_of_0 = s.render.iter().filter(|r| r.source == 0).count();
        assert_eq!(runs_of_0, 2);
        assert_eq!(s.render.len(), before + 1);
    }

    /// The runs of a mesh as plain values, to compare two builds.
    fn runs(s: &SimplexMesh) -> Vec<(u32, u16, u16, u32, [u32; 3])> {
        s.render
            .iter()
            .map(|r| {
                let t = r.tangent_m.to_array().map(f32::to_bits);
                (r.source, r.first, r.count, r.height_m.to_bits(), t)
            })
            .collect()
    }

    #[test]
    fn updating_the_runs_around_cuts_gives_what_a_full_rebuild_gives() {
        let mut s = SimplexMesh::dual(&kidney(&KidneyShape::default(), 3)).expect("dual");
        let mut alive = vec![true; s.len()];
        // Three cuts: a strip of faces, then faces next to it, then a lone face elsewhere.
        for cut in [
            (0..40u32).collect::<Vec<_>>(),
            (40..60).chain([900, 901]).collect(),
            vec![640],
        ] {
            for &f in &cut {
                alive[f as usize] = false;
            }
            let changed = s.vertices_around(&cut);
            assert!(changed.len() < s.vertex_count() / 4, "the update is local");
            s.update_render(&alive, &changed);
            let mut full = s.clone();
            full.rebuild_render(&alive);
            assert_eq!(runs(&s), runs(&full));
            assert_eq!(s.corners, full.corners);
        }
        // The cuts split fans: more runs than vertices now, and dead faces have no corners.
        assert!(s.render.len() > s.vertex_count() - 60);
        assert!(s.corners[0] == [u32::MAX; 3] && s.corners[640] == [u32::MAX; 3]);
    }
}
