//! A Jacobi-preconditioned conjugate gradient for the implicit step's system
//!
//!   A v = b,   A = D - W,
//!
//! where D is diagonal and W holds the (symmetric, non-negative) couplings between unknowns,
//! stored row by row (CSR) with local indices. The three components of a point's velocity are
//! three independent right-hand sides sharing one matrix, solved at once with their own step
//! lengths. Rows are worked in fixed chunks, in parallel when there are several; every dot
//! product is summed per chunk and then over the chunks in order, so the result is the same
//! bytes on one thread or many.

use glam::{DVec3, Vec3A};
use rayon::prelude::*;

/// Rows per chunk: the unit of parallel work and of the ordered reductions.
const CHUNK: usize = 512;
/// Rows per block of a chunk: a dot product is summed in f32 within a block (short enough to
/// lose nothing that matters), then block by block in f64, always in the same order.
const BLOCK: usize = 32;
/// Below this many rows the chunks run one after another on the calling thread: waking the
/// pool costs more than it saves. (The chunks and the order of the sums are the same.)
const PARALLEL_ROWS: usize = 2 * CHUNK;

/// The smallest run of chunks one task takes: all of them for a small system.
fn min_chunks(m: usize) -> usize {
    if m >= PARALLEL_ROWS { 1 } else { usize::MAX }
}

/// The system and the solver's working vectors, kept between steps so that a step allocates
/// nothing once the awake set has been seen. Vectors are 16-byte `Vec3A`s so that each
/// component-wise operation is one SIMD instruction.
#[derive(Debug, Default, Clone)]
pub(super) struct CgSystem {
    /// Diagonal of A.
    pub diag: Vec<f32>,
    /// Right-hand sides.
    pub b: Vec<Vec3A>,
    /// Row `k`'s couplings are `col[row_start[k]..row_start[k + 1]]` with weights `w[..]`.
    pub row_start: Vec<u32>,
    pub col: Vec<u32>,
    pub w: Vec<f32>,
    /// The solution; holds the starting guess on entry.
    pub x: Vec<Vec3A>,
    /// Scratch for the callers' count of couplings per row (see [`CgSystem::shape`]).
    pub counts: Vec<u32>,
    /// 1 / diag: the Jacobi preconditioner, multiplied rather than divided.
    inv_diag: Vec<f32>,
    r: Vec<Vec3A>,
    p: Vec<Vec3A>,
    ap: Vec<Vec3A>,
}

/// One run of rows of a shaped system (see [`CgSystem::shape`]), filled by one task: row `k`
/// of the run is `diag[k]`, `b[k]`, the guess `x[k]`, and its couplings, which fill `col` and
/// `w` in row order.
pub(super) struct RowsMut<'a> {
    pub diag: &'a mut [f32],
    pub b: &'a mut [Vec3A],
    pub x: &'a mut [Vec3A],
    pub col: &'a mut [u32],
    pub w: &'a mut [f32],
}

impl CgSystem {
    /// Empties the system (the caller then pushes rows in order).
    pub fn clear(&mut self) {
        self.diag.clear();
        self.b.clear();
        self.row_start.clear();
        self.row_start.push(0);
        self.col.clear();
        self.w.clear();
        self.x.clear();
    }

    /// Closes the row whose couplings were pushed since the last call.
    #[cfg(test)]
    pub fn end_row(&mut self, diag: f32, b: Vec3A, guess: Vec3A) {
        self.diag.push(diag);
        self.b.push(b);
        self.x.push(guess);
        self.row_start.push(self.col.len() as u32);
    }

    /// Sizes the system for rows with `lens[k]` couplings each.
    pub fn shape(&mut self, lens: &[u32]) {
        self.clear();
        let mut end = 0u32;
        for &n in lens {
            end += n;
            self.row_start.push(end);
        }
        let m = self.row_start.len() - 1;
        self.diag.resize(m, 0.0);
        self.b.resize(m, Vec3A::ZERO);
        self.x.resize(m, Vec3A::ZERO);
        self.col.resize(end as usize, 0);
        self.w.resize(end as usize, 0.0);
    }

