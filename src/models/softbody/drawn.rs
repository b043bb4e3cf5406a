//! The points' normals the renderer's snapshot takes, kept from one snapshot to the next: a
//! point's normal is found again only where it, or one of its three neighbours, moved or
//! died since the last snapshot. Most of a body sleeps between two frames, so a snapshot no
//! longer pays for every point's normal; what it gives is what finding them all would give,
//! bit for bit (a normal depends on nothing else).

use crate::models::simplex::SimplexMesh;
use crate::sim::ModelSnapshot;
use glam::Vec3;
use rayon::prelude::*;

/// The fewest points (or drawn vertices) one task of the snapshot takes.
const PER_TASK: usize = 4096;

/// What a snapshot of a body reads of it: borrowed from the body, or from the copies a
/// snapshot's job owns.
pub(super) struct Drawn<'a> {
    pub name: &'a str,
    pub mesh: &'a SimplexMesh,
    pub x: &'a [Vec3],
    /// Per point (and its triangle-mesh face): alive.
    pub alive: &'a [bool],
    pub regions: &'a [u8],
    pub sear_cuts: bool,
}

/// The surface drawn of `d`: the drawn vertices (found in parallel, each value written once:
/// the threads change no bit) on the points' normals that `kept` keeps from the last
/// snapshot, the live triangles, smooth normals, and the cuts' outlines.
pub(super) fn surface(d: &Drawn, kept: &mut DrawnNormals) -> ModelSnapshot {
    let Drawn { mesh, x, alive, .. } = *d;
    let normals = kept.update(mesh, x, alive);
    let positions: Vec<Vec3> = (0..mesh.render.len())
        .into_par_iter()
        .with_min_len(PER_TASK)
        .map(|r| mesh.render_position(r, x, normals))
        .collect();
    let mut indices = Vec::with_capacity(mesh.faces.len() * 3);
    let mut regions = Vec::with_capacity(mesh.faces.len());
    for f in 0..mesh.faces.len() {
        if alive[f] {
            indices.extend_from_slice(&mesh.corners[f]);
            regions.push(d.regions[f]);
        }
    }
    // Smooth render normals from the triangles.
    let mut rn = vec![Vec3::ZERO; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            rn[i as usize] += n;
        }
    }
    let cut_edge = (0..mesh.render.len())
        .into_par_iter()
        .with_min_len(PER_TASK)
        .map(|r| mesh.is_split(r))
        .collect();
    let mut out = ModelSnapshot {
        name: d.name.to_string(),
        cut_edge,
        positions,
        normals: rn.into_iter().map(Vec3::normalize_or_zero).collect(),
        indices,
        regions,
        // The procedure says what each region is.
        roles: Vec::new(),
        seared: Vec::new(),
    };
    // The holes cuts left: smooth outlines and a bed of raw (seared) tissue.
    let look = super::crater::close_cuts(&mut out, d.sear_cuts);
    if d.sear_cuts {
        out.seared = look.iter().map(|l| l.seared).collect();
    }
    out
}

/// The positions and life of every point at the last snapshot, and their normals then.
#[derive(Debug, Clone, Default)]
pub(super) struct DrawnNormals {
    x: Vec<Vec3>,
    alive: Vec<bool>,
    normals: Vec<Vec3>,
    /// Scratch: which points changed since the last snapshot.
    changed: Vec<bool>,
}

impl DrawnNormals {
    /// The normals of the points at `x` (alive where `alive`), as
    /// [`SimplexMesh::normal_area`] gives them.
    pub(super) fn update(&mut self, mesh: &SimplexMesh, x: &[Vec3], alive: &[bool]) -> &[Vec3] {
        let n = x.len();
        let fresh = self.x.len() != n
            || self.alive.len() != n
            || self.normals.len() != n
            || mesh.neighbors.len() != n;
        if fresh {
            self.normals = (0..n)
                .into_par_iter()
                .with_min_len(PER_TASK)
                .map(|i| mesh.normal_area(x, alive, i).0)
                .collect();
            self.x = x.to_vec();
            self.alive = alive.to_vec();
            return &self.normals;
        }
        let bits = |p: Vec3| p.to_array().map(f32::to_bits);
        let (was_x, was_alive) = (&self.x, &self.alive);
        (0..n)
            .into_par_iter()
            .with_min_len(PER_TASK)
            .map(|j| bits(x[j]) != bits(was_x[j]) || alive[j] != was_alive[j])
            .collect_into_vec(&mut self.changed);
        let changed = &self.changed;
        self.normals
            .par_iter_mut()
            .with_min_len(PER_TASK)
            .enumerate()
            .for_each(|(i, normal)| {
                let near = mesh.neighbors[i];
                if changed[i] || near.iter().any(|&k| changed[k as usize]) {
                    *normal = mesh.normal_area(x, alive, i).0;
                }
            });
        self.x
            .par_iter_mut()
            .with_min_len(PER_TASK)
            .zip(x)
            .for_each(|(was, &now)| *was = now);
        self.alive.copy_from_slice(alive);
        &self.normals
    }

    /// Heap bytes held (capacity), for the profiler.
    pub(super) fn heap_bytes(&self) -> usize {
        self.x.capacity() * size_of::<Vec3>()
            + self.normals.capacity() * size_of::<Vec3>()
            + self.alive.capacity()
            + self.changed.capacity()
    }
}
