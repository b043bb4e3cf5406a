//! The membrane's forces (eqs 3-4), one grid row at a time: springs around, along and between
//! layers, point damping, gravity, the attachments and the external forces. The state is only
//! read, so chunks of rows run in parallel, each writing its own rows.
//!
//! The kernel works on whole rows: every spring family of a row is one loop over slices of
//! equal length (positions and velocities of both ends, stiffness, rest length, damping), with
//! no branches and no bounds checks inside, which the compiler turns into SIMD (AVX2 where the
//! CPU has it, chosen at run time). A missing or cut spring has stiffness 0, so its damping
//! (`beta k`) is 0 too, and it adds exactly nothing.
//!
//! Each node's force is summed in a fixed order (the spring from the row before, the springs
//! around, the spring to the row after, the links, then the node's own terms), and a chunk's
//! first row recomputes the spring from the row before it with the same inputs, so the bytes
//! do not depend on how rows are split among threads.

use super::{ALONG, AROUND, LAYERS, LINK, Membrane, field};

/// Read access to the state's rows: `get(l, i)` is row `i` of layer `l`, six runs of `cols`
/// (positions x, y, z, velocities x, y, z).
pub(super) trait Rows: Sync {
    fn get(&self, l: usize, i: usize) -> &[f32];
}

/// A whole state, read only.
pub(super) struct Whole<'a> {
    pub data: &'a [f32],
    pub rows: usize,
    pub cols: usize,
}

impl Rows for Whole<'_> {
    fn get(&self, l: usize, i: usize) -> &[f32] {
        let at = (l * self.rows + i) * 6 * self.cols;
        &self.data[at..at + 6 * self.cols]
    }
}

