//! A session's output folder: made and tested for writing before the first step, cleared of
//! an earlier session's report, and filled so that it is whole or visibly absent. The
//! recording streams in while the session runs; events, timing and, last of all, the report
//! are written under temporary names, synced and renamed when it ends.

use super::{Outcome, Recorded, SessionError};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The files a session writes, besides `frames/` and `profiler.csv`.
pub const REPORT: &str = "report.json";
pub const EVENTS: &str = "events.jsonl";
pub const RECORDING: &str = "input.vtrace";
pub const TIMING: &str = "timing.json";

pub(super) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> SessionError + '_ {
    move |source| SessionError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// A new session's id: 16 hex digits from the wall clock, the process and a counter. Every
/// file of the output set carries it; a replay keeps the recording's.
pub fn new_session_id() -> String {
    static COUNT: AtomicU64 = AtomicU64::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let parts = [
        nanos.to_le_bytes().to_vec(),
        std::process::id().to_le_bytes().to_vec(),
        COUNT.fetch_add(1, Ordering::Relaxed).to_le_bytes().to_vec(),
    ];
    for b in parts.iter().flatten() {
        h = (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Makes `dir`, proves it takes a file (written, synced and removed), and removes the report,
/// events and timing an earlier session left there, so they never stand beside this session's
/// recording. Call it before the first step.
pub fn prepare(dir: &Path) -> Result<(), SessionError> {
    std::fs::create_dir_all(dir).map_err(|e| SessionError::Out {
        dir: dir.display().to_string(),
        reason: format!("cannot create it: {e}"),
    })?;
    let probe = dir.join(".vesalius-write-test");
    let tried = std::fs::File::create(&probe)
        .and_then(|mut f| f.write_all(b"vesalius").and_then(|()| f.sync_all()));
    let _ = std::fs::remove_file(&probe);
    tried.map_err(|e| SessionError::Out {
        dir: dir.display().to_string(),
        reason: format!("cannot write into it: {e}"),
    })?;
    for name in [REPORT, EVENTS, TIMING] {
        let p = dir.join(name);
        match std::fs::remove_file(&p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(io(&p)(e)),
        }
    }
    Ok(())
}

/// Writes `bytes` to `dir/name` through a synced temporary file and a rename.
fn write_whole(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), SessionError> {
    let path = dir.join(name);
    let tmp = dir.join(format!(".{name}.partial"));
    let done = std::fs::File::create(&tmp)
        .and_then(|mut f| f.write_all(bytes).and_then(|()| f.sync_all()));
    if let Err(e) = done {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(&tmp)(e));
    }
    std::fs::rename(&tmp, &path).map_err(io(&path))
}

/// Writes the output set into `dir`: the recording (unless it streamed there already), the
/// events, the timing and, last, the report, so that a failure on the way leaves no report.
pub fn write_outputs(o: &Outcome, dir: &Path) -> Result<(), SessionError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let recording = dir.join(RECORDING);
    match &o.recording {
        Recorded::Streamed(p) if same_file(p, &recording) => {}
        Recorded::Streamed(p) => {
            std::fs::copy(p, &recording).map_err(io(&recording))?;
        }
        Recorded::InMemory(r) => r.write(&recording).map_err(io(&recording))?,
    }
    let id = serde_json::json!({
        "session_id": o.report.session_id,
        "procedure": o.report.procedure,
    });
    let mut lines = serde_json::to_string(&id).unwrap_or_default();
    lines.push('\n');
    for e in &o.events {
        lines += &serde_json::to_string(e).unwrap_or_default();
        lines.push('\n');
    }
    write_whole(dir, EVENTS, lines.as_bytes())?;
    let steps_per_s = o.report.steps as f64 / o.wall_s.max(1e-9);
    let timing = serde_json::json!({
        "session_id": o.report.session_id,
        "wall_s": o.wall_s,
        "steps_per_s": steps_per_s,
        "realtime_factor": steps_per_s * o.report.dt_s as f64,
        "threads": rayon::current_num_threads(),
        "compute": o.report.compute,
        "adapter": o.report.adapter,
    });
    let timing = serde_json::to_string_pretty(&timing).unwrap_or_default() + "\n";
    write_whole(dir, TIMING, timing.as_bytes())?;
    let report = serde_json::to_string_pretty(&o.report).unwrap_or_default() + "\n";
    write_whole(dir, REPORT, report.as_bytes())
}

fn same_file(a: &Path, b: &Path) -> bool {
    let canon = |p: &Path| -> Option<PathBuf> { p.canonicalize().ok() };
    a == b || (canon(a).is_some() && canon(a) == canon(b))
}
