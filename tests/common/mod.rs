//! Helpers the integration tests share: the binary, scratch folders that clean up after a
//! passing test, and a session's report.
#![allow(dead_code)] // each test file uses some of them

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary, its precomputation caches in one folder of the build's scratch space that
/// every integration test shares (the myotomy's esophagus is built once per build, not
/// once per test or into the user's own cache).
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vesalius"));
    c.env("VESALIUS_CACHE_DIR", cache_dir());
    c
}

/// The shared precomputation cache folder.
pub fn cache_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("vesalius-cache")
}

/// A finished command's stdout, which must have succeeded (else its output is shown).
pub fn ok(o: &Output) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

/// Runs the sandbox's demo trace headless into `out`, with `more` arguments.
pub fn run_sandbox(out: &Path, more: &[&std::ffi::OsStr]) -> String {
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/sandbox-demo.toml");
    ok(&bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(&trace)
        .arg("--out")
        .arg(out)
        .args(more)
        .output()
        .expect("runs"))
}

/// A finished command's stdout and stderr, one after the other.
pub fn text(o: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A scratch folder, removed when the test passes (kept when it fails, to look at).
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A fresh, empty scratch folder named after the test file (`group`) and the test.
pub fn tmp(group: &str, name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("vesalius-{group}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    Scratch(d)
}

/// A report without its session id (two sessions have two ids; everything else must agree).
pub fn without_id(report: &[u8]) -> String {
    String::from_utf8_lossy(report)
        .lines()
        .filter(|l| !l.trim_start().starts_with("\"session_id\""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// A session's report.json.
pub fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).expect("report.json"))
        .expect("JSON")
}

/// Pixels (RGBA8) whose channels differ by more than `tolerance` between two images of the
/// same size.
pub fn pixels_differing(a: &[u8], b: &[u8], tolerance: u8) -> usize {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > tolerance))
        .count()
}

/// The left eye of `look` at `snap`, rendered at `size` on `gpu`.
pub fn left_eye(
    gpu: &vesalius::render::Gpu,
    look: &vesalius::render::frames::Look,
    snap: &vesalius::sim::Snapshot,
    size: (u32, u32),
) -> Vec<u8> {
    let mut r = look.renderer(gpu).expect("shaders compile");
    let target = vesalius::render::EyeTarget::new(gpu, size);
    r.update(snap);
    r.render(
        target.target(r.multiview()),
        size,
        &look.eyes(&look.view, size),
    );
    let [left, _] = target.read(gpu).expect("read back");
    left
}

/// A trace for the simulated runtime whose controllers stay 10 cm over the block, pointing
/// away from it, for `seconds`: whatever the probe touches, a stylus made it.
pub fn controllers_held_away(dir: &std::path::Path, seconds: f64) -> std::path::PathBuf {
    let trace = dir.join("away.toml");
    let keys = format!(
        "procedure = \"sandbox\"\n\
         [[head]]\nt_s = 0.0\nposition = [0.0, 0.135, 0.16]\ntarget = [0.0, 0.015, 0.0]\n\
         [[right]]\nt_s = 0.0\nposition = [0.04, 0.13, 0.03]\ntarget = [0.04, 0.18, 0.03]\n\
         [[right]]\nt_s = {seconds}\nposition = [0.04, 0.13, 0.03]\ntarget = [0.04, 0.18, 0.03]\n\
         [[left]]\nt_s = 0.0\nposition = [-0.04, 0.13, 0.03]\ntarget = [-0.04, 0.18, 0.03]\n"
    );
    std::fs::write(&trace, keys).expect("trace");
    trace
}
