//! Layer 0 and what holds it: the membrane's side of a coupling to the model that carries
//! layer 0 (the rectum's rod). Each layer-0 node is held to a target by its attachment; the
//! holder wants the load the membrane puts on it and how fast that load changes as the
//! target moves.

use super::forces::{RowScratch, Whole, row, sort_external};
use super::{ALONG, AROUND, LAYERS, LINK, Membrane, field};
use glam::Vec3;

impl Membrane {
    /// Layer 0's node at row `i`, column `j`: where it is held (its target) and the pull of
    /// the membrane on whatever holds it, `k (x - target)`, N (the reaction of the
    /// attachment's force on the node).
    pub fn anchor_pull(&self, i: usize, j: usize) -> Option<(Vec3, Vec3)> {
        if i >= self.rows || j >= self.cols {
            return None;
        }
        let k = self.attach[i * 4 * self.cols + j];
        let target = self.target_now(i, j, self.tile_of(i, j));
        let x = self.position(self.node(0, i, j));
        Some((target, (x - target) * k))
    }

    /// How stiffly the membrane holds layer 0's node at row `i`, column `j` against its
    /// anchor, N/m: the node's own stiffness (the diagonal of `K`: its springs around and
    /// along, its link to layer 1 and its share `(1 - w)^2` of the tethers of layers 1 and 2
    /// over it) in series with its attachment. Moving the anchor alone by `d` moves the
    /// membrane's load on it by at most this times `d`; a model holding layer 0 takes it as
    /// the stiffness of that load.
    pub fn anchor_stiffness(&self, i: usize, j: usize) -> f32 {
        if i >= self.rows || j >= self.cols {
            return 0.0;
        }
        let node = self.node(0, i, j);
        let mut k = self.spring(field::K[AROUND], node)
            + self.spring(field::K[LINK], node)
            + if i + 1 < self.rows {
                self.spring(field::K[ALONG], node)
            } else {
                0.0
            };
        if i > 0 {
            k += self.spring(field::K[ALONG], node - self.cols);
        }
        let before = if j > 0 {
            Some(j - 1)
        } else {
            self.periodic.then(|| self.cols - 1)
        };
        if let Some(jb) = before {
            k += self.spring(field::K[AROUND], self.node(0, i, jb));
        }
        for l in 1..LAYERS - 1 {
            let above = self.node(l, i, j);
            let w = self.spring(field::SHEAR_W, above);
            k += self.spring(field::SHEAR_K, above) * (1.0 - w) * (1.0 - w);
        }
        let ka = self.attach_stiffness(node);
        if k > 0.0 && ka > 0.0 {
            k * ka / (k + ka)
        } else {
            0.0
        }
    }

    /// What the rest of the membrane does to layer 0 on tiles `tiles`: for each of their
    /// layer-0 nodes (row, column) the sum of its springs, links, tethers and external forces
    /// now, N, into `out` (in tile order). The attachment that holds the node and its own
    /// damping are left out: at rest the attachment carries exactly this load to whatever
    /// holds layer 0, and unlike the attachment's stretch it does not ring with the node's
    /// own fast motion on its anchor, so a model holding layer 0 can take it as a given force.
    pub fn anchor_loads(&mut self, tiles: &[usize], out: &mut Vec<(u32, u32, Vec3)>) {
        sort_external(&mut self.external);
        let m = &*self;
        // Tiles side by side in a row of tiles go as one run of the row kernel.
        let (_, tc) = m.tiles();
        let mut runs: Vec<([usize; 2], [usize; 2])> = Vec::new();
        let mut last: Option<usize> = None;
        for &t in tiles {
            let (rs, cs) = m.tile_span(t);
            match (runs.last_mut(), last) {
                (Some((r, c)), Some(p))
                    if t == p + 1 && t % tc != 0 && *r == rs && c[1] == cs[0] =>
                {
                    c[1] = cs[1];
                }
                _ => runs.push((rs, cs)),
            }
            last = Some(t);
        }
        self.loads_over_runs(&runs, out);
    }

    /// [`Membrane::anchor_loads`] over `runs` of layer-0 nodes (rows, columns), each a
    /// rectangle of the grid, in order (the external forces sorted by node).
    pub(super) fn loads_over_runs(
        &self,
        runs: &[([usize; 2], [usize; 2])],
        out: &mut Vec<(u32, u32, Vec3)>,
    ) {
        use rayon::prelude::*;
        out.clear();
        let m = self;
        let (rows, cols) = (m.rows, m.cols);
        let whole = Whole {
            data: &m.state.data,
            rows,
            cols,
        };
        let one = |sc: &mut RowScratch, &span: &([usize; 2], [usize; 2])| {
            m.vectorized(LoadPass {
                m,
                whole: &whole,
                sc,
                span,
            })
        };
        let nodes: usize = runs
            .iter()
            .map(|([r0, r1], [c0, c1])| LAYERS * (r1 - r0) * (c1 - c0))
            .sum();
        let parts: Vec<Vec<(u32, u32, Vec3)>> = if super::active::worth_threads(nodes) {
            runs.par_iter().map_init(RowScratch::default, one).collect()
        } else {
            let mut sc = RowScratch::default();
            runs.iter().map(|r| one(&mut sc, r)).collect()
        };
        for p in parts {
            out.extend(p);
        }
    }
}

/// One run's layer-0 loads, compiled for the widest vector unit the CPU has.
struct LoadPass<'a, 'w> {
    m: &'a Membrane,
    whole: &'a Whole<'w>,
    sc: &'a mut RowScratch,
    span: ([usize; 2], [usize; 2]),
}

impl pulp::WithSimd for LoadPass<'_, '_> {
    type Output = Vec<(u32, u32, Vec3)>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        let LoadPass {
            m,
            whole,
            sc,
            span: ([r0, r1], [c0, c1]),
        } = self;
        let cols = m.cols;
        let mut part = Vec::with_capacity((r1 - r0) * (c1 - c0));
        for i in r0..r1 {
            row::<_, true>(m, whole, i, c0..c1, i == r0, sc);
            // Layer 0's row `i` is block `i`: the kernel's sum holds the attachment's
            // force, `-k (x - target)`: take it out.
            let at = i * 4 * cols;
            for j in c0..c1 {
                let k = m.attach[at + j];
                let f = Vec3::from_array(std::array::from_fn(|c| {
                    let x = whole.data[(i * 6 + c) * cols + j];
                    let target = m.attach[at + (1 + c) * cols + j];
                    sc.row(0, c, cols)[j] + k * (x - target)
                }));
                part.push((i as u32, j as u32, f));
            }
        }
        part
    }
}
