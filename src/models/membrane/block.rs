//! The active set's block kernel: a rectangle of the grid (rows `r0..r1`, columns `c0..c1`,
//! every layer) holding one or more runs of awake tiles, stepped as one block, its nodes side
//! by side with a ring of one node around them, as the GPU's kernels see a tile.
//!
//! The row kernel ([`super::forces::row`]) pays a fixed cost for each of its some eighty
//! short loops on every row, which on a run a few tiles wide outweighs the arithmetic. Here
//! every spring family of the whole block is one loop: the block's state is gathered into
//! `[layer][component][(rows + 2) x (width + 2)]` (the ring's nodes are the neighbours' or,
//! round the section, the wrapped columns), its parameters once a step (the attachments'
//! targets; the springs, tethers and masses only when the block's span or the membrane's
//! springs changed). After a substep the
//! runs' nodes keep their new state in the block; the ring and the sleeping nodes between
//! the runs keep what the step's first substep read (their forces are found with the rest,
//! but they never move), and where they hold another run's nodes they are read again from
//! the membrane (`active_share.rs` says where).
//!
//! Each node's force is summed in exactly the row kernel's order (the spring from the row
//! before, the springs around with each run's two edge springs on their own, the spring to
//! the row after, the links, the tethers, the attachments, the external forces), so a step
//! gives the same bytes as the row kernel's and the whole grid's.

use super::{ALONG, AROUND, LAYERS, LINK, Membrane, field};
use glam::Vec3;

/// Per layer, its parameters in the block: stiffness, rest length and damping time of the
/// springs around, along and to the next layer, the tether's stiffness and weight, 1 / mass.
const KA: usize = 0;
const KL: usize = 3;
const KK: usize = 6;
const SK: usize = 9;
const SW: usize = 10;
const IM: usize = 11;
const PER_LAYER: usize = 12;
/// After the layers' parameters: the attachments of layers 0 and 3 (stiffness, target x,
/// y, z each).
const ATTACH: usize = LAYERS * PER_LAYER;
const FIELDS: usize = ATTACH + 8;

/// A block's rows and columns in the membrane.
type Span = ([usize; 2], [usize; 2]);

/// One run's block: its parameters (gathered once a step), its state and forces, and its
/// new state after a substep.
#[derive(Debug, Clone, Default)]
pub(super) struct Block {
    span: ([usize; 2], [usize; 2]),
    /// Columns a block row (the run's width and its two ring columns).
    stride: usize,
    /// The ring's two columns in the membrane (wrapped round the section).
    ring_cols: [usize; 2],
    /// Nodes a layer of the block.
    n: usize,
    par: Vec<f32>,
    /// External forces on the block's nodes (block index, layer, force), in the order the
    /// row kernel adds them.
    ext: Vec<(u32, u8, Vec3)>,
    /// State `[layer][6][n]`: the substep's start, then (interior rows) its end.
    x: Vec<f32>,
    out: Vec<f32>,
    /// Forces `[layer][3][n]`, and one family of springs `[3][n]` (two at a time).
    f: Vec<f32>,
    s: Vec<f32>,
    t: Vec<f32>,
    /// The awake runs in the block, each a row's columns: (block row, first column, end
    /// column), block columns, by row; and the rest of each own row (the sleeping nodes
    /// between them and the ring's two columns). No substep writes the gaps, so both state
    /// buffers keep what the step's first read there; `live_gaps` (all the gaps, unless
    /// [`super::active`] says which of their nodes belong to some block's runs) are read
    /// from the membrane again at every substep.
    segs: Vec<(usize, usize, usize)>,
    gaps: Vec<(usize, usize, usize)>,
    pub(super) live_gaps: Vec<(usize, usize, usize)>,
    /// Per block node, 1 on the runs' nodes (`segs`), else 0.
    own: Vec<u8>,
    /// Each run row's first and last forces before the springs around are added.
    edge: Vec<[f32; 2]>,
    /// A substep has run since [`Block::prepare`] (`out` holds its end).
    stepped: bool,
    /// Whether the step's first substep keeps layer 0's loads (`loads`, `[3][n]`: the
    /// forces on each node of its runs less its attachment's, as
    /// [`Membrane::loads_over_runs`] gives them).
    keep_loads: bool,
    loads: Vec<f32>,
    /// The nodes of this block's runs that some block (this one too, where its ring wraps
    /// round the section onto itself) reads from the membrane during the step: (row,
    /// column), sorted. Each substep writes these back; the step's last writes all.
    pub(super) exports: Vec<(u32, u32)>,
    /// The ring's two rows hold nodes of some block's runs, so each substep reads them
    /// again; otherwise they are sleeping nodes, which keep their state through the step.
    pub(super) ring_rows_live: bool,
    /// The span and the membrane's springs version ([`Membrane::springs_version`]) the
    /// springs, tethers and masses in `par` were gathered for: while both stay the same, a
    /// step gathers only the attachments (whose targets move every step).
    par_for: Option<(Span, u64)>,
}