/// One row of nodes in one layer: positions and velocities, `len` long from a column.
#[derive(Clone, Copy)]
struct Run<'a> {
    x: [&'a [f32]; 3],
    v: [&'a [f32]; 3],
}

impl<'a> Run<'a> {
    #[inline(always)]
    fn of(row: &'a [f32], cols: usize, from: usize, len: usize) -> Run<'a> {
        let part = |c: usize| &row[c * cols + from..c * cols + from + len];
        Run {
            x: [part(0), part(1), part(2)],
            v: [part(3), part(4), part(5)],
        }
    }
}

/// The springs from `a[j]` to `b[j]` for every `j < k.len()`: the force on `a[j]` (the
/// opposite acts on `b[j]`) into `out[c * stride + j]`. Eqs 3-4: `k (|d| - L0)` along `d`
/// plus `beta k (dv . d) / |d|` along it.
#[inline(always)]
fn springs(a: &Run, b: &Run, k: &[f32], rest: &[f32], beta: f32, out: &mut [f32], stride: usize) {
    let (ox, rest_out) = out.split_at_mut(stride);
    let (oy, oz) = rest_out.split_at_mut(stride);
    let [ax, ay, az] = a.x;
    let [avx, avy, avz] = a.v;
    let [bx, by, bz] = b.x;
    let [bvx, bvy, bvz] = b.v;
    spring_loop(
        [ax, ay, az, avx, avy, avz],
        [bx, by, bz, bvx, bvy, bvz],
        k,
        rest,
        beta,
        [ox, oy, oz],
    );
}

/// A spring family's damping time: one for all (a row's) or one a spring (a block's).
pub(super) trait Beta: Copy {
    fn at(self, j: usize) -> f32;
}

impl Beta for f32 {
    #[inline(always)]
    fn at(self, _: usize) -> f32 {
        self
    }
}

impl Beta for &[f32] {
    #[inline(always)]
    fn at(self, j: usize) -> f32 {
        self[j]
    }
}

/// The springs' arithmetic, for the row kernel and the block kernel alike (so both give the
/// same bytes): `a` and `b` are positions then velocities, three components each; the force
/// on `a[j]` into `out`, for every `j < k.len()`.
#[inline(always)]
pub(super) fn spring_loop<B: Beta>(
    a: [&[f32]; 6],
    b: [&[f32]; 6],
    k: &[f32],
    rest: &[f32],
    beta: B,
    out: [&mut [f32]; 3],
) {
    let n = k.len();
    let rest = &rest[..n];
    let [ax, ay, az, avx, avy, avz] = a.map(|v| &v[..n]);
    let [bx, by, bz, bvx, bvy, bvz] = b.map(|v| &v[..n]);
    let [ox, oy, oz] = out;
    let (ox, oy, oz) = (&mut ox[..n], &mut oy[..n], &mut oz[..n]);
    for j in 0..n {
        let (dx, dy, dz) = (bx[j] - ax[j], by[j] - ay[j], bz[j] - az[j]);
        let len = (dx * dx + dy * dy + dz * dz).sqrt();
        let inv = 1.0 / if len > 1e-20 { len } else { 1e-20 };
        let along = (bvx[j] - avx[j]) * dx + (bvy[j] - avy[j]) * dy + (bvz[j] - avz[j]) * dz;
        let s = k[j] * ((len - rest[j]) + beta.at(j) * along * inv) * inv;
        ox[j] = dx * s;
        oy[j] = dy * s;
        oz[j] = dz * s;
    }
}

/// The shear tethers of one middle layer for every element: the force pulling node `nd[j]`
/// sideways (across its column's line from `a[j]`, layer 0, to `b[j]`, layer 3) back onto
/// that line at its weight `wt[j]` along it, into `out`.
#[inline(always)]
pub(super) fn tethers(
    a: [&[f32]; 3],
    b: [&[f32]; 3],
    nd: [&[f32]; 3],
    k: &[f32],
    wt: &[f32],
    out: [&mut [f32]; 3],
) {
    let n = k.len();
    let wt = &wt[..n];
    let [ax, ay, az] = a.map(|v| &v[..n]);
    let [bx, by, bz] = b.map(|v| &v[..n]);
    let [nx, ny, nz] = nd.map(|v| &v[..n]);
    let [sx, sy, sz] = out;
    let (sx, sy, sz) = (&mut sx[..n], &mut sy[..n], &mut sz[..n]);
    for j in 0..n {
        let (ux, uy, uz) = (bx[j] - ax[j], by[j] - ay[j], bz[j] - az[j]);
        let len2 = ux * ux + uy * uy + uz * uz;
        let inv2 = 1.0 / if len2 > 1e-30 { len2 } else { 1e-30 };
        let (dx, dy, dz) = (
            nx[j] - (ax[j] + wt[j] * ux),
            ny[j] - (ay[j] + wt[j] * uy),
            nz[j] - (az[j] + wt[j] * uz),
        );
        let along = (dx * ux + dy * uy + dz * uz) * inv2;
        sx[j] = -k[j] * (dx - along * ux);
        sy[j] = -k[j] * (dy - along * uy);
        sz[j] = -k[j] * (dz - along * uz);
    }
}

/// Lanes of the widest vector unit the kernel is compiled for (AVX2: 8 `f32`).
const LANES: usize = 8;

/// Per-thread buffers of the row kernel.
#[derive(Debug, Clone, Default)]
pub(super) struct RowScratch {
    /// Forces of the current row: `[layer][component][column]`.
    pub f: Vec<f32>,
    /// The along springs' forces on the next row: `[layer][component][column]`.
    carry: Vec<f32>,
    /// One family of springs: `[component][column]`.
    s: Vec<f32>,
}

impl RowScratch {
    fn fit(&mut self, cols: usize) {
        for b in [&mut self.f, &mut self.carry] {
            b.clear();
            b.resize(LAYERS * 3 * cols, 0.0);
        }
        self.s.clear();
        self.s.resize(3 * cols, 0.0);
    }

    /// The forces on layer `l`, component `c` of the current row.
    pub fn row(&self, l: usize, c: usize, cols: usize) -> &[f32] {
        let at = (l * 3 + c) * cols;
        &self.f[at..at + cols]
    }
}

/// The external forces sorted by node, so each row finds its own by bisection.
pub(super) fn sort_external(ext: &mut [(u32, glam::Vec3)]) {
    ext.sort_by_key(|e| e.0);
}

/// The acceleration a node's own terms give it (eq 4's point damping `-D v` and gravity):
/// they scale with its mass, so they are added as accelerations, not forces.
#[inline(always)]
pub(super) fn own_acceleration(p: &super::MembraneParams, c: usize, v: f32) -> f32 {
    p.gravity[c] - p.damping_per_s * v
}

/// Forces on row `i` of every layer, columns `span`, into `sc.f` (at the same columns): the
/// springs, the attachments and the external forces (not the node's own terms,
/// [`own_acceleration`]). Nodes outside `span` are read, not written. `first` says that row
/// `i - 1` was not the last row computed with `sc` over the same span (so its springs to this
/// row are recomputed rather than carried).
///
/// With `LAYER0`, its forces on layer 0 alone (the other layers' rows of `sc.f` are then left
/// meaningless): the same terms summed in the same order, without the work that only the
/// other layers need.
#[inline(always)]
pub(super) fn row<R: Rows, const LAYER0: bool>(
    m: &Membrane,
    state: &R,
    i: usize,
    span: std::ops::Range<usize>,
    first: bool,
    sc: &mut RowScratch,
) {
    // With `LAYER0`, the in-layer springs, the external forces and the attachments of layer
    // 0 only, and its link to layer 1; the tethers of layers 1 and 2 all (they pull on it).
    let (in_plane, links, attached) = if LAYER0 {
        (1, 1, 1)
    } else {
        (LAYERS, LAYERS - 1, 2)
    };
    let (rows, cols) = (m.rows, m.cols);
    let (c0, c1) = (span.start, span.end.min(cols));
    if c0 >= c1 {
        return;
    }
    let w = c1 - c0;
    if sc.s.len() != 3 * cols {
        sc.fit(cols);
    }
    // The springs of a family go over whole vector lanes where the row has the columns: the
    // extra lanes read real nodes further along the row and their results are never read, so
    // a short span (an active set's run) pays no scalar tail, eight times dearer an element.
    let wide = |from: usize, n: usize| {
        let up = n.div_ceil(LANES) * LANES;
        if from + up <= cols { up } else { n }
    };
    let wx = wide(c0, w);
    // `n` of a family's parameters from column `from`.
    let params_n = |b: usize, f: usize, from: usize, n: usize| {
        let at = (b * field::COUNT + f) * cols + from;
        &m.rows_data[at..at + n]
    };
    let around_at = |b: usize, f: usize, j: usize| m.rows_data[(b * field::COUNT + f) * cols + j];
    // The springs from the row before were carried: the carry becomes this row's forces (the
    // old forces' buffer takes the next carry).
    if i > 0 && !first {
        std::mem::swap(&mut sc.f, &mut sc.carry);
    }
    let RowScratch { f, carry, s } = sc;
    // `f`, `carry` and `s` hold a run of `cols` per component; this span is `c0..c1` of it.
    for l in 0..in_plane {
        let b = l * rows + i;
        let fl = &mut f[l * 3 * cols..(l + 1) * 3 * cols];
        let cl = &mut carry[l * 3 * cols..(l + 1) * 3 * cols];
        let here_row = state.get(l, i);
        let here = Run::of(here_row, cols, c0, wx);
        // The spring from the row before.
        if i == 0 {
            for c in 0..3 {
                fl[c * cols + c0..c * cols + c1].fill(0.0);
            }
        } else if first {
            let before = Run::of(state.get(l, i - 1), cols, c0, wx);
            let (k, rest) = (
                params_n(b - 1, field::K[ALONG], c0, wx),
                params_n(b - 1, field::REST[ALONG], c0, wx),
            );
            springs(&before, &here, k, rest, m.beta[b - 1][ALONG], s, cols);
            for c in 0..3 {
                let r = c * cols..c * cols + w;
                for (o, v) in fl[c * cols + c0..c * cols + c1].iter_mut().zip(&s[r]) {
                    *o = -v;
                }
            }
        }
        // Around: column j to j + 1 inside the span in one loop; the springs that cross its
        // two edges (to the columns beside it, or round the ring) on their own.
        let beta = m.beta[b][AROUND];
        if w > 1 {
            let n = wide(c0 + 1, w - 1);
            let (k, rest) = (
                params_n(b, field::K[AROUND], c0, n),
                params_n(b, field::REST[AROUND], c0, n),
            );
            let (a, bb) = (
                Run::of(here_row, cols, c0, n),
                Run::of(here_row, cols, c0 + 1, n),
            );
            springs(&a, &bb, k, rest, beta, s, cols);
            for c in 0..3 {
                // Node j gets spring j and loses spring j - 1.
                let fc = &mut fl[c * cols + c0..c * cols + c1];
                let sc = &s[c * cols..c * cols + w - 1];
                fc[0] += sc[0];
                for ((o, a), b) in fc[1..w - 1].iter_mut().zip(&sc[1..]).zip(sc) {
                    *o += a - b;
                }
                fc[w - 1] -= sc[w - 2];
            }
        }
        // The spring into the span's first column and the one out of its last.
        let left = (c0 + cols - 1) % cols;
        let right = c1 - 1;
        for (from, to, into) in [(left, c0, c0), (right, c1 % cols, right)] {
            let k = around_at(b, field::K[AROUND], from);
            if k <= 0.0 {
                continue;
            }
            let rest = around_at(b, field::REST[AROUND], from);
            let (a, bb) = (
                Run::of(here_row, cols, from, 1),
                Run::of(here_row, cols, to, 1),
            );
            springs(&a, &bb, &[k], &[rest], beta, s, cols);
            let sign = if into == from { 1.0 } else { -1.0 };
            for c in 0..3 {
                fl[c * cols + into] += sign * s[c * cols];
            }
        }
        // Along: to the next row, whose share is carried.
        if i + 1 < rows {
            let next = Run::of(state.get(l, i + 1), cols, c0, wx);
            let (k, rest) = (
                params_n(b, field::K[ALONG], c0, wx),
                params_n(b, field::REST[ALONG], c0, wx),
            );
            springs(&here, &next, k, rest, m.beta[b][ALONG], s, cols);
            for c in 0..3 {
                let r = c * cols + c0..c * cols + c1;
                let sv = &s[c * cols..c * cols + w];
                for ((o, cv), v) in fl[r.clone()].iter_mut().zip(&mut cl[r]).zip(sv) {
                    *o += v;
                    *cv = -v;
                }
            }
        }
    }
    // Links between layers at this row.
    for l in 0..links {
        let b = l * rows + i;
        let a = Run::of(state.get(l, i), cols, c0, wx);
        let bb = Run::of(state.get(l + 1, i), cols, c0, wx);
        let (k, rest) = (
            params_n(b, field::K[LINK], c0, wx),
            params_n(b, field::REST[LINK], c0, wx),
        );
        springs(&a, &bb, k, rest, m.beta[b][LINK], s, cols);
        let (lower, upper) = f.split_at_mut((l + 1) * 3 * cols);
        let fa = &mut lower[l * 3 * cols..];
        let fb = &mut upper[..3 * cols];
        for c in 0..3 {
            let r = c * cols + c0..c * cols + c1;
            let sv = &s[c * cols..c * cols + w];
            for ((oa, ob), v) in fa[r.clone()].iter_mut().zip(&mut fb[r]).zip(sv) {
                *oa += v;
                *ob -= v;
            }
        }
    }
    // The shear tethers of layers 1 and 2: each node pulled sideways (across its column's
    // line from layer 0 to layer 3) back onto that line; the reaction shared by the column's
    // layer-0 and layer-3 nodes in proportion to where on the line it is.
    for l in 1..LAYERS - 1 {
        let b = l * rows + i;
        let (k, wt) = (
            params_n(b, field::SHEAR_K, c0, wx),
            params_n(b, field::SHEAR_W, c0, wx),
        );
        let (x0, xl, x3) = (state.get(0, i), state.get(l, i), state.get(LAYERS - 1, i));
        fn px(r: &[f32], c: usize, cols: usize, c0: usize, n: usize) -> &[f32] {
            &r[c * cols + c0..c * cols + c0 + n]
        }
        let px = |r, c| px(r, c, cols, c0, wx);
        let (sx, rest_s) = s.split_at_mut(cols);
        let (sy, sz) = rest_s.split_at_mut(cols);
        tethers(
            [px(x0, 0), px(x0, 1), px(x0, 2)],
            [px(x3, 0), px(x3, 1), px(x3, 2)],
            [px(xl, 0), px(xl, 1), px(xl, 2)],
            &k[..wx],
            &wt[..wx],
            [&mut sx[..wx], &mut sy[..wx], &mut sz[..wx]],
        );
        for c in 0..3 {
            let sv = &s[c * cols..c * cols + w];
            let r = c * cols + c0..c * cols + c1;
            let (lower, upper) = f.split_at_mut(l * 3 * cols);
            let (mid, top) = upper.split_at_mut(3 * cols);
            let f0 = &mut lower[r.clone()];
            let fm = &mut mid[r.clone()];
            let f3 = &mut top[(LAYERS - 2 - l) * 3 * cols..][r];
            for j in 0..w {
                fm[j] += sv[j];
                f0[j] -= (1.0 - wt[j]) * sv[j];
                f3[j] -= wt[j] * sv[j];
            }
        }
    }
    // The attachments (a node's point damping and gravity are its own: see
    // [`own_acceleration`]).
    for (slot, l) in [(0usize, 0usize), (1, LAYERS - 1)]
        .into_iter()
        .take(attached)
    {
        let x = state.get(l, i);
        let at = (slot * rows + i) * 4 * cols;
        let attach = &m.attach[at..at + 4 * cols];
        let ka = &attach[c0..c1];
        for c in 0..3 {
            let fc = &mut f[(l * 3 + c) * cols + c0..(l * 3 + c) * cols + c1];
            let (x, tg) = (
                &x[c * cols + c0..c * cols + c1],
                &attach[(1 + c) * cols + c0..(1 + c) * cols + c1],
            );
            for j in 0..w {
                fc[j] -= ka[j] * (x[j] - tg[j]);
            }
        }
    }
    for l in 0..in_plane {
        let base = (l * rows + i) * cols;
        // External forces on this row of this layer, inside the span.
        let from = m.external.partition_point(|e| (e.0 as usize) < base + c0);
        for &(node, fe) in m.external[from..]
            .iter()
            .take_while(|e| (e.0 as usize) < base + c1)
        {
            let j = node as usize - base;
            for c in 0..3 {
                f[(l * 3 + c) * cols + j] += fe[c];
            }
        }
    }
}
