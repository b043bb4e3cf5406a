//! `vesalius precompute myotomy` at the paper's size (N = 11,160), the one full-size run of
//! the boundary-element precomputation: built into an empty cache, then read back from it
//! (corrupt, stale and cut-short files are rebuilt: `models::bem` tests, at a small size).

mod common;
use common::{bin, text, tmp};

fn json(out: &std::process::Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}: {}", text(out)))
}

#[test]
fn the_esophagus_is_precomputed_once_at_full_size_and_read_back() {
    let dir = tmp("precompute", "full");
    let cache = dir.join("myotomy.bem");
    let cache_arg = cache.to_string_lossy().to_string();
    let built = bin()
        .args(["precompute", "myotomy", "--json", "--cache", &cache_arg])
        .output()
        .expect("runs");
    assert_eq!(built.status.code(), Some(0), "{}", text(&built));
    let b = json(&built);
    assert_eq!(b["n"], 11_160);
    assert_eq!(b["elements"], 3_720);
    assert_eq!(b["from_cache"], false);
    assert!(
        b["rebuilt_because"]
            .as_str()
            .is_some_and(|w| w.contains("no cache yet"))
    );
    let gflops = b["factor_gflops"].as_f64().unwrap_or(0.0);
    assert!(gflops > 0.0, "{b}");
    // The progress bar went to standard error (not a terminal here: a line every 10 %).
    let err = String::from_utf8_lossy(&built.stderr);
    assert!(
        err.contains("assembly: 50 %") && err.contains("factorisation: 100 %"),
        "{err}"
    );

    let read = bin()
        .args(["precompute", "myotomy", "--json", "--cache", &cache_arg])
        .output()
        .expect("runs");
    assert_eq!(read.status.code(), Some(0), "{}", text(&read));
    let r = json(&read);
    assert_eq!(r["from_cache"], true);
    assert!(r["rebuilt_because"].is_null());
    assert_eq!(r["bytes"], b["bytes"]);
}