impl Block {
    /// The parameters as gathered (tests compare a kept block's with a fresh one's).
    #[cfg(test)]
    pub fn params(&self) -> &[f32] {
        &self.par
    }

    pub fn heap_bytes(&self) -> usize {
        (self.par.capacity()
            + self.x.capacity()
            + self.out.capacity()
            + self.f.capacity()
            + self.s.capacity()
            + self.t.capacity()
            + self.loads.capacity())
            * std::mem::size_of::<f32>()
    }

    fn rows(&self) -> usize {
        self.span.0[1] - self.span.0[0]
    }

    /// The global row of block row `r`, if there is one.
    fn global_row(&self, m: &Membrane, r: usize) -> Option<usize> {
        (self.span.0[0] + r).checked_sub(1).filter(|&i| i < m.rows)
    }

    /// Copies the `cols`-long run `src` (a row of the state or of a parameter) at the block's
    /// columns (the ring's two wrapped round the section) into `dst`.
    fn gather_row(&self, src: &[f32], dst: &mut [f32]) {
        let [c0, c1] = self.span.1;
        let ([left, right], w) = (self.ring_cols, c1 - c0);
        dst[0] = src[left];
        dst[1..=w].copy_from_slice(&src[c0..c1]);
        dst[w + 1] = src[right];
    }

    /// Sets the block up for this step's substeps over `span`, whose awake nodes are the
    /// runs `runs` (rows, columns: each a row of tiles' awake run, inside `span`; the rest of
    /// the block is stepped but never written back): the springs (cuts happen between
    /// steps), the attachments' targets and the external forces.
    pub fn prepare(
        &mut self,
        m: &Membrane,
        span: ([usize; 2], [usize; 2]),
        runs: &[([usize; 2], [usize; 2])],
    ) {
        let (rows, cols) = (m.rows, m.cols);
        self.span = span;
        let ([r0, r1], [c0, c1]) = span;
        self.ring_cols = [(c0 + cols - 1) % cols, c1 % cols];
        let w = c1 - c0;
        self.stride = w + 2;
        self.n = (r1 - r0 + 2) * self.stride;
        let n = self.n;
        // Every value is written below (or a row past the membrane's edge zeroed): the
        // buffers keep their old contents rather than being cleared each step. The springs
        // change only between steps, with the membrane's springs version.
        self.par.resize(FIELDS * n, 0.0);
        let key = (span, m.springs_version);
        let springs = self.par_for != Some(key);
        self.par_for = Some(key);
        let mut par = std::mem::take(&mut self.par);
        for r in 0..r1 - r0 + 2 {
            let at = r * self.stride;
            let Some(i) = self.global_row(m, r) else {
                if springs {
                    for fld in 0..FIELDS {
                        par[fld * n + at..][..self.stride].fill(0.0);
                    }
                }
                continue;
            };
            for l in (0..LAYERS).filter(|_| springs) {
                let b = l * rows + i;
                let base = l * PER_LAYER;
                for fam in [AROUND, ALONG, LINK] {
                    let slot = base + KA + 3 * fam;
                    for (d, fld) in [field::K[fam], field::REST[fam]].into_iter().enumerate() {
                        let src = &m.rows_data[(b * field::COUNT + fld) * cols..][..cols];
                        self.gather_row(src, &mut par[(slot + d) * n + at..][..self.stride]);
                    }
                    par[(slot + 2) * n + at..][..self.stride].fill(m.beta[b][fam]);
                }
                for (slot, fld) in [
                    (SK, field::SHEAR_K),
                    (SW, field::SHEAR_W),
                    (IM, field::INV_MASS),
                ] {
                    let src = &m.rows_data[(b * field::COUNT + fld) * cols..][..cols];
                    self.gather_row(src, &mut par[(base + slot) * n + at..][..self.stride]);
                }
            }
            for s in 0..2 {
                for c in 0..4 {
                    let src = &m.attach[((s * rows + i) * 4 + c) * cols..][..cols];
                    let dst = &mut par[(ATTACH + s * 4 + c) * n + at..][..self.stride];
                    self.gather_row(src, dst);
                }
            }
        }
        self.par = par;
        // The external forces, sorted by node (stable: one node's in the order given).
        self.ext.clear();
        for &(node, fe) in &m.external {
            let node = node as usize;
            let (b, j) = (node / cols, node % cols);
            let (l, i) = (b / rows, b % rows);
            if l < LAYERS && (r0..r1).contains(&i) && (c0..c1).contains(&j) {
                let k = (i - r0 + 1) * self.stride + (j - c0 + 1);
                self.ext.push((k as u32, l as u8, fe));
            }
        }
        for v in [&mut self.x, &mut self.out] {
            v.resize(LAYERS * 6 * n, 0.0);
        }
        self.f.resize(LAYERS * 3 * n, 0.0);
        for v in [&mut self.s, &mut self.t] {
            v.resize(3 * n, 0.0);
        }
        // The awake runs by block row, and the gaps between them.
        self.segs.clear();
        for &([a0, a1], [b0, b1]) in runs {
            for i in a0..a1 {
                self.segs.push((i - r0 + 1, b0 - c0 + 1, b1 - c0 + 1));
            }
        }
        self.segs.sort_unstable();
        self.gaps.clear();
        let mut k = 0;
        for r in 1..=r1 - r0 {
            let mut from = 0;
            while k < self.segs.len() && self.segs[k].0 == r {
                let (_, qa, qb) = self.segs[k];
                if qa > from {
                    self.gaps.push((r, from, qa));
                }
                from = qb;
                k += 1;
            }
            self.gaps.push((r, from, w + 2));
        }
        self.edge.resize(self.segs.len(), [0.0; 2]);
        self.own.clear();
        self.own.resize(n, 0);
        for &(r, qa, qb) in &self.segs {
            self.own[r * self.stride + qa..r * self.stride + qb].fill(1);
        }
        self.stepped = false;
        self.keep_loads = false;
        self.exports.clear();
        self.ring_rows_live = true;
        self.live_gaps.clone_from(&self.gaps);
    }

