//! Sessions that lose nothing: the recording streams while the session runs, so `kill -9`
//! loses at most a second; SIGINT and SIGTERM end it with an interrupted report; a corrupted
//! recording is an error naming its block; a full disk is a clear error with no report; bad
//! output folders, endless traces and absurd scenarios are refused before the first step.

mod common;
use common::{Scratch, bin, report, text};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};
use vesalius::registry::builtin;

/// The shipped scenario at coarse resolution (fast, far above real time).
fn coarse(dir: &Path) -> PathBuf {
    let text = builtin("nephrectomy")
        .expect("builtin")
        .replace("level = 5", "level = 3")
        .replace("vessel_rings = 64", "vessel_rings = 12");
    let p = dir.join("coarse.toml");
    std::fs::write(&p, text).expect("scenario");
    p
}

fn demo_trace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/nephrectomy-demo.toml")
}

/// `vesalius run nephrectomy --headless --trace TRACE`, to be completed by the caller.
fn headless(trace: &Path) -> Command {
    let mut c = bin();
    c.args(["run", "nephrectomy", "--headless", "--trace"])
        .arg(trace);
    c
}

/// A coarse demo session paced in real time, writing into `dir/out`.
fn start_realtime(dir: &Path) -> Child {
    headless(&demo_trace())
        .arg("--realtime")
        .arg("--scenario")
        .arg(coarse(dir))
        .arg("--out")
        .arg(dir.join("out"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starts")
}

/// Waits until the session's recording exists (its header is written just before the first
/// step) and returns when that was seen.
fn wait_for_recording(dir: &Path, child: &mut Child) -> Instant {
    let rec = dir.join("out/input.vtrace");
    for _ in 0..6000 {
        if rec.is_file() {
            return Instant::now();
        }
        if let Ok(Some(s)) = child.try_wait() {
            panic!("the session ended before recording ({s})");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!("no recording after 30 s");
}

fn replay(rec: &Path, out: &Path) -> Output {
    bin()
        .arg("replay")
        .arg(rec)
        .arg("--out")
        .arg(out)
        .output()
        .expect("runs")
}

#[test]
fn kill_9_leaves_a_recording_that_replays_to_within_a_second_of_the_kill() {
    let dir = tmp("kill");
    let mut child = start_realtime(&dir);
    let started = wait_for_recording(&dir, &mut child);
    std::thread::sleep(Duration::from_millis(3000));
    child.kill().expect("SIGKILL");
    let ran_s = started.elapsed().as_secs_f64();
    let _ = child.wait();
    assert!(
        !dir.join("out/report.json").exists(),
        "no report for a killed session"
    );
    let o = replay(&dir.join("out/input.vtrace"), &dir.join("replayed"));
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("stops short"),
        "the replay says the recording was cut: {}",
        text(&o)
    );
    let r = report(&dir.join("replayed"));
    assert_eq!(r["ended"], "truncated_recording");
    let replayed_s = r["simulated_s"].as_f64().expect("simulated_s");
    // Real-time pacing: the session had simulated at most `ran_s` when it was killed, and
    // blocks go to disk at least once a simulated second. Half a second more allows for the
    // step that follows the header and a loaded machine's pacing lag.
    assert!(
        replayed_s <= ran_s + 0.05,
        "{replayed_s} s replayed, killed after {ran_s} s"
    );
    assert!(
        replayed_s >= ran_s - 1.5,
        "{replayed_s} s replayed, killed after {ran_s} s: more than a second lost"
    );
}

fn interrupted_by(signal: &str, code: i32) {
    let dir = tmp(signal);
    let mut child = start_realtime(&dir);
    wait_for_recording(&dir, &mut child);
    std::thread::sleep(Duration::from_millis(1000));
    let pid = child.id().to_string();
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &pid])
        .status()
        .expect("kill");
    assert!(sent.success());
    let o = child.wait_with_output().expect("ends");
    assert_eq!(o.status.code(), Some(code), "{}", text(&o));
    assert!(text(&o).contains(&format!("interrupted by SIG{signal}")));
    let r = report(&dir.join("out"));
    assert_eq!(r["completed"], false);
    assert_eq!(r["ended"], "interrupted");
    let steps = r["steps"].as_u64().expect("steps");
    assert!(steps > 0 && r["simulated_s"].as_f64().unwrap_or(99.0) < 10.0);
    // The interrupted recording is whole: it replays to the same report, byte for byte.
    let o = replay(&dir.join("out/input.vtrace"), &dir.join("replayed"));
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        std::fs::read(dir.join("replayed/report.json")).expect("replayed"),
        std::fs::read(dir.join("out/report.json")).expect("original")
    );
}

#[test]
fn sigterm_ends_the_session_with_an_interrupted_report() {
    interrupted_by("TERM", 143);
}

#[test]
fn sigint_ends_the_session_with_an_interrupted_report() {
    interrupted_by("INT", 130);
}

/// A coarse demo session, recorded into `dir/out`.
fn short_session(dir: &Path) -> PathBuf {
    let out = dir.join("out");
    let o = headless(&demo_trace())
        .arg("--scenario")
        .arg(coarse(dir))
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", text(&o));
    out.join("input.vtrace")
}

