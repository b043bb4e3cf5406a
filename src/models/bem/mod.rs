//! Linear elastostatics by the boundary element method, the model of the myotomy paper's
//! esophagus (after James and Pai's precomputed BEM).
//!
//! - [`surface`]: closed triangulated surfaces and their flat elements ([`Sector`]: a
//!   thick-walled tube or a sector of one).
//! - [`kelvin`]: Kelvin's fundamental solutions and their integrals over an element.
//! - [`system`]: collocation at the centroids, mixed boundary conditions, the dense matrix
//!   assembled in parallel and factorised by LU (faer, f64).
//! - [`cache`]: the precomputation on disk, keyed by everything it depends on, checksummed.
//!
//! [`precompute`] ties them together: it solves the problem as given (`Y0`) and, for a set of
//! "field" elements where instruments may press, the response of every unknown to a unit
//! traction on each of them (`A^-1 G`'s columns, James and Pai's Green's functions), reading
//! them from the cache when the key matches and the checksum holds, and rebuilding them
//! otherwise.

pub mod cache;
pub mod contact;
pub mod incision;
pub mod kelvin;
mod model;
pub mod palpation;
pub mod reference;
pub mod surface;
pub mod system;

pub use model::Palpated;

pub use kelvin::Material;
pub use surface::{Element, Face, Sector, Surface};
pub use system::{BemError, Condition, Known, Progress};

use faer::Par;
use glam::DVec3;
use std::path::Path;
use std::time::Instant;

/// A boundary-value problem: elements, material and a condition per element.
#[derive(Debug, Clone)]
pub struct Problem {
    pub elements: Vec<Element>,
    pub material: Material,
    pub conditions: Vec<Condition>,
}

/// Every element's displacement (m) and traction (Pa).
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    pub displacement: Vec<DVec3>,
    pub traction: Vec<DVec3>,
}

/// How long the parts of a precomputation took, s.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timings {
    pub assembly_s: f64,
    pub factor_s: f64,
    pub solve_s: f64,
}

impl Problem {
    /// The unknowns' count, `N = 3 n`.
    pub fn unknowns(&self) -> usize {
        3 * self.elements.len()
    }

    /// A key over everything the precomputation depends on: the elements, the material, the
    /// conditions, the field elements and the cache's format.
    pub fn key(&self, field: &[usize]) -> u64 {
        let mut k = cache::Key::default();
        k.u64(u64::from(cache::VERSION));
        k.u64(self.elements.len() as u64);
        for e in &self.elements {
            for c in e.corners {
                for v in c.to_array() {
                    k.f64(v);
                }
            }
        }
        k.f64(self.material.young_pa);
        k.f64(self.material.poisson);
        for c in &self.conditions {
            for (known, v) in c.known.iter().zip(c.value.to_array()) {
                k.u64(*known as u64);
                k.f64(v);
            }
        }
        k.u64(field.len() as u64);
        for &f in field {
            k.u64(f as u64);
        }
        k.0
    }

    /// Solves it once (assembly, factorisation, one solve).
    pub fn solve(&self, par: Par, progress: Progress) -> Result<(Solution, Timings), BemError> {
        let p = self.precompute(&[], par, progress)?;
        Ok((p.solution(self), p.timings))
    }

    /// `Y0` and the field's responses, computed.
    pub fn precompute(
        &self,
        field: &[usize],
        par: Par,
        progress: Progress,
    ) -> Result<Precomputed, BemError> {
        let t0 = Instant::now();
        let asm = system::assemble(
            &self.elements,
            &self.material,
            &self.conditions,
            field,
            progress,
        )?;
        let t1 = Instant::now();
        progress("factorisation", 0.0);
        let n = asm.n;
        let lu = system::Factored::new(n, asm.a_t, par)?;
        progress("factorisation", 1.0);
        let t2 = Instant::now();
        let mut y0 = asm.f;
        lu.solve(&mut y0, 1, par);
        let mut response = asm.g_cols;
        if !field.is_empty() {
            progress("responses", 0.0);
            lu.solve(&mut response, 3 * field.len(), par);
            progress("responses", 1.0);
        }
        let t3 = Instant::now();
        Ok(Precomputed {
            n,
            y0,
            field: field.to_vec(),
            response,
            timings: Timings {
                assembly_s: (t1 - t0).as_secs_f64(),
                factor_s: (t2 - t1).as_secs_f64(),
                solve_s: (t3 - t2).as_secs_f64(),
            },
            from_cache: false,
        })
    }