    /// The step's first substep keeps layer 0's loads on the block's runs (read them with
    /// [`Block::load`]); [`Block::prepare`] turns this off.
    pub fn keep_loads(&mut self) {
        self.keep_loads = true;
        self.loads.resize(3 * self.n, 0.0);
    }

    /// Layer 0's load at row `i`, column `j` (a node of one of the block's runs) kept by the
    /// step's first substep ([`Block::keep_loads`]): what the rest of the membrane does to
    /// it at the step's start, the attachment left out, N.
    pub fn load(&self, i: usize, j: usize) -> Vec3 {
        let k = self.at(i, j);
        Vec3::new(
            self.loads[k],
            self.loads[self.n + k],
            self.loads[2 * self.n + k],
        )
    }

    /// Layer 0's loads from the forces of the first substep (`f`, the attachment's force
    /// `-k (x - target)` in it, taken out here as [`Membrane::loads_over_runs`] takes it).
    fn take_loads(&mut self) {
        let (n, p) = (self.n, self.stride);
        for &(r, qa, qb) in &self.segs {
            let at = r * p;
            let ka = &self.par[ATTACH * n + at..][qa..qb];
            for c in 0..3 {
                let tg = &self.par[(ATTACH + 1 + c) * n + at..][qa..qb];
                let x = &self.x[c * n + at..][qa..qb];
                let f = &self.f[c * n + at..][qa..qb];
                let out = &mut self.loads[c * n + at..][qa..qb];
                for ((((o, f), k), x), t) in out.iter_mut().zip(f).zip(ka).zip(x).zip(tg) {
                    *o = f + k * (x - t);
                }
            }
        }
    }