#[test]
fn a_flipped_byte_in_a_recording_is_an_error_naming_its_block() {
    let dir = tmp("flip");
    let rec = short_session(&dir);
    let bytes = std::fs::read(&rec).expect("recording");
    // Somewhere among the frames, and near the end (the end block).
    for at in [bytes.len() / 2, bytes.len() * 3 / 4, bytes.len() - 3] {
        let mut bad = bytes.clone();
        bad[at] ^= 0x10;
        let p = dir.join(format!("flipped-{at}.vtrace"));
        std::fs::write(&p, &bad).expect("write");
        let o = replay(&p, &dir.join(format!("replay-{at}")));
        assert_eq!(o.status.code(), Some(1), "byte {at}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("block "), "byte {at}: {err}");
        assert!(
            err.contains(&p.display().to_string()),
            "names the file: {err}"
        );
        assert!(!dir.join(format!("replay-{at}/report.json")).exists());
        let check = bin().arg("check").arg(&p).output().expect("check runs");
        assert_eq!(check.status.code(), Some(1));
    }
}

#[test]
fn a_file_size_limit_gives_a_clear_error_and_no_report() {
    let dir = tmp("ulimit");
    let out = dir.join("out");
    // 64 blocks of 512 bytes: the recording's header fits, its first second of frames too,
    // the whole demo (about 850 kB) does not.
    let script = format!(
        "ulimit -f 64; exec '{}' run nephrectomy --headless --trace '{}' --scenario '{}' --out '{}'",
        env!("CARGO_BIN_EXE_vesalius"),
        demo_trace().display(),
        coarse(&dir).display(),
        out.display()
    );
    let o = Command::new("sh")
        .args(["-c", &script])
        .output()
        .expect("sh");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("cannot write the recording"), "{err}");
    assert!(err.contains("no report was written"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.join("report.json").exists());
    // What did reach the disk is a recording cut short, which still replays.
    let o = replay(&out.join("input.vtrace"), &dir.join("replayed"));
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(
        report(&dir.join("replayed"))["ended"],
        "truncated_recording"
    );
}

#[test]
fn an_unwritable_out_fails_before_the_first_step() {
    let dir = tmp("unwritable");
    let file = dir.join("a-file");
    std::fs::write(&file, "not a folder").expect("write");
    for out in [
        file.join("out"),
        PathBuf::from("/proc/vesalius-cannot-write-here"),
    ] {
        let o = headless(&demo_trace())
            .arg("--out")
            .arg(&out)
            .output()
            .expect("runs");
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("--out") && err.contains(&out.display().to_string()),
            "{err}"
        );
        assert!(o.stdout.is_empty(), "nothing ran: {}", text(&o));
    }
}

#[test]
fn a_new_session_removes_the_old_report_before_it_starts() {
    let dir = tmp("stale");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).expect("out");
    std::fs::write(out.join("report.json"), "{\"completed\": true}").expect("old report");
    // A session that fails mid-way (its trace names a key far past the limit) writes nothing.
    let long = dir.join("long.toml");
    std::fs::write(
        &long,
        std::fs::read_to_string(demo_trace()).expect("trace")
            + "\n[[left]]\nt_s = 1e300\nposition = [0.0, 0.1, 0.1]\ntarget = [0.0, 0.0, 0.0]\n",
    )
    .expect("long trace");
    let o = headless(&long)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("t_s") && err.contains("--max-session"),
        "{err}"
    );
    // The trace was refused before the output folder was touched...
    assert!(out.join("report.json").exists());
    // ...and a session that does start clears the old report first, so a crash mid-way
    // never leaves it beside the new recording.
    let mut child = start_realtime(&dir);
    wait_for_recording(&dir, &mut child);
    assert!(!out.join("report.json").exists(), "old report removed");
    child.kill().expect("kill");
    let _ = child.wait();
}

#[test]
fn absurd_scenarios_are_refused_before_anything_is_built() {
    let dir = tmp("absurd");
    let base = builtin("nephrectomy").expect("builtin");
    // A legal trace of 3.9 hours: two keys per hand.
    let long = dir.join("long.toml");
    let key = |hand: &str, t: f64| {
        format!("[[{hand}]]\nt_s = {t:.1}\nposition = [0.0, 0.1, 0.1]\ntarget = [0.0, 0.0, 0.0]\n")
    };
    let trace = format!(
        "procedure = \"nephrectomy\"\n{}{}{}",
        key("left", 0.0),
        key("left", 14000.0),
        key("right", 0.0)
    );
    std::fs::write(&long, trace).expect("long trace");
    let cases = [
        (
            "huge.toml",
            base.replace("level = 5", "level = 7")
                .replace("vessel_rings = 64", "vessel_rings = 1024")
                .replace("vessel_segments = 32", "vessel_segments = 256"),
            demo_trace(),
            "simulated points",
        ),
        (
            "tiny-direction.toml",
            base.replace(
                "tumour_direction = [",
                "tumour_direction = [1e-30, 0.0, 0.0] # was [",
            ),
            demo_trace(),
            "anatomy.tumour_direction",
        ),
        (
            "costly.toml",
            base.replace("level = 5", "level = 6")
                .replace("dt_s = 0.004", "dt_s = 0.0001"),
            long,
            "point-steps",
        ),
    ];
    for (name, scenario, trace, says) in cases {
        let p = dir.join(name);
        std::fs::write(&p, &scenario).expect("scenario");
        let o = headless(&trace)
            .arg("--scenario")
            .arg(&p)
            .output()
            .expect("runs");
        assert_eq!(o.status.code(), Some(1), "{name}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says) && err.contains(name), "{name}: {err}");
    }
}

fn tmp(name: &str) -> Scratch {
    common::tmp("sessions", name)
}
