//! Precomputations a procedure needs before its first session (`vesalius precompute`): what
//! one is (a procedure's description names its own) and what it reports.

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

/// Progress of a long computation: (stage, fraction done).
pub type Progress<'a> = &'a (dyn Fn(&str, f64) + Sync);

/// A procedure's precomputation: its name, its cache file's name in a cache folder, and the
/// function that reads or builds it in a given cache file, reporting progress as (stage,
/// fraction).
pub struct Precomputable {
    pub name: &'static str,
    pub default_file: fn(&Path) -> PathBuf,
    pub run: fn(&Path, Progress) -> Result<PrecomputeReport, super::ModelError>,
}