    /// The shaped system cut into runs of `rows` rows, each to be filled by one task.
    pub fn runs_mut(&mut self, rows: usize) -> Vec<RowsMut<'_>> {
        let m = self.len();
        let cuts: Vec<u32> = (rows..m)
            .step_by(rows.max(1))
            .map(|k| self.row_start[k])
            .collect();
        let row_cuts: Vec<u32> = (rows..m).step_by(rows.max(1)).map(|k| k as u32).collect();
        let diag = super::split_at_offsets(&mut self.diag, &row_cuts);
        let b = super::split_at_offsets(&mut self.b, &row_cuts);
        let x = super::split_at_offsets(&mut self.x, &row_cuts);
        let col = super::split_at_offsets(&mut self.col, &cuts);
        let w = super::split_at_offsets(&mut self.w, &cuts);
        diag.into_iter()
            .zip(b)
            .zip(x)
            .zip(col)
            .zip(w)
            .map(|((((diag, b), x), col), w)| RowsMut { diag, b, x, col, w })
            .collect()
    }

    pub fn len(&self) -> usize {
        self.diag.len()
    }

    /// Heap bytes the system holds (capacity), for the profiler.
    pub fn heap_bytes(&self) -> usize {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        b(&self.diag)
            + b(&self.b)
            + b(&self.row_start)
            + b(&self.col)
            + b(&self.w)
            + b(&self.x)
            + b(&self.counts)
            + b(&self.inv_diag)
            + b(&self.r)
            + b(&self.p)
            + b(&self.ap)
    }

    /// Solves until every component's residual norm is at most `tolerance` times its
    /// right-hand side's or its root mean square over the rows is at most `floor`, or
    /// `max_iterations` have run. Returns the iterations taken.
    ///
    /// The iteration is preconditioned CG rearranged to take two passes over the rows instead
    /// of three: with z = D^-1 r, the new direction's product A p' = A z + beta A p is formed
    /// in the same pass as p' = z + beta p, so the product reads z (known once the residual
    /// is updated) rather than p' (known only after it). In exact arithmetic the iterates are
    /// those of the textbook method.
    pub fn solve(&mut self, tolerance: f32, floor: f32, max_iterations: usize) -> usize {
        let m = self.len();
        if m == 0 {
            return 0;
        }
        self.r.resize(m, Vec3A::ZERO);
        self.p.resize(m, Vec3A::ZERO);
        self.ap.resize(m, Vec3A::ZERO);
        self.inv_diag.clear();
        self.inv_diag.extend(self.diag.iter().map(|d| 1.0 / d));
        let mat = Matrix {
            diag: &self.diag,
            row_start: &self.row_start,
            col: &self.col,
            w: &self.w,
        };
        // r = b - A x.
        mat.apply_dot(&self.x, &mut self.ap);
        let (b, ap, inv_diag) = (&self.b, &self.ap, &self.inv_diag);
        let (rr, rz) = reduce(
            self.r.par_chunks_mut(CHUNK).with_min_len(min_chunks(m)),
            |c, r| {
                let base = c * CHUNK;
                blocked(r.len(), |k| {
                    let i = base + k;
                    r[k] = b[i] - ap[i];
                    (r[k] * r[k], r[k] * (r[k] * inv_diag[i]))
                })
            },
        );
        let bb = reduce(
            self.b.par_chunks(CHUNK).with_min_len(min_chunks(m)),
            |_, b| blocked(b.len(), |k| (b[k] * b[k], Vec3A::ZERO)),
        )
        .0;
        // Converged once every component is below the relative goal or the floor's RMS.
        let floor = m as f64 * f64::from(floor) * f64::from(floor);
        let goal = (bb * f64::from(tolerance * tolerance)).max(DVec3::splat(floor));
        let (mut rr, mut rz) = (rr, rz);
        // p = z, A p = A z: the first direction pass with beta = 0 (p and A p start at zero).
        self.p.fill(Vec3A::ZERO);
        self.ap.fill(Vec3A::ZERO);
        let mut beta = Vec3A::ZERO;
        let mut iterations = 0;
        while iterations < max_iterations && !(rr.cmple(goal).all()) {
            let pap = mat.next_direction(&self.r, &self.inv_diag, beta, &mut self.p, &mut self.ap);
            // A component whose curvature is zero has converged: it takes no step.
            let alpha = Vec3A::from(ratio(rz, pap).as_vec3());
            let (ap, inv_diag) = (&self.ap, &self.inv_diag);
            let (rr_new, rz_new) = reduce(
                self.x
                    .par_chunks_mut(CHUNK)
                    .zip(self.r.par_chunks_mut(CHUNK))
                    .zip(self.p.par_chunks(CHUNK))
                    .with_min_len(min_chunks(m)),
                |c, ((x, r), p)| {
                    let base = c * CHUNK;
                    let (ap, inv_diag) = (&ap[base..base + x.len()], &inv_diag[base..]);
                    blocked(x.len(), |k| {
                        x[k] += alpha * p[k];
                        r[k] -= alpha * ap[k];
                        let z = r[k] * inv_diag[k];
                        (r[k] * r[k], r[k] * z)
                    })
                },
            );
            beta = Vec3A::from(ratio(rz_new, rz).as_vec3());
            rr = rr_new;
            rz = rz_new;
            iterations += 1;
        }
        iterations
    }
}

