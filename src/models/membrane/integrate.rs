//! The membrane's integrators: symplectic Euler (`v += dt F(x, v) / m`, `x += dt v`) and the
//! paper's classical fourth-order Runge-Kutta on `(x, v)`. Both are explicit: stable only
//! below [`super::Membrane::explicit_step_limit`] (see `docs/rectum.md` for what that means at
//! the paper's resolution).
//!
//! Rows go in fixed chunks; every sum is per node, so the bytes do not depend on the number
//! of threads. The symplectic step is one pass in place: a chunk computes a row's forces and
//! advances that row at once (no later row of the chunk reads it: the springs to it are
//! carried). The first and last rows of each chunk are read by the neighbouring chunks, so
//! their new state waits in a buffer until every chunk is done.

use super::forces::{self, RowScratch, Rows, Whole};
use super::{ALONG, AROUND, LAYERS, LINK, Membrane, State, field};
use rayon::prelude::*;

/// Rows per parallel task.
const CHUNK_ROWS: usize = 16;

#[derive(Debug, Clone, Default)]
pub(super) struct Scratch {
    /// Forces in row blocks: `[block][component][column]`.
    f: Vec<f32>,
    /// Runge-Kutta's stage state and running sums.
    stage: State,
    sum: Vec<f32>,
}

pub(super) fn step(m: &mut Membrane, dt: f32) {
    let dt = if dt.is_finite() && dt > 0.0 { dt } else { 1e-3 };
    forces::sort_external(&mut m.external);
    let mut sc = std::mem::take(&mut m.scratch);
    match m.params.integrator {
        super::Integrator::Symplectic => symplectic(m, dt),
        super::Integrator::RungeKutta4 => runge_kutta(m, &mut sc, dt),
    }
    m.scratch = sc;
}

fn chunk_rows(c: usize, rows: usize) -> (usize, usize) {
    let r0 = c * CHUNK_ROWS;
    (r0, (r0 + CHUNK_ROWS).min(rows))
}

/// Forces at `state` for every node into `f` (row blocks of three components), the node's
/// own terms included.
fn forces_all(m: &Membrane, state: &[f32], f: &mut Vec<f32>) {
    let (rows, cols) = (m.rows, m.cols);
    f.resize(m.len() * 3, 0.0);
    let whole = Whole {
        data: state,
        rows,
        cols,
    };
    // Per chunk, the blocks of each layer.
    let mut parts: Vec<Vec<&mut [f32]>> =
        (0..rows.div_ceil(CHUNK_ROWS)).map(|_| Vec::new()).collect();
    for layer in f.chunks_mut(rows * 3 * cols) {
        for (c, piece) in layer.chunks_mut(CHUNK_ROWS * 3 * cols).enumerate() {
            parts[c].push(piece);
        }
    }
    parts
        .par_iter_mut()
        .enumerate()
        .for_each_init(RowScratch::default, |sc, (chunk, out)| {
            let (r0, r1) = chunk_rows(chunk, rows);
            for i in r0..r1 {
                forces::row::<_, false>(m, &whole, i, 0..cols, i == r0, sc);
                for (l, o) in out.iter_mut().enumerate() {
                    let b = l * rows + i;
                    let (mass, row) = (&m.mass[b * cols..(b + 1) * cols], whole.get(l, i));
                    for c in 0..3 {
                        let o = &mut o[((i - r0) * 3 + c) * cols..((i - r0) * 3 + c + 1) * cols];
                        let v = &row[(3 + c) * cols..(4 + c) * cols];
                        for (((o, f), w), v) in
                            o.iter_mut().zip(sc.row(l, c, cols)).zip(mass).zip(v)
                        {
                            *o = f + w * forces::own_acceleration(&m.params, c, *v);
                        }
                    }
                }
            }
        });
}

/// A chunk's view of the state in the symplectic pass: its interior rows to write, and the
/// first and last rows of every chunk to read.
struct ChunkView<'a, 'e> {
    r0: usize,
    rows: usize,
    /// Per layer, rows `r0 + 1 .. r1 - 1`.
    own: Vec<Vec<&'a mut [f32]>>,
    /// Per row block, the first and last rows of every chunk.
    edges: &'e [Option<&'a [f32]>],
}