    /// The state at a substep's start: gathered whole at the step's first; after that the
    /// last substep's end for the block's own nodes and, for its ring (other runs' nodes,
    /// or sleeping ones), the membrane's.
    fn start_substep(&mut self, m: &Membrane) {
        if !self.stepped {
            self.gather_state(m);
            return;
        }
        std::mem::swap(&mut self.x, &mut self.out);
        let (rows, cols, n, p) = (m.rows, m.cols, self.n, self.stride);
        let rr = self.rows();
        let mut x = std::mem::take(&mut self.x);
        if self.ring_rows_live {
            self.gather_rows(m, &mut x, [0, rr + 1]);
        }
        let [c0, c1] = self.span.1;
        let ([left, right], w) = (self.ring_cols, c1 - c0);
        for &(r, qa, qb) in &self.live_gaps {
            let i = self.span.0[0] + r - 1;
            // The ring's columns (wrapped round the section) and the columns between.
            let (ends, mid) = ([qa == 0, qb == w + 2], qa.max(1)..qb.min(w + 1));
            for l in 0..LAYERS {
                let b = l * rows + i;
                for c in 0..6 {
                    let src = &m.state.data[(b * 6 + c) * cols..][..cols];
                    let dst = &mut x[(l * 6 + c) * n + r * p..][..p];
                    if ends[0] {
                        dst[0] = src[left];
                    }
                    if ends[1] {
                        dst[w + 1] = src[right];
                    }
                    if mid.start < mid.end {
                        dst[mid.clone()]
                            .copy_from_slice(&src[c0 + mid.start - 1..c0 + mid.end - 1]);
                    }
                }
            }
        }
        self.x = x;
    }

    /// The block's state (and its ring's) from the membrane's, into both buffers (a
    /// substep writes only the runs' nodes, so the rest stays as read here unless it is read
    /// again).
    fn gather_state(&mut self, m: &Membrane) {
        let mut x = std::mem::take(&mut self.x);
        self.gather_rows(m, &mut x, 0..self.rows() + 2);
        self.out.copy_from_slice(&x);
        self.x = x;
    }

    /// Block rows `rows_of` of the state into `x` (zeros for a row past the membrane's edge).
    fn gather_rows(&self, m: &Membrane, x: &mut [f32], rows_of: impl IntoIterator<Item = usize>) {
        let (rows, cols, n) = (m.rows, m.cols, self.n);
        for r in rows_of {
            let at = r * self.stride;
            match self.global_row(m, r) {
                Some(i) => {
                    for l in 0..LAYERS {
                        let b = l * rows + i;
                        for c in 0..6 {
                            let src = &m.state.data[(b * 6 + c) * cols..][..cols];
                            self.gather_row(src, &mut x[(l * 6 + c) * n + at..][..self.stride]);
                        }
                    }
                }
                None => {
                    for lc in 0..LAYERS * 6 {
                        x[lc * n + at..][..self.stride].fill(0.0);
                    }
                }
            }
        }
    }

    /// The block index of the membrane's row `i`, column `j` (inside the block's span).
    fn at(&self, i: usize, j: usize) -> usize {
        let ([r0, _], [c0, _]) = self.span;
        (i + 1 - r0) * self.stride + (j + 1 - c0)
    }

    /// Writes the new state of the nodes [`Block::exports`] lists into the membrane's.
    pub fn scatter_exports(&self, m: &mut Membrane) {
        let (rows, cols, n) = (m.rows, m.cols, self.n);
        for &(i, j) in &self.exports {
            let (i, j) = (i as usize, j as usize);
            let k = self.at(i, j);
            for l in 0..LAYERS {
                let b = l * rows + i;
                for c in 0..6 {
                    m.state.data[(b * 6 + c) * cols + j] = self.out[(l * 6 + c) * n + k];
                }
            }
        }
    }

    /// Writes the block's new state (its own nodes) into the membrane's.
    pub fn scatter(&self, m: &mut Membrane) {
        let (rows, cols, n, p) = (m.rows, m.cols, self.n, self.stride);
        let ([r0, _], [c0, _]) = self.span;
        for &(r, qa, qb) in &self.segs {
            let i = r0 + r - 1;
            for l in 0..LAYERS {
                let b = l * rows + i;
                for c in 0..6 {
                    m.state.data[(b * 6 + c) * cols + c0 + qa - 1..][..qb - qa]
                        .copy_from_slice(&self.out[(l * 6 + c) * n + r * p + qa..][..qb - qa]);
                }
            }
        }
    }
}

/// The springs from `a` to `b` (positions and velocities, three components each) for every
/// element: the force on `a` into `o`. Eqs 3-4, as the row kernel computes them.
#[inline(always)]
fn springs(a: [&[f32]; 6], b: [&[f32]; 6], p: [&[f32]; 3], o: &mut [f32], n: usize) {
    let [k, rest, beta] = p.map(|v| &v[..n]);
    let (ox, rest_o) = o.split_at_mut(o.len() / 3);
    let (oy, oz) = rest_o.split_at_mut(rest_o.len() / 2);
    super::forces::spring_loop(a, b, k, rest, beta, [ox, oy, oz]);
}