/// Per component: `num / den` where `den` is positive, else zero.
fn ratio(num: DVec3, den: DVec3) -> DVec3 {
    let q = |n: f64, d: f64| if d > 0.0 { n / d } else { 0.0 };
    DVec3::new(q(num.x, den.x), q(num.y, den.y), q(num.z, den.z))
}

/// Runs `f` on rows `0..len` in order and sums its two terms: in f32 within each run of
/// [`BLOCK`] rows, then the runs in f64, in order.
#[inline(always)]
fn blocked(len: usize, mut f: impl FnMut(usize) -> (Vec3A, Vec3A)) -> (DVec3, DVec3) {
    let (mut s, mut t) = (DVec3::ZERO, DVec3::ZERO);
    let mut k = 0;
    while k < len {
        let end = (k + BLOCK).min(len);
        let (mut a, mut b) = (Vec3A::ZERO, Vec3A::ZERO);
        while k < end {
            let (da, db) = f(k);
            a += da;
            b += db;
            k += 1;
        }
        s += a.as_dvec3();
        t += b.as_dvec3();
    }
    (s, t)
}

/// Runs `f` on every chunk (index, item) and sums the chunks' pairs in chunk order.
fn reduce<I, T>(iter: I, f: impl Fn(usize, T) -> (DVec3, DVec3) + Sync) -> (DVec3, DVec3)
where
    I: IndexedParallelIterator<Item = T>,
    T: Send,
{
    let parts: Vec<(DVec3, DVec3)> = iter.enumerate().map(|(c, t)| f(c, t)).collect();
    parts
        .into_iter()
        .fold((DVec3::ZERO, DVec3::ZERO), |(a, b), (c, d)| (a + c, b + d))
}

struct Matrix<'a> {
    diag: &'a [f32],
    row_start: &'a [u32],
    col: &'a [u32],
    w: &'a [f32],
}

