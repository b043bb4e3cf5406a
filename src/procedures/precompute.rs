//! Precomputations a procedure needs before its first session (`vesalius precompute`): the
//! registry of procedures that have one, and what each reports.

use crate::models::bem::Timings;
use std::path::{Path, PathBuf};

/// What a precomputation did: where its cache is, whether it was read or built (and why it
/// was rebuilt), its sizes and timings.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PrecomputeReport {
    pub procedure: &'static str,
    pub cache: PathBuf,
    pub from_cache: bool,
    /// Why the cache was not used (missing, stale, corrupt, ...), when it was built.
    pub rebuilt_because: Option<String>,
    pub elements: usize,
    /// The dense system's size.
    pub n: usize,
    pub field_elements: usize,
    pub assembly_s: f64,
    pub factor_s: f64,
    /// The factorisation's rate, GFLOP/s (0 when read from the cache).
    pub factor_gflops: f64,
    pub solve_s: f64,
    pub total_s: f64,
    /// The cache file's size.
    pub bytes: u64,
}

impl PrecomputeReport {
    /// Fills the common fields from a boundary-element precomputation's timings.
    pub fn timed(mut self, t: Timings, flops: f64) -> PrecomputeReport {
        self.assembly_s = t.assembly_s;
        self.factor_s = t.factor_s;
        self.solve_s = t.solve_s;
        self.total_s = t.assembly_s + t.factor_s + t.solve_s;
        self.factor_gflops = if t.factor_s > 0.0 {
            flops / t.factor_s / 1e9
        } else {
            0.0
        };
        self
    }
}

/// A procedure's precomputation: its name, its cache file's name in a cache folder, and the
/// function that reads or builds it in a given cache file, reporting progress as (stage,
/// fraction).
pub struct Precomputable {
    pub name: &'static str,
    pub default_file: fn(&Path) -> PathBuf,
    pub run: fn(
        &Path,
        crate::models::bem::Progress,
    ) -> Result<PrecomputeReport, crate::models::bem::PrecomputeError>,
}

/// Every procedure with a precomputation.
pub const PRECOMPUTABLE: &[Precomputable] = &[super::myotomy::PRECOMPUTE];

/// The precomputation of procedure `name`.
pub fn find(name: &str) -> Option<&'static Precomputable> {
    PRECOMPUTABLE.iter().find(|p| p.name == name)
}