impl Rows for ChunkView<'_, '_> {
    fn get(&self, l: usize, i: usize) -> &[f32] {
        match self.edges[l * self.rows + i] {
            Some(r) => r,
            None => &self.own[l][i - self.r0 - 1][..],
        }
    }
}

/// Advances one row (six runs of `cols`) by symplectic Euler under the forces `f`.
#[inline(always)]
fn advance(m: &Membrane, l: usize, i: usize, f: &RowScratch, row: &mut [f32], dt: f32) {
    let cols = m.cols;
    let b = l * m.rows + i;
    let at = (b * field::COUNT + field::INV_MASS) * cols;
    let inv_m = &m.rows_data[at..at + cols];
    let (g, d) = (m.params.gravity, m.params.damping_per_s);
    let (xs, vs) = row.split_at_mut(3 * cols);
    for c in 0..3 {
        let fc = f.row(l, c, cols);
        let x = &mut xs[c * cols..(c + 1) * cols];
        let v = &mut vs[c * cols..(c + 1) * cols];
        for j in 0..cols {
            let a = fc[j] * inv_m[j] + (g[c] - d * v[j]);
            v[j] += dt * a;
            x[j] += dt * v[j];
        }
    }
}

/// One chunk's symplectic pass, compiled for the widest vector unit the CPU has (the loops
/// are plain element-wise arithmetic, so every width gives the same bytes).
struct ChunkPass<'v, 'a, 'e, 'm> {
    m: &'m Membrane,
    view: &'v mut ChunkView<'a, 'e>,
    sc: &'v mut RowScratch,
    dt: f32,
}

impl pulp::WithSimd for ChunkPass<'_, '_, '_, '_> {
    /// The new state of the chunk's first and last rows, by row block.
    type Output = Vec<(usize, Vec<f32>)>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> Self::Output {
        let ChunkPass { m, view, sc, dt } = self;
        let rows = m.rows;
        let (r0, r1) = (view.r0, (view.r0 + CHUNK_ROWS).min(rows));
        let mut later = Vec::new();
        for i in r0..r1 {
            forces::row::<_, false>(m, &*view, i, 0..m.cols, i == r0, sc);
            for l in 0..LAYERS {
                if i == r0 || i + 1 == r1 {
                    let mut row = view.get(l, i).to_vec();
                    advance(m, l, i, sc, &mut row, dt);
                    later.push((l * rows + i, row));
                } else {
                    advance(m, l, i, sc, view.own[l][i - r0 - 1], dt);
                }
            }
        }
        later
    }
}

fn symplectic(m: &mut Membrane, dt: f32) {
    let (rows, cols) = (m.rows, m.cols);
    let width = 6 * cols;
    let chunks = rows.div_ceil(CHUNK_ROWS);
    let mut data = std::mem::take(&mut m.state.data);
    let deferred: Vec<Vec<(usize, Vec<f32>)>> = {
        let mut edges: Vec<Option<&[f32]>> = Vec::with_capacity(LAYERS * rows);
        let mut own: Vec<Vec<Vec<&mut [f32]>>> = (0..chunks)
            .map(|_| (0..LAYERS).map(|_| Vec::new()).collect())
            .collect();
        for (k, row) in data.chunks_mut(width).enumerate() {
            let (l, i) = (k / rows, k % rows);
            let (r0, r1) = chunk_rows(i / CHUNK_ROWS, rows);
            if i == r0 || i + 1 == r1 {
                edges.push(Some(row));
            } else {
                edges.push(None);
                own[i / CHUNK_ROWS][l].push(row);
            }
        }
        let m = &*m;
        let edges = &edges[..];
        let mut views: Vec<ChunkView> = own
            .into_iter()
            .enumerate()
            .map(|(c, own)| ChunkView {
                r0: c * CHUNK_ROWS,
                rows,
                own,
                edges,
            })
            .collect();
        views
            .par_iter_mut()
            .map_init(RowScratch::default, |sc, view| {
                m.vectorized(ChunkPass { m, view, sc, dt })
            })
            .collect()
    };
    for (k, row) in deferred.into_iter().flatten() {
        data[k * width..(k + 1) * width].copy_from_slice(&row);
    }
    m.state.data = data;
}