    /// [`Problem::precompute`] through the cache at `path`: read when it was made from these
    /// inputs and is whole, else computed and written (the reason it was not used is
    /// returned with it).
    pub fn precompute_cached(
        &self,
        field: &[usize],
        path: &Path,
        par: Par,
        progress: Progress,
    ) -> Result<(Precomputed, Option<cache::CacheError>), PrecomputeError> {
        let key = self.key(field);
        let n = self.unknowns();
        let why = match cache::read(path, key) {
            Ok(arrays) => match Precomputed::from_arrays(n, field, arrays) {
                Some(p) => return Ok((p, None)),
                None => cache::CacheError::Corrupt {
                    path: path.to_path_buf(),
                },
            },
            Err(e) => e,
        };
        let p = self.precompute(field, par, progress)?;
        cache::write(path, key, &p.to_arrays())?;
        Ok((p, Some(why)))
    }
}

/// Why a cached precomputation failed.
#[derive(Debug, thiserror::Error)]
pub enum PrecomputeError {
    #[error(transparent)]
    Bem(#[from] BemError),
    #[error(transparent)]
    Cache(#[from] cache::CacheError),
    /// The scenario the precomputation's inputs come from.
    #[error(transparent)]
    Input(#[from] crate::scenario::InputError),
}

impl From<PrecomputeError> for crate::sim::ModelError {
    fn from(e: PrecomputeError) -> Self {
        crate::sim::ModelError::new("precomputing the tissue's responses", e)
    }
}

impl From<PrecomputeError> for crate::sim::BuildError {
    fn from(e: PrecomputeError) -> Self {
        crate::sim::BuildError::Model(e.into())
    }
}

impl Timings {
    /// `report` with these stage times, their total and the factorisation's rate for
    /// `flops` operations.
    pub fn fill(
        self,
        mut report: crate::sim::precompute::PrecomputeReport,
        flops: f64,
    ) -> crate::sim::precompute::PrecomputeReport {
        report.assembly_s = self.assembly_s;
        report.factor_s = self.factor_s;
        report.solve_s = self.solve_s;
        report.total_s = self.assembly_s + self.factor_s + self.solve_s;
        report.factor_gflops = if self.factor_s > 0.0 {
            flops / self.factor_s / 1e9
        } else {
            0.0
        };
        report
    }
}

/// A problem's solution as given and its field elements' responses.
#[derive(Debug, Clone, PartialEq)]
pub struct Precomputed {
    pub n: usize,
    /// The unknowns with no instrument: displacements where tractions are known and the
    /// reverse.
    pub y0: Vec<f64>,
    pub field: Vec<usize>,
    /// `N x 3k` column-major: column `3 s + c` is every unknown's change per pascal of
    /// traction along `c` on field element `s`.
    pub response: Vec<f64>,
    pub timings: Timings,
    pub from_cache: bool,
}

impl Precomputed {
    /// The solution with no instrument.
    pub fn solution(&self, problem: &Problem) -> Solution {
        let (displacement, traction) = system::split_solution(&self.y0, &problem.conditions);
        Solution {
            displacement,
            traction,
        }
    }

    fn to_arrays(&self) -> cache::Arrays {
        vec![
            ("y0".to_string(), self.y0.clone()),
            ("response".to_string(), self.response.clone()),
        ]
    }

    fn from_arrays(n: usize, field: &[usize], arrays: cache::Arrays) -> Option<Precomputed> {
        let mut y0 = None;
        let mut response = None;
        for (name, v) in arrays {
            match name.as_str() {
                "y0" => y0 = Some(v),
                "response" => response = Some(v),
                _ => return None,
            }
        }
        let (y0, response) = (y0?, response?);
        if y0.len() != n || response.len() != n * 3 * field.len() {
            return None;
        }
        if !y0.iter().chain(&response).all(|v| v.is_finite()) {
            return None;
        }
        Some(Precomputed {
            n,
            y0,
            field: field.to_vec(),
            response,
            timings: Timings::default(),
            from_cache: true,
        })
    }
}

#[cfg(test)]
mod tests;
