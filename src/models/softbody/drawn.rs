//! The points' normals the renderer's snapshot takes, kept from one snapshot to the next: a
//! point's normal is found again only where it, or one of its three neighbours, moved or
//! died since the last snapshot. Most of a body sleeps between two frames, so a snapshot no
//! longer pays for every point's normal; what it gives is what finding them all would give,
//! bit for bit (a normal depends on nothing else).

use crate::models::simplex::SimplexMesh;
use glam::Vec3;
use rayon::prelude::*;

/// The fewest points one task of the snapshot's normals takes.
const PER_TASK: usize = 4096;

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