fn runge_kutta(m: &mut Membrane, sc: &mut Scratch, dt: f32) {
    let (rows, cols) = (m.rows, m.cols);
    let blocks = LAYERS * rows;
    let start = std::mem::take(&mut m.state.data);
    let mut stage = std::mem::take(&mut sc.stage.data);
    stage.clone_from(&start);
    sc.sum.clear();
    sc.sum.resize(start.len(), 0.0);
    // Stage k: derivative (v, F/m) at the stage's state; weights 1, 2, 2, 1; the next stage
    // starts from the state plus `h_k` times the derivative.
    let weights = [1.0f32, 2.0, 2.0, 1.0];
    let next_h = [0.5 * dt, 0.5 * dt, dt, 0.0];
    for k in 0..4 {
        forces_all(m, &stage, &mut sc.f);
        let (w, h) = (weights[k], next_h[k]);
        for b in 0..blocks {
            let at = (b * field::COUNT + field::INV_MASS) * cols;
            let inv_m = &m.rows_data[at..at + cols];
            for c in 0..3 {
                let (xo, vo) = ((b * 6 + c) * cols, (b * 6 + 3 + c) * cols);
                let fo = (b * 3 + c) * cols;
                for j in 0..cols {
                    let v = stage[vo + j];
                    let a = sc.f[fo + j] * inv_m[j];
                    sc.sum[xo + j] += w * v;
                    sc.sum[vo + j] += w * a;
                    if k < 3 {
                        // The next stage's state from the start, with this derivative.
                        stage[xo + j] = start[xo + j] + h * v;
                        stage[vo + j] = start[vo + j] + h * a;
                    }
                }
            }
        }
    }
    let mut state = start;
    for (s, d) in state.iter_mut().zip(&sc.sum) {
        *s += dt / 6.0 * d;
    }
    m.state.data = state;
    sc.stage.data = stage;
}

impl Membrane {
    /// The largest explicit step the grid allows, s, from bounds on the highest eigenvalues
    /// of the stiffness `lambda` (of `M^-1 K`, linearised at rest) and of the damping `nu`
    /// (of `M^-1 C` plus the point damping `D`), both by Gershgorin on the symmetric
    /// `M^-1/2 (.) M^-1/2`: a spring (or tether) acting on nodes `p` with weights `a_p` (1 and
    /// -1 for a spring; 1, w - 1 and -w for a tether) adds `k |a_p| / sqrt(m_p) * sum_q |a_q|
    /// / sqrt(m_q)` to row `p` (its damping `beta k` likewise), an attachment `k / m_p`. (For
    /// a uniform chain it gives `4 k / m`, the exact highest frequency.)
    ///
    /// A mode `x'' = -lambda x - nu x'` under symplectic Euler at step `h` is stable while
    /// `h^2 lambda + 2 h nu < 4` (the Jury conditions on its 2 x 2 update), so the limit is
    /// the positive root of that quadratic: with strong damping along stiff springs it is
    /// the damping, not the stiffness, that bounds the step. Runge-Kutta's region holds the
    /// left half-disc of radius 2.5 around 0, so its limit is 2.5 over the largest `|mu|` of
    /// the mode's roots `mu = -nu/2 +- sqrt(nu^2/4 - lambda)`.
    pub fn explicit_step_limit(&self) -> f32 {
        let per = self.rows * self.cols;
        let n = self.len();
        let inv_sqrt: Vec<f32> = self
            .mass
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m.sqrt() } else { 0.0 })
            .collect();
        let mut stiff = vec![0.0f32; n];
        let mut damp = vec![0.0f32; n];
        let mut add = |nodes: &[(usize, f32)], k: f32, c: f32| {
            if k <= 0.0 {
                return;
            }
            let total: f32 = nodes.iter().map(|&(q, a)| a.abs() * inv_sqrt[q]).sum();
            for &(p, a) in nodes {
                let g = a.abs() * inv_sqrt[p] * total;
                stiff[p] += k * g;
                damp[p] += c * g;
            }
        };
        for node in 0..n {
            let (l, i, j) = self.coords(node);
            let beta = self.beta[node / self.cols];
            if let Some(jn) = self.next_col(j) {
                let k = self.spring(field::K[AROUND], node);
                add(
                    &[(node, 1.0), (self.node(l, i, jn), -1.0)],
                    k,
                    beta[AROUND] * k,
                );
            }
            if i + 1 < self.rows {
                let k = self.spring(field::K[ALONG], node);
                add(&[(node, 1.0), (node + self.cols, -1.0)], k, beta[ALONG] * k);
            }
            if l + 1 < LAYERS {
                let k = self.spring(field::K[LINK], node);
                add(&[(node, 1.0), (node + per, -1.0)], k, beta[LINK] * k);
            }
            if l > 0 && l + 1 < LAYERS {
                let w = self.spring(field::SHEAR_W, node);
                add(
                    &[
                        (node, 1.0),
                        (self.node(0, i, j), w - 1.0),
                        (self.node(LAYERS - 1, i, j), -w),
                    ],
                    self.spring(field::SHEAR_K, node),
                    0.0,
                );
            }
        }
        let (mut lambda, mut nu) = (0.0f32, 0.0f32);
        for node in 0..n {
            if self.mass[node] > 0.0 {
                lambda = lambda.max(stiff[node] + self.attach_stiffness(node) / self.mass[node]);
                nu = nu.max(damp[node]);
            }
        }
        let nu = nu + self.params.damping_per_s.max(0.0);
        limit_for(self.params.integrator, lambda, nu)
    }
}

