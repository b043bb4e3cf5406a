//! The dynamic assessment's instructions in the headset: under the simulated runtime (through
//! the Khronos loader), a tree whose rule fires 1 s into the sandbox session puts a panel of
//! words before the trainee's eyes in the frames the runtime receives, and not before then.

mod common;
use common::Scratch;

use std::path::Path;

const WORDS: &str = "Keep both instruments in view";

fn run(out: &Path, tree: Option<&Path>) {
    let _ = std::fs::remove_dir_all(out);
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/sandbox-demo.toml");
    let mut c = common::bin();
    c.args(["run", "sandbox", "--xr-sim"])
        .arg(&trace)
        .arg("--out")
        .arg(out)
        .args([
            "--xr-duration",
            "2.2",
            "--eye-size",
            "270x300",
            "--no-window",
        ]);
    if let Some(t) = tree {
        c.arg("--assessment").arg(t);
    }
    common::ok(&c.output().expect("runs"));
}

fn frame(dir: &Path, k: u32) -> ((u32, u32), Vec<u8>) {
    vesalius::render::gpu::read_png(&dir.join(format!("xr-sim/frames/{k:04}_left.png")))
        .expect("frame dumped")
}

fn scratch() -> Scratch {
    common::tmp("xr-words", "instruction")
}

#[test]
fn an_instruction_shows_in_the_headset_while_it_is_current() {
    let base = scratch();
    // The sandbox's own tree, with one rule more: over 1 s simulated, say WORDS.
    let own = vesalius::procedures::sandbox::INFO.assessment;
    let tree = base.join("tree.toml");
    std::fs::write(
        &tree,
        format!(
            "{own}\n[[rule]]\nid = \"in_view\"\nmetric = \"session.simulated_s\"\nabove = 1.0\nsay = \"{WORDS}\"\n"
        ),
    )
    .expect("tree");
    let (with, without) = (base.join("with"), base.join("without"));
    run(&with, Some(&tree));
    run(&without, None);
    let events = std::fs::read_to_string(with.join("events.jsonl")).expect("events");
    let said: Vec<&str> = events.lines().filter(|l| l.contains(WORDS)).collect();
    assert_eq!(said.len(), 1, "{events}");
    assert!(said[0].contains("\"instruction\""), "{}", said[0]);
    // Frame 0 (before the rule fired): the same picture either way.
    let (size, a0) = frame(&with, 0);
    let (_, b0) = frame(&without, 0);
    assert_eq!(size, (270, 300));
    assert_eq!(a0, b0, "no panel before the instruction");
    // Frame 180 (2 s at 90 Hz): the panel, below the line of sight, across the middle.
    let (_, a) = frame(&with, 180);
    let (_, b) = frame(&without, 180);
    let (mut n, mut sx, mut sy, mut bright) = (0usize, 0f64, 0f64, 0usize);
    for (k, (p, q)) in a.chunks_exact(4).zip(b.chunks_exact(4)).enumerate() {
        if (0..3).any(|c| p[c].abs_diff(q[c]) > 8) {
            n += 1;
            sx += (k % 270) as f64;
            sy += (k / 270) as f64;
            // Text: light pixels on the panel's dark ground.
            if p[0] > 150 && p[1] > 140 {
                bright += 1;
            }
        }
    }
    let share = n as f64 / (270.0 * 300.0);
    assert!(
        share > 0.015,
        "the panel changed {:.2} % of the eye",
        share * 100.0
    );
    let (cx, cy) = (sx / n as f64, sy / n as f64);
    assert!((cx - 135.0).abs() < 50.0, "panel centred at x {cx:.0}");
    assert!(cy > 150.0, "panel below the middle: y {cy:.0}");
    assert!(bright > 20, "{bright} light text pixels");
}
