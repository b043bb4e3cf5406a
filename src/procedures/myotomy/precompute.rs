//! The myotomy's precomputation: the default scenario's esophagus's boundary-element
//! responses, in the cache file its sessions read.

use super::anatomy::Esophagus;
use super::plugin::{INFO, cache_file};
use super::scenario::Scenario;
use crate::models::bem::PrecomputeError;
use crate::models::bem::system::lu_flops;
use crate::sim::ModelError;
use crate::sim::precompute::{Precomputable, PrecomputeReport, Progress};
use std::path::{Path, PathBuf};

/// Its precomputation, named in its description (`ProcedureInfo::precompute`).
pub const PRECOMPUTE: Precomputable = Precomputable {
    name: "myotomy",
    default_file,
    run,
};

/// The default scenario's esophagus.
fn esophagus() -> Result<Esophagus, PrecomputeError> {
    let s = Scenario::parse("builtin myotomy scenario", INFO.scenario)?;
    Ok(Esophagus::new(&s.esophagus_params()))
}

fn default_file(dir: &Path) -> PathBuf {
    match esophagus() {
        Ok(e) => cache_file(dir, &e),
        Err(_) => dir.join("myotomy.bem"),
    }
}

fn run(path: &Path, progress: Progress) -> Result<PrecomputeReport, ModelError> {
    let e = esophagus()?;
    let par = faer::Par::rayon(rayon::current_num_threads());
    let (pre, why) = e.problem.precompute_cached(&e.field, path, par, progress)?;
    let report = PrecomputeReport {
        procedure: "myotomy",
        cache: path.to_path_buf(),
        from_cache: pre.from_cache,
        rebuilt_because: why.map(|w| w.to_string()),
        elements: e.problem.elements.len(),
        n: pre.n,
        field_elements: pre.field.len(),
        assembly_s: 0.0,
        factor_s: 0.0,
        factor_gflops: 0.0,
        solve_s: 0.0,
        total_s: 0.0,
        bytes: std::fs::metadata(path).map(|m| m.len()).unwrap_or(0),
    };
    Ok(pre.timings.fill(report, lu_flops(pre.n)))
}