/// A block's substep of `h`, compiled for the widest vector unit the CPU has.
pub(super) struct BlockPass<'a> {
    pub m: &'a Membrane,
    pub block: &'a mut Block,
    pub h: f32,
}

impl pulp::WithSimd for BlockPass<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) {
        let BlockPass { m, block, h } = self;
        block.start_substep(m);
        forces(m, block);
        if block.keep_loads && !block.stepped {
            block.take_loads();
        }
        advance(m, block, h);
        block.stepped = true;
    }
}

/// The forces on the block's own rows (its ring's and its sleeping nodes' are meaningless).
#[inline(always)]
fn forces(m: &Membrane, bk: &mut Block) {
    let (n, p) = (bk.n, bk.stride);
    let rr = bk.rows();
    let [r0, r1] = bk.span.0;
    let Block {
        par,
        ext,
        x,
        f,
        s,
        t,
        edge,
        segs,
        ..
    } = bk;
    let (par, x) = (&par[..], &x[..]);
    let pr = |l: usize, q: usize| &par[(l * PER_LAYER + q) * n..][..n];
    // Layer `l`'s state from block index `from`.
    let xs = |l: usize, from: usize| -> [&[f32]; 6] {
        std::array::from_fn(|c| &x[(l * 6 + c) * n + from..(l * 6 + c + 1) * n])
    };
    let own = p..(rr + 1) * p;
    // The rows whose spring to the next row exists (the membrane's last row has none).
    let along_end = if r1 < m.rows { rr + 1 } else { rr } * p;
    for l in 0..LAYERS {
        let fl = &mut f[l * 3 * n..(l + 1) * 3 * n];
        // Along, from every block row but the last to the next: `s`.
        let fam = |q: usize, from: usize, len: usize| -> [&[f32]; 3] {
            std::array::from_fn(|d| &pr(l, q + d)[from..from + len])
        };
        let len = (rr + 1) * p;
        springs(xs(l, 0), xs(l, p), fam(KL, 0, len), s, len);
        // Around, from each column to the next on the block's own rows: `t`.
        let len_a = rr * p;
        springs(xs(l, p), xs(l, p + 1), fam(KA, p, len_a), &mut t[..], len_a);
        for c in 0..3 {
            let fc = &mut fl[c * n..(c + 1) * n];
            let (sa, sr) = (&s[c * n..(c + 1) * n], &t[c * n..(c + 1) * n]);
            // The spring from the row before (none before the membrane's first row).
            for (o, v) in fc[own.clone()].iter_mut().zip(&sa[..rr * p]) {
                *o = -v;
            }
            if r0 == 0 {
                fc[p..2 * p].fill(0.0);
            }
            for (e, &(r, qa, qb)) in edge.iter_mut().zip(segs.iter()) {
                *e = [fc[r * p + qa], fc[r * p + qb - 1]];
            }
            // Around, inside the run (`sr` is indexed from the block's first own row).
            let m_a = rr * p;
            for ((o, a), b) in fc[p + 1..(rr + 1) * p]
                .iter_mut()
                .zip(&sr[1..m_a])
                .zip(&sr[..m_a - 1])
            {
                *o += a - b;
            }
            // Each run's first and last node as the row kernel sums them: the springs
            // inside the run, then the one into its first column and the one out of its
            // last (where they exist).
            for (&[first, last], &(r, qa, qb)) in edge.iter().zip(segs.iter()) {
                let (a, z) = (r * p + qa, r * p + qb - 1);
                let wide = qb - qa > 1;
                fc[a] = if wide { first + sr[a - p] } else { first };
                if wide {
                    fc[z] = last - sr[z - 1 - p];
                }
                if pr(l, KA)[a - 1] > 0.0 {
                    fc[a] += -sr[a - 1 - p];
                }
                if pr(l, KA)[z] > 0.0 {
                    fc[z] += sr[z - p];
                }
            }
            // Along, to the next row.
            for (o, v) in fc[p..along_end].iter_mut().zip(&sa[p..along_end]) {
                *o += v;
            }
        }
    }
    // Links between layers.
    for l in 0..LAYERS - 1 {
        let len = rr * p;
        let par3: [&[f32]; 3] = std::array::from_fn(|d| &pr(l, KK + d)[p..p + len]);
        springs(xs(l, p), xs(l + 1, p), par3, s, len);
        let (lower, upper) = f.split_at_mut((l + 1) * 3 * n);
        for c in 0..3 {
            let fa = &mut lower[(l * 3 + c) * n + p..][..len];
            let fb = &mut upper[c * n + p..][..len];
            let sv = &s[c * n..][..len];
            for ((oa, ob), v) in fa.iter_mut().zip(fb.iter_mut()).zip(sv) {
                *oa += v;
                *ob -= v;
            }
        }
    }
    // The shear tethers of layers 1 and 2.
    let len = rr * p;
    for l in 1..LAYERS - 1 {
        let (k, wt) = (&pr(l, SK)[p..p + len], &pr(l, SW)[p..p + len]);
        let px = |l: usize, c: usize| &x[(l * 6 + c) * n + p..][..len];
        let (sx, rest_s) = s.split_at_mut(n);
        let (sy, sz) = rest_s.split_at_mut(n);
        super::forces::tethers(
            [px(0, 0), px(0, 1), px(0, 2)],
            [px(LAYERS - 1, 0), px(LAYERS - 1, 1), px(LAYERS - 1, 2)],
            [px(l, 0), px(l, 1), px(l, 2)],
            k,
            wt,
            [&mut sx[..len], &mut sy[..len], &mut sz[..len]],
        );
        for c in 0..3 {
            let sv = &s[c * n..][..len];
            let (lower, upper) = f.split_at_mut(l * 3 * n);
            let (mid, top) = upper.split_at_mut(3 * n);
            let f0 = &mut lower[c * n + p..][..len];
            let fm = &mut mid[c * n + p..][..len];
            let f3 = &mut top[((LAYERS - 2 - l) * 3 + c) * n + p..][..len];
            for j in 0..len {
                fm[j] += sv[j];
                f0[j] -= (1.0 - wt[j]) * sv[j];
                f3[j] -= wt[j] * sv[j];
            }
        }
    }
    // The attachments of layers 0 and 3.
    for (slot, l) in [(0usize, 0usize), (1, LAYERS - 1)] {
        let ka = &par[(ATTACH + slot * 4) * n + p..][..len];
        for c in 0..3 {
            let tg = &par[(ATTACH + slot * 4 + 1 + c) * n + p..][..len];
            let xc = &x[(l * 6 + c) * n + p..][..len];
            let fc = &mut f[(l * 3 + c) * n + p..][..len];
            for j in 0..len {
                fc[j] -= ka[j] * (xc[j] - tg[j]);
            }
        }
    }
    for &(k, l, fe) in ext.iter() {
        for c in 0..3 {
            f[(usize::from(l) * 3 + c) * n + k as usize] += fe[c];
        }
    }
}

