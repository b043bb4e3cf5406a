//! Where the membrane is drawn, a grid of nodes at a time: [`Membrane::carried_position`] of
//! many nodes ([`Membrane::place_drawn`]), in parallel by rows (each value is written once:
//! the threads change no bit).
//!
//! What places a sleeping node (its rest, its column's rest on layer 0, its share of the
//! anchor, its offset and its column's binding on the chain) lies in five of the model's
//! arrays, a few cache lines a drawn node at full size, where a frame would gather it anew.
//! A [`DrawnGrid`] keeps a copy of it in the grid's own order, refreshed for a tile only when
//! the tile's offsets were written again (it fell asleep anew: a new [`stamp`]), and for the
//! bindings when the chain is bound anew; a frame then streams the copy.

use super::Activity;
use crate::models::membrane::chain::ChainBinding;
use crate::models::membrane::{LAYERS, Membrane};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Grid rows a task takes at the least.
const ROWS_PER_TASK: usize = 8;

/// Stamps handed out so far (0 is none).
static STAMPS: AtomicU64 = AtomicU64::new(1);

/// A stamp no other write has had: it marks a write of a tile's offsets or of a chain's
/// bindings, so that a copy of them knows whether it is current (only equality is read, so
/// the values change no bytes of the model).
pub(in crate::models::membrane) fn stamp() -> u64 {
    STAMPS.fetch_add(1, Ordering::Relaxed)
}

/// A sleeping node's fixed parts: it is drawn at `rest + (target - rest0) keep + offset`.
#[derive(Debug, Clone, Copy, Default)]
struct Fixed {
    rest: [f32; 3],
    rest0: [f32; 3],
    offset: [f32; 3],
    keep: f32,
}

impl Fixed {
    /// Node `(l, i, j)`'s parts in the active set `a` of `m`.
    fn of(m: &Membrane, a: &Activity, [l, i, j]: [usize; 3]) -> Fixed {
        let (cols, b) = (m.cols, l * m.rows + i);
        Fixed {
            rest: std::array::from_fn(|c| a.rest[(b * 3 + c) * cols + j]),
            rest0: std::array::from_fn(|c| a.rest[(i * 3 + c) * cols + j]),
            offset: std::array::from_fn(|c| a.offset[(b * 3 + c) * cols + j]),
            keep: 1.0 - a.weight[b * cols + j],
        }
    }

    /// Where the node is drawn under its column's layer-0 target `target`.
    #[inline]
    fn at(&self, target: Vec3) -> Vec3 {
        Vec3::from_array(std::array::from_fn(|c| {
            self.rest[c] + (target[c] - self.rest0[c]) * self.keep + self.offset[c]
        }))
    }
}

/// A grid of drawn nodes (layers by rows by columns, each list in the order given) with a copy
/// of what places its sleeping nodes (module docs). Made once for a surface and handed to
/// [`Membrane::place_drawn`] at each frame; a copy made for another membrane, tiling or chain
/// is made again on its own.
#[derive(Debug, Clone, Default)]
pub struct DrawnGrid {
    layers: Vec<usize>,
    rows: Vec<usize>,
    cols: Vec<usize>,
    /// The membrane's rows and columns and its tiles' rows and columns the copy is laid out
    /// for (zeros: none yet).
    made_for: [usize; 4],
    /// Per cell (row by row over `rows` x `cols`): its tile, `u32::MAX` outside the grid.
    tile: Vec<u32>,
    /// Per tile: the stamp of the offsets copied (0: none).
    seen: Vec<u64>,
    /// Per node (layer by layer, then cell by cell): the fixed parts.
    fixed: Vec<Fixed>,
    /// Per cell: its column's binding on the chain, copied under the chain's stamp
    /// `chain_seen` (0: none).
    bound: Vec<Option<ChainBinding>>,
    chain_seen: u64,
}

impl DrawnGrid {
    /// The nodes of layers `layers` at rows `rows` and columns `cols`; one outside the
    /// membrane is drawn at the origin.
    pub fn new(layers: &[usize], rows: &[usize], cols: &[usize]) -> DrawnGrid {
        DrawnGrid {
            layers: layers.to_vec(),
            rows: rows.to_vec(),
            cols: cols.to_vec(),
            ..DrawnGrid::default()
        }
    }

