//! The boundary-element system (the myotomy paper's eq. 2): collocation at every element's
//! centroid, mixed boundary conditions per element and component, the dense `N x N` matrix
//! assembled in parallel and factorised by LU with partial pivoting (faer, f64).
//!
//! Row block `i` of eq. 1 at element `i`'s centroid reads `sum_j H_ij u_j = sum_j G_ij p_j`
//! with `H_ij = int_j P` (plus `c I = I / 2` on the diagonal, a smooth point of a flat element)
//! and `G_ij = int_j U`. For every element and global component one of `u` and `p` is known:
//! the unknown's column goes into `A` (`H`'s for a displacement, `-G`'s for a traction) and the
//! known's into the right-hand side `F`.
//!
//! `A` is kept transposed (row block `i` of `A` is a contiguous column block of `A^T`, so the
//! collocation points fill it in parallel without sharing anything); `A y = F` is solved with
//! `A^T`'s factors. Each collocation point's row is a sum over the elements in order, so the
//! bytes do not depend on the thread count.

use super::kelvin::{Material, integrate_off, integrate_self};
use super::surface::Element;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::perm::PermRef;
use faer::{MatMut, MatRef, Par};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Which of displacement and traction is known, for one component.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Known {
    Displacement,
    Traction,
}

/// An element's boundary condition: per global component, what is known, and its value (m
/// or Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Condition {
    pub known: [Known; 3],
    pub value: DVec3,
}

impl Condition {
    /// Held where it is.
    pub fn fixed() -> Condition {
        Condition {
            known: [Known::Displacement; 3],
            value: DVec3::ZERO,
        }
    }

    /// A prescribed traction, Pa (zero: a free surface).
    pub fn traction(t: DVec3) -> Condition {
        Condition {
            known: [Known::Traction; 3],
            value: t,
        }
    }
}

/// Why a system could not be built or solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BemError {
    #[error("{elements} elements but {conditions} boundary conditions")]
    Lengths { elements: usize, conditions: usize },
    #[error("element {element} is degenerate (area {area_m2} m^2)")]
    Degenerate { element: usize, area_m2: f64 },
    #[error(
        "material: Young's modulus {young_pa} Pa must be positive and Poisson's ratio {poisson} in [0, 0.5)"
    )]
    Material { young_pa: f64, poisson: f64 },
    #[error("field element {element} is out of range or listed twice ({elements} elements)")]
    Field { element: usize, elements: usize },
    #[error(
        "the system is singular (pivot {pivot} is zero): the body is not held against rigid motion"
    )]
    Singular { pivot: usize },
}

/// A stage of the precomputation and its fraction done, for a progress bar.
pub type Progress<'a> = &'a (dyn Fn(&str, f64) + Sync);

/// The assembled system: `A^T` (column-major, `N x N`), `F`, and, for the elements asked
/// for, `G`'s columns (`N x 3k`, column-major): the response to a traction put on them.
pub struct Assembled {
    pub n: usize,
    pub a_t: Vec<f64>,
    pub f: Vec<f64>,
    pub g_cols: Vec<f64>,
    pub g_elements: Vec<usize>,
}

/// Checks a problem's inputs.
pub fn validate(
    elements: &[Element],
    material: &Material,
    conditions: &[Condition],
) -> Result<(), BemError> {
    if elements.len() != conditions.len() {
        return Err(BemError::Lengths {
            elements: elements.len(),
            conditions: conditions.len(),
        });
    }
    if !(material.young_pa > 0.0 && (0.0..0.5).contains(&material.poisson)) {
        return Err(BemError::Material {
            young_pa: material.young_pa,
            poisson: material.poisson,
        });
    }
    for (k, e) in elements.iter().enumerate() {
        if !(e.area_m2 > 0.0 && e.area_m2.is_finite()) {
            return Err(BemError::Degenerate {
                element: k,
                area_m2: e.area_m2,
            });
        }
    }
    Ok(())
}

/// `(H_ij, G_ij)` for collocation at element `i` and integration over element `j`.
pub fn blocks(m: &Material, elements: &[Element], i: usize, j: usize) -> (DMat3, DMat3) {
    if i == j {
        let (g, h) = integrate_self(m, &elements[j]);
        (h + DMat3::IDENTITY * 0.5, g)
    } else {
        let (g, h) = integrate_off(m, elements[i].centroid, &elements[j]);
        (h, g)
    }
}

