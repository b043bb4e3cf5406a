//! `vesalius precompute`: builds a procedure's precomputed model data into the cache.

use super::CliError;
use std::path::PathBuf;
use vesalius::models::bem::cache;
use vesalius::progress::Bar;
use vesalius::registry::CATALOG;
use vesalius::sim::precompute::Precomputable;

/// The procedures that have something to precompute, for the command line (the registered
/// ones whose description names a precomputation).
pub fn names() -> Vec<&'static str> {
    CATALOG
        .iter()
        .filter(|p| p.options.precompute.is_some())
        .map(|p| p.name)
        .collect()
}

/// The precomputation of procedure `name`.
fn find(name: &str) -> Option<&'static Precomputable> {
    CATALOG.find(name).and_then(|p| p.options.precompute)
}

pub fn precompute(
    procedure: &str,
    cache_file: Option<PathBuf>,
    json: bool,
) -> Result<(), CliError> {
    let Some(p) = find(procedure) else {
        return Err(CliError::Usage(format!(
            "{procedure}: nothing to precompute (only {})",
            names().join(", ")
        )));
    };
    let path = cache_file.unwrap_or_else(|| (p.default_file)(&cache::default_dir()));
    let bar = Bar::new();
    let progress = |stage: &str, f: f64| bar.show(stage, f);
    let r = (p.run)(&path, &progress).map_err(|e| CliError::Failed(e.to_string()))?;
    if json {
        let line = serde_json::to_string(&r).map_err(|e| CliError::Failed(e.to_string()))?;
        say!("{line}");
        return Ok(());
    }
    say!("cache {}", r.cache.display());
    match &r.rebuilt_because {
        None => say!("read from the cache (made from these inputs, checksum good)"),
        Some(w) => say!("built: {w}"),
    }
    say!(
        "elements {}  N {}  field elements {}",
        r.elements,
        r.n,
        r.field_elements
    );
    if !r.from_cache {
        say!(
            "assembly {:.2} s  LU {:.2} s ({:.1} GFLOP/s)  solves {:.2} s  total {:.2} s",
            r.assembly_s,
            r.factor_s,
            r.factor_gflops,
            r.solve_s,
            r.total_s
        );
    }
    say!("{:.1} MB on disk", r.bytes as f64 / 1e6);
    Ok(())
}