/// Symplectic Euler on the block's runs, into `out`: every node of its own rows is
/// computed, and those outside the runs (`own`) keep their state.
#[inline(always)]
fn advance(m: &Membrane, bk: &mut Block, h: f32) {
    let (n, p) = (bk.n, bk.stride);
    let len = bk.rows() * p;
    let (g, d) = (m.params.gravity, m.params.damping_per_s);
    let own = &bk.own[p..p + len];
    for l in 0..LAYERS {
        let inv_m = &bk.par[(l * PER_LAYER + IM) * n + p..][..len];
        let (xs, vs) = bk.x[l * 6 * n..(l + 1) * 6 * n].split_at(3 * n);
        let (xo, vo) = bk.out[l * 6 * n..(l + 1) * 6 * n].split_at_mut(3 * n);
        for c in 0..3 {
            let fc = &bk.f[(l * 3 + c) * n + p..][..len];
            let (x0, v0) = (&xs[c * n + p..][..len], &vs[c * n + p..][..len]);
            let (xn, vn) = (&mut xo[c * n + p..][..len], &mut vo[c * n + p..][..len]);
            for j in 0..len {
                let acc = fc[j] * inv_m[j] + (g[c] - d * v0[j]);
                let v = v0[j] + h * acc;
                let x = x0[j] + h * v;
                let keep = own[j] == 0;
                vn[j] = if keep { v0[j] } else { v };
                xn[j] = if keep { x0[j] } else { x };
            }
        }
    }
}