/// Assembles `A^T`, `F` and `G`'s columns for `g_elements`, in parallel over the
/// collocation points.
pub fn assemble(
    elements: &[Element],
    material: &Material,
    conditions: &[Condition],
    g_elements: &[usize],
    progress: Progress,
) -> Result<Assembled, BemError> {
    validate(elements, material, conditions)?;
    let ne = elements.len();
    let mut seen = vec![false; ne];
    for &e in g_elements {
        match seen.get_mut(e) {
            Some(s) if !*s => *s = true,
            _ => {
                return Err(BemError::Field {
                    element: e,
                    elements: ne,
                });
            }
        }
    }
    let n = 3 * ne;
    let k = 3 * g_elements.len();
    // Where each element's G columns go, if anywhere.
    let mut g_slot = vec![usize::MAX; ne];
    for (s, &e) in g_elements.iter().enumerate() {
        if let Some(slot) = g_slot.get_mut(e) {
            *slot = s;
        }
    }
    let mut a_t = vec![0.0f64; n * n];
    // `G`'s rows for each collocation point, transposed like `A` (3k values a row; a
    // placeholder of one value a point when no columns are asked for).
    let mut g_t = vec![0.0f64; ne * (3 * k).max(1)];
    let mut f = vec![0.0f64; n];
    let done = AtomicUsize::new(0);
    let step = (ne / 100).max(1);
    a_t.par_chunks_mut(3 * n)
        .zip(g_t.par_chunks_mut((3 * k).max(1)))
        .zip(f.par_chunks_mut(3))
        .enumerate()
        .for_each(|(i, ((cols, g_rows), f_i))| {
            let mut rhs = DVec3::ZERO;
            for j in 0..ne {
                let (h, g) = blocks(material, elements, i, j);
                let cond = &conditions[j];
                for c in 0..3 {
                    let (hc, gc) = (h.col(c), g.col(c));
                    // The unknown's column goes into A, the known's into F.
                    let col = match cond.known[c] {
                        Known::Displacement => {
                            rhs -= hc * cond.value[c];
                            -gc
                        }
                        Known::Traction => {
                            rhs += gc * cond.value[c];
                            hc
                        }
                    };
                    for r in 0..3 {
                        cols[r * n + 3 * j + c] = col[r];
                    }
                    if g_slot[j] != usize::MAX {
                        for r in 0..3 {
                            g_rows[r * k + 3 * g_slot[j] + c] = gc[r];
                        }
                    }
                }
            }
            f_i.copy_from_slice(&rhs.to_array());
            let now = done.fetch_add(1, Ordering::Relaxed) + 1;
            if now.is_multiple_of(step) || now == ne {
                progress("assembly", now as f64 / ne as f64);
            }
        });
    // G's columns, column-major N x 3k, from its transposed rows.
    let mut g_cols = vec![0.0f64; n * k];
    for row in 0..n {
        for col in 0..k {
            g_cols[col * n + row] = g_t[row * k + col];
        }
    }
    Ok(Assembled {
        n,
        a_t,
        f,
        g_cols,
        g_elements: g_elements.to_vec(),
    })
}

/// `A^T`'s LU factors (in place) and row permutation.
pub struct Factored {
    pub n: usize,
    lu: Vec<f64>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
}

impl Factored {
    /// Factorises `A^T` (taken over, `N x N` column-major).
    pub fn new(n: usize, mut a_t: Vec<f64>, par: Par) -> Result<Factored, BemError> {
        let mut perm = vec![0usize; n];
        let mut perm_inv = vec![0usize; n];
        {
            let m = MatMut::from_column_major_slice_mut(&mut a_t, n, n);
            let mut buf = MemBuffer::new(factor::lu_in_place_scratch::<usize, f64>(
                n,
                n,
                par,
                Default::default(),
            ));
            factor::lu_in_place(
                m,
                &mut perm,
                &mut perm_inv,
                par,
                MemStack::new(&mut buf),
                Default::default(),
            );
        }
        for i in 0..n {
            let d = a_t[i * n + i];
            if d == 0.0 || !d.is_finite() {
                return Err(BemError::Singular { pivot: i });
            }
        }
        Ok(Factored {
            n,
            lu: a_t,
            perm,
            perm_inv,
        })
    }

    /// Solves `A Y = B` in place for `B`'s columns (`N x cols`, column-major).
    pub fn solve(&self, b: &mut [f64], cols: usize, par: Par) {
        let n = self.n;
        let lu = MatRef::from_column_major_slice(&self.lu, n, n);
        let perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let rhs = MatMut::from_column_major_slice_mut(b, n, cols);
        let mut buf = MemBuffer::new(solve::solve_transpose_in_place_scratch::<usize, f64>(
            n, cols, par,
        ));
        solve::solve_transpose_in_place(lu, lu, perm, rhs, par, MemStack::new(&mut buf));
    }
}

/// The floating-point operations of an `N x N` LU factorisation.
pub fn lu_flops(n: usize) -> f64 {
    2.0 / 3.0 * (n as f64).powi(3)
}

/// Splits a solution `Y` into every element's displacement and traction, putting back the
/// known components.
pub fn split_solution(y: &[f64], conditions: &[Condition]) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut u = Vec::with_capacity(conditions.len());
    let mut p = Vec::with_capacity(conditions.len());
    for (j, cond) in conditions.iter().enumerate() {
        let mut uj = DVec3::ZERO;
        let mut pj = DVec3::ZERO;
        for c in 0..3 {
            let v = y[3 * j + c];
            match cond.known[c] {
                Known::Displacement => {
                    uj[c] = cond.value[c];
                    pj[c] = v;
                }
                Known::Traction => {
                    uj[c] = v;
                    pj[c] = cond.value[c];
                }
            }
        }
        u.push(uj);
        p.push(pj);
    }
    (u, p)
}