    /// Nodes in the grid (the length of what [`Membrane::place_drawn`] returns).
    pub fn len(&self) -> usize {
        self.layers.len() * self.rows.len() * self.cols.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The grid's layers, rows and columns, each in its order.
    pub(in crate::models::membrane) fn parts(&self) -> [&[usize]; 3] {
        [&self.layers, &self.rows, &self.cols]
    }

    /// Brings the copy up to `m` and its active set `a`: laid out anew for another size or
    /// tiling, the bindings copied anew for another chain, and the fixed parts of each
    /// sleeping tile whose offsets were written since.
    fn refresh(&mut self, m: &Membrane, a: &Activity) {
        let (nr, nc) = (self.rows.len(), self.cols.len());
        let made_for = [m.rows, m.cols, a.params.tile_rows, a.params.tile_cols];
        if made_for != self.made_for || self.seen.len() != a.awake.len() {
            self.made_for = made_for;
            self.tile = (0..nr * nc)
                .map(|cell| {
                    let (i, j) = (self.rows[cell / nc], self.cols[cell % nc]);
                    if i < m.rows && j < m.cols {
                        m.tile_of(i, j) as u32
                    } else {
                        u32::MAX
                    }
                })
                .collect();
            self.seen = vec![0; a.awake.len()];
            self.fixed = vec![Fixed::default(); self.len()];
            self.chain_seen = 0;
        }
        match m.chain.as_deref() {
            Some(c) if c.stamp != self.chain_seen => {
                self.bound = (0..nr * nc)
                    .map(|cell| {
                        let (i, j) = (self.rows[cell / nc], self.cols[cell % nc]);
                        (i < m.rows && j < m.cols)
                            .then(|| c.bound.get(i * m.cols + j).copied())
                            .flatten()
                    })
                    .collect();
                self.chain_seen = c.stamp;
            }
            _ => {}
        }
        let stale: Vec<bool> = (0..a.awake.len())
            .map(|t| !a.awake[t] && a.slept.get(t).is_none_or(|&s| s != self.seen[t]))
            .collect();
        if !stale.contains(&true) {
            return;
        }
        for (cell, &t) in self.tile.iter().enumerate() {
            if t == u32::MAX || !stale[t as usize] {
                continue;
            }
            let (i, j) = (self.rows[cell / nc], self.cols[cell % nc]);
            for (k, &l) in self.layers.iter().enumerate() {
                if l >= LAYERS {
                    continue;
                }
                self.fixed[k * nr * nc + cell] = Fixed::of(m, a, [l, i, j]);
            }
        }
        for (t, s) in stale.into_iter().enumerate() {
            if s {
                self.seen[t] = a.slept.get(t).copied().unwrap_or(0);
            }
        }
    }
}

impl Membrane {
    /// Node `(l, i, j)` of a sleeping tile: where its anchor, on layer 0's target `target`
    /// at its column, and its offset carry it.
    pub(super) fn carried_asleep(&self, a: &Activity, node: [usize; 3], target: Vec3) -> Vec3 {
        Fixed::of(self, a, node).at(target)
    }

    /// [`Membrane::carried_position`] of the nodes of layers `layers` at rows `rows` and
    /// columns `cols`, layer by layer and row by row: the same values. A node outside the
    /// grid is drawn at the origin. (A frame after frame keeps a [`DrawnGrid`] instead.)
    pub fn carried_grid(&mut self, layers: &[usize], rows: &[usize], cols: &[usize]) -> Vec<Vec3> {
        self.place_drawn(&mut DrawnGrid::new(layers, rows, cols))
    }

