//! Symmetric block-tridiagonal systems with 6 x 6 blocks, solved by block Cholesky in O(n):
//! the rod's Newton system, one block per node and its element (position and rotation).

/// A 6 x 6 block, row-major.
pub type Block = [[f64; 6]; 6];
/// A 6-vector.
pub type Vec6 = [f64; 6];

pub const ZERO_BLOCK: Block = [[0.0; 6]; 6];

/// `H = tridiag(U^T, D, U)`: `diag[b]` couples block b with itself, `upper[b]` block b (rows)
/// with block b + 1 (columns).
#[derive(Debug, Clone, Default)]
pub struct BlockTridiagonal {
    pub diag: Vec<Block>,
    pub upper: Vec<Block>,
    /// Factor scratch: the Cholesky factors of the Schur complements, and L^-1 U.
    l: Vec<Block>,
    w: Vec<Block>,
}

/// The system is not positive definite (a pivot at block `block` was not positive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotPositive {
    pub block: usize,
}

impl BlockTridiagonal {
    /// An all-zero system of `n` blocks.
    pub fn reset(&mut self, n: usize) {
        self.diag.clear();
        self.diag.resize(n, ZERO_BLOCK);
        self.upper.clear();
        self.upper.resize(n.saturating_sub(1), ZERO_BLOCK);
    }

    /// Solves `H x = rhs` in place.
    pub fn solve(&mut self, rhs: &mut [Vec6]) -> Result<(), NotPositive> {
        let n = self.diag.len();
        self.l.resize(n, ZERO_BLOCK);
        self.w.resize(n.saturating_sub(1), ZERO_BLOCK);
        for b in 0..n {
            let mut c = self.diag[b];
            if b > 0 {
                let w = &self.w[b - 1];
                // C = D - W^T W.
                for i in 0..6 {
                    for j in 0..=i {
                        let s: f64 = (0..6).map(|k| w[k][i] * w[k][j]).sum();
                        c[i][j] -= s;
                        c[j][i] = c[i][j];
                    }
                }
            }
            self.l[b] = cholesky(&c).ok_or(NotPositive { block: b })?;
            if b + 1 < n {
                self.w[b] = lower_solve_matrix(&self.l[b], &self.upper[b]);
            }
        }
        // Forward: y_b = L_b^-1 (r_b - W_{b-1}^T y_{b-1}).
        for b in 0..n {
            if b > 0 {
                let prev = rhs[b - 1];
                let w = &self.w[b - 1];
                for (i, r) in rhs[b].iter_mut().enumerate() {
                    *r -= (0..6).map(|k| w[k][i] * prev[k]).sum::<f64>();
                }
            }
            rhs[b] = lower_solve(&self.l[b], &rhs[b]);
        }
        // Backward: z_b = L_b^-T (y_b - W_b z_{b+1}).
        for b in (0..n).rev() {
            if b + 1 < n {
                let next = rhs[b + 1];
                let w = &self.w[b];
                for (i, r) in rhs[b].iter_mut().enumerate() {
                    *r -= (0..6).map(|k| w[i][k] * next[k]).sum::<f64>();
                }
            }
            rhs[b] = upper_solve_transposed(&self.l[b], &rhs[b]);
        }
        Ok(())
    }
}

/// The lower Cholesky factor of a symmetric positive definite block; none if it is not.
fn cholesky(a: &Block) -> Option<Block> {
    let mut l = ZERO_BLOCK;
    for i in 0..6 {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                let d = a[i][i] - s;
                if d <= 0.0 || !d.is_finite() {
                    return None;
                }
                l[i][i] = d.sqrt();
            } else {
                l[i][j] = (a[i][j] - s) / l[j][j];
            }
        }
    }
    Some(l)
}

/// `L^-1 b` for lower-triangular `L`.
fn lower_solve(l: &Block, b: &Vec6) -> Vec6 {
    let mut y = [0.0; 6];
    for i in 0..6 {
        let s: f64 = (0..i).map(|k| l[i][k] * y[k]).sum();
        y[i] = (b[i] - s) / l[i][i];
    }
    y
}

/// `L^-T b` for lower-triangular `L`.
fn upper_solve_transposed(l: &Block, b: &Vec6) -> Vec6 {
    let mut x = [0.0; 6];
    for i in (0..6).rev() {
        let s: f64 = (i + 1..6).map(|k| l[k][i] * x[k]).sum();
        x[i] = (b[i] - s) / l[i][i];
    }
    x
}

/// `L^-1 M` column by column.
fn lower_solve_matrix(l: &Block, m: &Block) -> Block {
    let mut out = ZERO_BLOCK;
    for j in 0..6 {
        let col: Vec6 = std::array::from_fn(|i| m[i][j]);
        let y = lower_solve(l, &col);
        for i in 0..6 {
            out[i][j] = y[i];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dense copy of the block system, for checking.
    fn dense(h: &BlockTridiagonal) -> Vec<Vec<f64>> {
        let n = h.diag.len() * 6;
        let mut a = vec![vec![0.0; n]; n];
        for (b, d) in h.diag.iter().enumerate() {
            for i in 0..6 {
                for j in 0..6 {
                    a[6 * b + i][6 * b + j] = d[i][j];
                }
            }
        }
        for (b, u) in h.upper.iter().enumerate() {
            for i in 0..6 {
                for j in 0..6 {
                    a[6 * b + i][6 * (b + 1) + j] = u[i][j];
                    a[6 * (b + 1) + j][6 * b + i] = u[i][j];
                }
            }
        }
        a
    }

    #[test]
    fn a_block_tridiagonal_solve_satisfies_the_dense_system() {
        let n = 7;
        let mut h = BlockTridiagonal::default();
        h.reset(n);
        // Diagonally dominant, symmetric, with full couplings.
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for b in 0..n {
            for i in 0..6 {
                for j in 0..=i {
                    let v = rnd();
                    h.diag[b][i][j] = v;
                    h.diag[b][j][i] = v;
                }
                h.diag[b][i][i] += 20.0;
            }
        }
        for u in &mut h.upper {
            for row in u.iter_mut() {
                for x in row.iter_mut() {
                    *x = rnd();
                }
            }
        }
        let rhs: Vec<Vec6> = (0..n).map(|_| std::array::from_fn(|_| rnd())).collect();
        let mut x = rhs.clone();
        h.solve(&mut x).expect("positive definite");
        let a = dense(&h);
        let flat: Vec<f64> = x.iter().flatten().copied().collect();
        for (row, r) in a.iter().zip(rhs.iter().flatten()) {
            let ax: f64 = row.iter().zip(&flat).map(|(p, q)| p * q).sum();
            assert!((ax - r).abs() < 1e-12, "{ax} vs {r}");
        }
        // An indefinite pivot is reported, not solved.
        h.diag[3][2][2] = -100.0;
        assert_eq!(h.solve(&mut x.clone()), Err(NotPositive { block: 3 }));
    }
}
