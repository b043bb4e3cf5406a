//! The active set's passes over many tiles at once (`active.rs`), row block by row block of
//! the grid: each block's rows are its own, so the blocks run in parallel where the tiles are
//! many, and the bytes are those of a pass tile by tile.

use super::{Activity, anchors_into, worth_threads};
use crate::models::membrane::{LAYERS, Membrane};
use glam::Vec3;

/// What a tile's sleep and wake checks measure: its fastest node relative to its anchor
/// (m/s), how far its edge nodes moved from where they were when it woke (m), the box round
/// its nodes, and whether all their positions are finite (the quarantine's check, where a
/// device measured the tile; the CPU's own check reads the positions).
#[derive(Debug, Clone, Copy)]
pub(in crate::models::membrane) struct Watch {
    pub fastest: f32,
    pub edge: f32,
    pub lo: Vec3,
    pub hi: Vec3,
    pub finite: bool,
}

impl Watch {
    const NONE: Watch = Watch {
        fastest: 0.0,
        edge: 0.0,
        lo: Vec3::splat(f32::MAX),
        hi: Vec3::splat(f32::MIN),
        finite: true,
    };

    /// Both measures together (maxima and minima: the same in any order).
    fn and(self, o: Watch) -> Watch {
        Watch {
            fastest: self.fastest.max(o.fastest),
            edge: self.edge.max(o.edge),
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            finite: self.finite && o.finite,
        }
    }
}