    /// [`Membrane::carried_position`] of each node of `g`, layer by layer and row by row (the
    /// same values), its copy of the sleeping nodes' fixed parts brought up to date first.
    /// Where the membrane steps on a device, an awake node of a tile the CPU lags is drawn
    /// where the device left it ([`Membrane::lagging_positions`]; the tile stays lagging);
    /// should that read fail, everything is brought up to date first
    /// ([`Membrane::catch_up`], which gives the device up).
    pub fn place_drawn(&mut self, g: &mut DrawnGrid) -> Vec<Vec3> {
        let (mut out, lagging) = self.place_current(g);
        // The device gathers this grid's nodes for the frames after this one.
        self.gather_drawn(g);
        if lagging.is_empty() || self.lagging_positions(g, &lagging, &mut out).is_ok() {
            return out;
        }
        self.catch_up();
        self.place_current(g).0
    }

    /// [`Membrane::place_drawn`] of the nodes current on the CPU, with the nodes of lagging
    /// tiles left at the origin and listed (layer, row, column, and place).
    fn place_current(&self, g: &mut DrawnGrid) -> (Vec<Vec3>, Vec<([usize; 3], usize)>) {
        let (nr, nc) = (g.rows.len(), g.cols.len());
        let mut out = vec![Vec3::ZERO; g.len()];
        if nc == 0 {
            return (out, Vec::new());
        }
        let Some(a) = self.activity.as_ref().filter(|a| !a.all_awake) else {
            let inside =
                |l: usize, i: usize, j: usize| l < LAYERS && i < self.rows && j < self.cols;
            out.par_chunks_mut(nc)
                .with_min_len(ROWS_PER_TASK)
                .enumerate()
                .for_each(|(k, row)| {
                    let (l, i) = (g.layers[k / nr], g.rows[k % nr]);
                    for (p, &j) in row.iter_mut().zip(&g.cols) {
                        if inside(l, i, j) {
                            *p = self.position(self.node(l, i, j));
                        }
                    }
                });
            return (out, Vec::new());
        };
        g.refresh(self, a);
        let g = &*g;
        let asleep = |t: u32| t != u32::MAX && a.awake.get(t as usize).is_some_and(|&w| !w);
        // Per cell, whether its tile lags the device (awake, never asleep).
        let lags: Vec<bool> = g
            .tile
            .iter()
            .map(|&t| t != u32::MAX && self.tile_lags(t as usize))
            .collect();
        // Layer 0's targets under the sleeping columns, once for all the layers (as
        // `Membrane::target_now` finds them).
        let chain = self.chain.as_deref().filter(|c| c.pose > 0);
        let mut targets = vec![Vec3::ZERO; nr * nc];
        targets
            .par_chunks_mut(nc)
            .with_min_len(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(r, row)| {
                let i = g.rows[r];
                for (q, p) in row.iter_mut().enumerate() {
                    let t = g.tile[r * nc + q];
                    if !asleep(t) {
                        continue;
                    }
                    let on_chain = chain
                        .filter(|c| !c.current(t as usize))
                        .and_then(|c| c.target_of(g.bound.get(r * nc + q)?.as_ref()?));
                    *p = on_chain.unwrap_or_else(|| self.target_set(i, g.cols[q]));
                }
            });
        out.par_chunks_mut(nc)
            .with_min_len(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(k, row)| {
                let (l, r) = (g.layers[k / nr], k % nr);
                if l >= LAYERS {
                    return;
                }
                let i = g.rows[r];
                let fixed = &g.fixed[k * nc..(k + 1) * nc];
                let (tiles, targets) = (&g.tile[r * nc..(r + 1) * nc], &targets[r * nc..]);
                for q in 0..nc {
                    let t = tiles[q];
                    if t == u32::MAX || lags[r * nc + q] {
                        continue;
                    }
                    row[q] = if asleep(t) {
                        fixed[q].at(targets[q])
                    } else {
                        self.position(self.node(l, i, g.cols[q]))
                    };
                }
            });
        let mut lagging = Vec::new();
        if lags.contains(&true) {
            for (k, &l) in g.layers.iter().enumerate().filter(|&(_, &l)| l < LAYERS) {
                for (cell, _) in lags.iter().enumerate().filter(|&(_, &x)| x) {
                    let (i, j) = (g.rows[cell / nc], g.cols[cell % nc]);
                    lagging.push(([l, i, j], k * nr * nc + cell));
                }
            }
        }
        (out, lagging)
    }
}