impl Matrix<'_> {
    /// out = A p; returns p . A p per component.
    fn apply_dot(&self, p: &[Vec3A], out: &mut [Vec3A]) -> DVec3 {
        reduce(
            out.par_chunks_mut(CHUNK).with_min_len(min_chunks(p.len())),
            |c, out| {
                let base = c * CHUNK;
                blocked(out.len(), |k| {
                    let i = base + k;
                    let mut acc = p[i] * self.diag[i];
                    let (s, e) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
                    for (&j, &w) in self.col[s..e].iter().zip(&self.w[s..e]) {
                        acc -= p[j as usize] * w;
                    }
                    out[k] = acc;
                    (acc * p[i], Vec3A::ZERO)
                })
            },
        )
        .0
    }

    /// The next search direction and its product in one pass: with z = D^-1 r,
    /// p <- z + beta p and A p <- A z + beta A p. Returns p . A p per component.
    fn next_direction(
        &self,
        r: &[Vec3A],
        inv_diag: &[f32],
        beta: Vec3A,
        p: &mut [Vec3A],
        ap: &mut [Vec3A],
    ) -> DVec3 {
        reduce(
            p.par_chunks_mut(CHUNK)
                .zip(ap.par_chunks_mut(CHUNK))
                .with_min_len(min_chunks(r.len())),
            |c, (p, ap)| {
                let base = c * CHUNK;
                blocked(p.len(), |k| {
                    let i = base + k;
                    let z = r[i] * inv_diag[i];
                    let mut az = z * self.diag[i];
                    let (s, e) = (self.row_start[i] as usize, self.row_start[i + 1] as usize);
                    for (&j, &w) in self.col[s..e].iter().zip(&self.w[s..e]) {
                        az -= r[j as usize] * inv_diag[j as usize] * w;
                    }
                    p[k] = z + beta * p[k];
                    ap[k] = az + beta * ap[k];
                    (p[k] * ap[k], Vec3A::ZERO)
                })
            },
        )
        .0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of `m` unknowns with unequal couplings, solved against a dense Gaussian
    /// elimination of the same matrix.
    fn chain(m: usize) -> (CgSystem, Vec<Vec<f64>>) {
        let mut s = CgSystem::default();
        s.clear();
        let mut dense = vec![vec![0.0f64; m]; m];
        for k in 0..m {
            let mut d = 0.5 + (k % 7) as f32 * 0.1;
            for j in [k.wrapping_sub(1), k + 1] {
                if j < m {
                    let w = 1.0 + ((k + j) % 5) as f32 * 0.3;
                    s.col.push(j as u32);
                    s.w.push(w);
                    dense[k][j] = -(w as f64);
                    d += w;
                }
            }
            dense[k][k] = d as f64;
            let b = Vec3A::new(k as f32 * 0.01, 1.0, -((k % 3) as f32));
            s.end_row(d, b, Vec3A::ZERO);
        }
        (s, dense)
    }

    fn dense_solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
        let m = b.len();
        for c in 0..m {
            for r in c + 1..m {
                let f = a[r][c] / a[c][c];
                for k in c..m {
                    a[r][k] -= f * a[c][k];
                }
                b[r] -= f * b[c];
            }
        }
        let mut x = vec![0.0; m];
        for r in (0..m).rev() {
            let s: f64 = (r + 1..m).map(|k| a[r][k] * x[k]).sum();
            x[r] = (b[r] - s) / a[r][r];
        }
        x
    }

    #[test]
    fn matches_a_dense_solve_across_chunks() {
        let m = 2 * CHUNK + 37;
        let (mut s, dense) = chain(m);
        let it = s.solve(1e-6, 0.0, 10_000);
        assert!(it > 0 && it < 10_000, "{it} iterations");
        for axis in 0..3 {
            let b: Vec<f64> = s.b.iter().map(|v| v[axis] as f64).collect();
            let want = dense_solve(dense.clone(), b);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (k, w) in want.iter().enumerate() {
                let got = s.x[k][axis] as f64;
                assert!(
                    (got - w).abs() <= 1e-3 * scale,
                    "row {k} axis {axis}: {got} vs {w}"
                );
            }
        }
    }

    #[test]
    fn same_bytes_on_one_thread_or_two() {
        let run = |threads| {
            crate::sim::on_threads(threads, || {
                let (mut s, _) = chain(PARALLEL_ROWS + 3 * CHUNK + 5);
                s.solve(1e-5, 0.0, 10_000);
                s.x.iter()
                    .flat_map(|v| v.to_array())
                    .map(f32::to_bits)
                    .collect::<Vec<_>>()
            })
        };
        assert_eq!(run(1), run(2));
    }

    #[test]
    fn a_zero_right_hand_side_takes_no_step() {
        let (mut s, _) = chain(10);
        s.b.iter_mut().for_each(|b| *b = Vec3A::ZERO);
        assert_eq!(s.solve(1e-4, 0.0, 100), 0);
        assert!(s.x.iter().all(|v| *v == Vec3A::ZERO));
    }
}