/// Row `i` of layer `l` in the tiles `run` (each `(k, t)`: its place in the list and the
/// tile; side by side in one row of tiles, left to right) measured ([`Watch`], pushed in
/// order with `k` onto `out`) after a step of `dt`; their nodes' offsets from their anchors
/// now go into `last` (this row block's three component rows of `Activity::last`), and `now`
/// is scratch. Each tile's measure is taken over its own nodes in their order, as tile by
/// tile; the run shares the loops over the anchors.
fn watch_run(
    m: &Membrane,
    a: &Activity,
    (run, l, i): (&[(usize, usize)], usize, usize),
    dt: f32,
    (last, now): (&mut [f32], &mut Vec<f32>),
    out: &mut Vec<(usize, Watch)>,
) {
    let (rows, cols) = (m.rows, m.cols);
    let (Some(&(_, first)), Some(&(_, end))) = (run.first(), run.last()) else {
        return;
    };
    let ([r0, r1], [c0, _]) = a.span(first, rows, cols);
    let (_, [_, c1]) = a.span(end, rows, cols);
    let b = l * rows + i;
    let w = c1 - c0;
    // Three component rows of offsets now, then each node's squared speed and move.
    now.resize(5 * w, 0.0);
    // Each node's offset from its anchor now, by component.
    for c in 0..3 {
        let out = &mut now[c * w..(c + 1) * w];
        anchors_into(m, a, l, i, [c0, c1], c, out);
        let x = &m.state.data[(b * 6 + c) * cols + c0..(b * 6 + c) * cols + c1];
        for (o, x) in out.iter_mut().zip(x) {
            *o = x - *o;
        }
    }
    let border_row = i == r0 || i + 1 == r1;
    let in_run = |c: usize| c * cols + c0..c * cols + c1;
    let (n0, rest) = now.split_at_mut(w);
    let (n1, rest) = rest.split_at_mut(w);
    let (n2, rest) = rest.split_at_mut(w);
    let (fast, moved) = rest.split_at_mut(w);
    let (l0, l1, l2) = (&last[in_run(0)], &last[in_run(1)], &last[in_run(2)]);
    let row3 = |c: usize| (b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1;
    let (o0, o1, o2) = (&a.offset[row3(0)], &a.offset[row3(1)], &a.offset[row3(2)]);
    // Squared lengths, node by node over the run ([`squared`]). Squared: the root of the
    // largest is the largest root (a rounded root is monotonic), so one root a tile gives
    // the same bytes as one a node.
    let (n0, n1, n2) = (&*n0, &*n1, &*n2);
    squared(fast, [n0, n1, n2], [l0, l1, l2]);
    let mv = |j: usize| {
        let (x, y, z) = (n0[j] - o0[j], n1[j] - o1[j], n2[j] - o2[j]);
        x * x + y * y + z * z
    };
    if border_row {
        squared(moved, [n0, n1, n2], [o0, o1, o2]);
    }
    let most = |v: &[f32]| v.iter().fold(0.0f32, |m, &x| m.max(x));
    let x = |c: usize| &m.state.data[(b * 6 + c) * cols + c0..(b * 6 + c) * cols + c1];
    let (x0, x1, x2) = (x(0), x(1), x(2));
    for &(k, t) in run {
        let (_, [t0, t1]) = a.span(t, rows, cols);
        let (j0, j1) = (t0 - c0, t1 - c0);
        let mut watch = Watch::NONE;
        watch.fastest = most(&fast[j0..j1]).sqrt() / dt;
        let edge = if border_row {
            most(&moved[j0..j1])
        } else {
            0.0f32.max(mv(j0)).max(mv(j1 - 1))
        };
        watch.edge = edge.sqrt();
        for j in j0..j1 {
            let p = Vec3::new(x0[j], x1[j], x2[j]);
            watch.lo = watch.lo.min(p);
            watch.hi = watch.hi.max(p);
            watch.finite &= p.is_finite();
        }
        out.push((k, watch));
    }
    for c in 0..3 {
        last[in_run(c)].copy_from_slice(&now[c * w..(c + 1) * w]);
    }
}

/// Each node's squared length of `p - q` (three component rows each) into `out`, summed
/// as `Vec3::length_squared` sums it, in a loop the compiler vectorises.
#[inline(always)]
fn squared(out: &mut [f32], [p0, p1, p2]: [&[f32]; 3], [q0, q1, q2]: [&[f32]; 3]) {
    let n = out.len();
    let (p0, p1, p2, q0, q1, q2) = (&p0[..n], &p1[..n], &p2[..n], &q0[..n], &q1[..n], &q2[..n]);
    for k in 0..n {
        let (x, y, z) = (p0[k] - q0[k], p1[k] - q1[k], p2[k] - q2[k]);
        out[k] = x * x + y * y + z * z;
    }
}

/// `tiles` (a row of tiles' awake tiles, `(k, t)`, left to right) cut into runs of tiles
/// side by side.
fn runs_of(tiles: &[(usize, usize)]) -> impl Iterator<Item = &[(usize, usize)]> {
    tiles.chunk_by(|a, b| b.1 == a.1 + 1)
}

/// Every awake tile measured ([`Watch`], in the order of `a.list`) after a step of `dt`,
/// row block by row block (in parallel where the tiles are many: each block's rows are its
/// own, and the measures are maxima and minima, so the bytes are the same).
pub(super) fn watch_all(m: &Membrane, a: &mut Activity, dt: f32) -> Vec<Watch> {
    use rayon::prelude::*;
    let (rows, cols) = (m.rows, m.cols);
    let tr = a.params.tile_rows;
    let by_row = a.by_tile_row(a.list.iter().map(|&t| t as usize));
    let mut last = std::mem::take(&mut a.last);
    let a_ref = &*a;
    let one = |now: &mut Vec<f32>, (b, block): (usize, &mut [f32])| -> Vec<(usize, Watch)> {
        let (l, i) = (b / rows, b % rows);
        let mut out = Vec::new();
        for run in runs_of(by_row.of(i)) {
            watch_run(
                m,
                a_ref,
                (run, l, i),
                dt,
                (&mut *block, &mut *now),
                &mut out,
            );
        }
        out
    };
    let nodes = a.list.len() * LAYERS * tr * a.params.tile_cols;
    let blocks: Vec<Vec<(usize, Watch)>> = if worth_threads(nodes) {
        last.par_chunks_mut(3 * cols)
            .enumerate()
            .map_init(Vec::new, one)
            .collect()
    } else {
        let mut now = Vec::new();
        last.chunks_mut(3 * cols)
            .enumerate()
            .map(|bb| one(&mut now, bb))
            .collect()
    };
    a.last = last;
    // Each tile's rows in order of layer and row, as one pass over the tile takes them.
    let mut watch = vec![Watch::NONE; a.list.len()];
    for (k, w) in blocks.into_iter().flatten() {
        watch[k] = watch[k].and(w);
    }
    watch
}

/// [`place_asleep`] for each tile of `tiles`, row block by row block (in parallel where the
/// tiles are many: each node is written once, so the bytes are the same).
pub(super) fn place_all_asleep(m: &mut Membrane, a: &Activity, tiles: &[usize]) {
    use rayon::prelude::*;
    super::super::chain::place(m, Some(a), tiles);
    for &t in tiles {
        m.device.tile_changed(t);
        m.nodes_changed(t);
    }
    let (rows, cols) = (m.rows, m.cols);
    let tr = a.params.tile_rows;
    let by_row = a.by_tile_row(tiles.iter().copied());
    // The anchors read the targets and the rest shape, never the state: the state is taken
    // out while the rows are written.
    let mut data = std::mem::take(&mut m.state.data);
    let whole = &*m;
    let one = |anchor: &mut Vec<f32>, (b, x): (usize, &mut [f32])| {
        let (l, i) = (b / rows, b % rows);
        for &(_, t) in by_row.of(i) {
            let (_, [c0, c1]) = a.span(t, rows, cols);
            anchor.resize(c1 - c0, 0.0);
            for c in 0..3 {
                anchors_into(whole, a, l, i, [c0, c1], c, anchor);
                let off = &a.offset[(b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1];
                let at = &mut x[c * cols + c0..c * cols + c1];
                for ((x, p), o) in at.iter_mut().zip(anchor.iter()).zip(off) {
                    *x = p + o;
                }
                x[(3 + c) * cols + c0..(3 + c) * cols + c1].fill(0.0);
            }
        }
    };
    if worth_threads(tiles.len() * LAYERS * tr * a.params.tile_cols) {
        data.par_chunks_mut(6 * cols)
            .enumerate()
            .for_each_init(Vec::new, one);
    } else {
        let mut anchor = Vec::new();
        data.chunks_mut(6 * cols)
            .enumerate()
            .for_each(|bx| one(&mut anchor, bx));
    }
    m.state.data = data;
}

/// Tile `t`'s nodes' offsets from their anchors now into `Activity::offset` (a tile falling
/// asleep where its last measure was taken on a device: the same values its watch's `now`
/// holds there, up to the device's rounding).
pub(super) fn offsets_now(m: &Membrane, a: &mut Activity, t: usize) {
    let (rows, cols) = (m.rows, m.cols);
    let ([r0, r1], [c0, c1]) = a.span(t, rows, cols);
    let mut now = vec![0.0; c1 - c0];
    for l in 0..LAYERS {
        for i in r0..r1 {
            let b = l * rows + i;
            for c in 0..3 {
                anchors_into(m, a, l, i, [c0, c1], c, &mut now);
                let x = &m.state.data[(b * 6 + c) * cols + c0..(b * 6 + c) * cols + c1];
                let off = &mut a.offset[(b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1];
                for ((o, x), p) in off.iter_mut().zip(x).zip(&now) {
                    *o = x - p;
                }
            }
        }
    }
}
