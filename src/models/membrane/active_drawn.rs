//! Where the membrane is drawn, a grid of nodes at a time: [`Membrane::carried_position`]
//! of many nodes, with layer 0's target under a sleeping column found once for every layer
//! drawn there, in parallel by rows (each value is written once: the threads change no bit).

use super::Activity;
use crate::models::membrane::Membrane;
use glam::Vec3;
use rayon::prelude::*;

/// Grid rows a task takes at the least.
const ROWS_PER_TASK: usize = 8;

impl Membrane {
    /// Node `(l, i, j)` of a sleeping tile: where its anchor, on layer 0's target `target`
    /// at its column, and its offset carry it.
    pub(super) fn carried_asleep(&self, a: &Activity, [l, i, j]: [usize; 3], target: Vec3) -> Vec3 {
        let (cols, b) = (self.cols, l * self.rows + i);
        let keep = 1.0 - a.weight[b * cols + j];
        Vec3::from_array(std::array::from_fn(|c| {
            let rest = a.rest[(b * 3 + c) * cols + j];
            let rest0 = a.rest[(i * 3 + c) * cols + j];
            rest + (target[c] - rest0) * keep + a.offset[(b * 3 + c) * cols + j]
        }))
    }

    /// [`Membrane::carried_position`] of the nodes of layers `layers` at rows `rows` and
    /// columns `cols` (each inside the grid), layer by layer and row by row: the same values.
    /// A node outside the grid is drawn at the origin.
    pub fn carried_grid(&self, layers: &[usize], rows: &[usize], cols: &[usize]) -> Vec<Vec3> {
        let (nr, nc) = (rows.len(), cols.len());
        let mut out = vec![Vec3::ZERO; layers.len() * nr * nc];
        if nc == 0 {
            return out;
        }
        let inside =
            |l: usize, i: usize, j: usize| l < super::LAYERS && i < self.rows && j < self.cols;
        let Some(a) = self.activity.as_ref().filter(|a| !a.all_awake) else {
            out.par_chunks_mut(nc)
                .with_min_len(ROWS_PER_TASK)
                .enumerate()
                .for_each(|(k, row)| {
                    let (l, i) = (layers[k / nr], rows[k % nr]);
                    for (p, &j) in row.iter_mut().zip(cols) {
                        if inside(l, i, j) {
                            *p = self.position(self.node(l, i, j));
                        }
                    }
                });
            return out;
        };
        let asleep = |i: usize, j: usize| {
            let t = self.tile_of(i, j);
            a.awake.get(t).is_some_and(|&w| !w).then_some(t)
        };
        // Layer 0's targets under the sleeping columns, once for all the layers.
        let mut targets = vec![Vec3::ZERO; nr * nc];
        targets
            .par_chunks_mut(nc)
            .with_min_len(ROWS_PER_TASK)
            .zip(rows)
            .for_each(|(row, &i)| {
                for (p, &j) in row.iter_mut().zip(cols) {
                    if inside(0, i, j)
                        && let Some(t) = asleep(i, j)
                    {
                        *p = self.target_now(i, j, t);
                    }
                }
            });
        out.par_chunks_mut(nc)
            .with_min_len(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(k, row)| {
                let (l, r) = (layers[k / nr], k % nr);
                let i = rows[r];
                for ((p, &j), &target) in row.iter_mut().zip(cols).zip(&targets[r * nc..]) {
                    if !inside(l, i, j) {
                        continue;
                    }
                    *p = match asleep(i, j) {
                        Some(_) => self.carried_asleep(a, [l, i, j], target),
                        None => self.position(self.node(l, i, j)),
                    };
                }
            });
        out
    }
}
