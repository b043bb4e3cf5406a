//! `vesalius precompute`: builds a procedure's precomputed model data into the cache.

use super::CliError;
use super::progress::Bar;
use std::path::{Path, PathBuf};
use vesalius::models::bem::cache;
use vesalius::models::bem::system::lu_flops;
use vesalius::procedures::myotomy::anatomy::{Esophagus, EsophagusParams};

/// The procedures that have something to precompute.
pub const PRECOMPUTABLE: [&str; 1] = ["myotomy"];

/// The myotomy's cache file in `dir`.
pub fn myotomy_cache(dir: &Path) -> PathBuf {
    dir.join("myotomy.bem")
}

pub fn precompute(
    procedure: &str,
    cache_file: Option<PathBuf>,
    json: bool,
) -> Result<(), CliError> {
    if procedure != "myotomy" {
        return Err(CliError::Usage(format!(
            "{procedure}: nothing to precompute (only {})",
            PRECOMPUTABLE.join(", ")
        )));
    }
    let path = cache_file.unwrap_or_else(|| myotomy_cache(&cache::default_dir()));
    let e = Esophagus::new(&EsophagusParams::default());
    let bar = Bar::new();
    let progress = |stage: &str, f: f64| bar.show(stage, f);
    let par = faer::Par::rayon(rayon::current_num_threads());
    let (pre, why) = e
        .problem
        .precompute_cached(&e.field, &path, par, &progress)
        .map_err(|err| CliError::Failed(err.to_string()))?;
    let n = pre.n;
    let t = pre.timings;
    let total = t.assembly_s + t.factor_s + t.solve_s;
    let gflops = if t.factor_s > 0.0 {
        lu_flops(n) / t.factor_s / 1e9
    } else {
        0.0
    };
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    if json {
        say!(
            "{}",
            serde_json::json!({
                "procedure": procedure,
                "cache": path.display().to_string(),
                "from_cache": pre.from_cache,
                "rebuilt_because": why.as_ref().map(|w| w.to_string()),
                "elements": e.problem.elements.len(),
                "n": n,
                "field_elements": pre.field.len(),
                "assembly_s": t.assembly_s,
                "factor_s": t.factor_s,
                "factor_gflops": gflops,
                "solve_s": t.solve_s,
                "total_s": total,
                "bytes": bytes,
            })
        );
        return Ok(());
    }
    say!("cache {}", path.display());
    match &why {
        None => say!("read from the cache (made from these inputs, checksum good)"),
        Some(w) => say!("built: {w}"),
    }
    say!(
        "elements {}  N {n}  field elements {}",
        e.problem.elements.len(),
        pre.field.len()
    );
    if !pre.from_cache {
        say!(
            "assembly {:.2} s  LU {:.2} s ({gflops:.1} GFLOP/s)  solves {:.2} s  total {total:.2} s",
            t.assembly_s,
            t.factor_s,
            t.solve_s
        );
    }
    say!("{:.1} MB on disk", bytes as f64 / 1e6);
    Ok(())
}