/// The stable step for a mode bounded by stiffness `lambda` (1/s^2) and damping `nu` (1/s):
/// see [`Membrane::explicit_step_limit`].
pub(super) fn limit_for(integrator: super::Integrator, lambda: f32, nu: f32) -> f32 {
    if lambda <= 0.0 && nu <= 0.0 {
        return f32::INFINITY;
    }
    let (lambda, nu) = (f64::from(lambda.max(0.0)), f64::from(nu.max(0.0)));
    let h = match integrator {
        super::Integrator::Symplectic => {
            if lambda > 0.0 {
                // The positive root of lambda h^2 + 2 nu h - 4 = 0, written to keep its
                // precision when nu dominates.
                4.0 / (nu + (nu * nu + 4.0 * lambda).sqrt())
            } else {
                2.0 / nu
            }
        }
        super::Integrator::RungeKutta4 => {
            let half = 0.5 * nu;
            let disc = half * half - lambda;
            let largest = if disc > 0.0 {
                half + disc.sqrt()
            } else {
                lambda.sqrt()
            };
            2.5 / largest
        }
    };
    h as f32
}

impl Membrane {
    /// The forces on every node at the membrane's state now, N (eqs 3-4 with the node's own
    /// damping and gravity; for tests and `vesalius verify`).
    pub fn forces_now(&self) -> Vec<glam::Vec3> {
        let mut f = Vec::new();
        forces_all(self, &self.current_state(), &mut f);
        let cols = self.cols;
        (0..self.len())
            .map(|node| {
                let (b, j) = (node / cols, node % cols);
                glam::Vec3::from_array(std::array::from_fn(|c| f[(b * 3 + c) * cols + j]))
            })
            .collect()
    }

    /// Moves `node` by `d` (m), its velocity kept (for tests and `vesalius verify`).
    pub fn displace(&mut self, node: usize, d: glam::Vec3) {
        if node < self.len() && d.is_finite() {
            self.catch_up();
            for c in 0..3 {
                let at = self.state_at(c, node);
                self.state.data[at] += d[c];
            }
            self.device.stale();
            self.all_changed();
        }
    }
}

#[cfg(test)]
pub(super) mod tests_support {
    /// The forces on every node at the membrane's state.
    pub fn forces(m: &super::Membrane) -> Vec<glam::Vec3> {
        m.forces_now()
    }
}
