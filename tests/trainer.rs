//! The desktop trainee mode under Xvfb: identification needs a deliberate act, an action out
//! of the task's order is recorded and counted, and the results screen is on the screenshot
//! once the session has ended.

mod common;

use std::path::Path;
use std::process::Command;

/// The demo's first pose of the laser: its beam on the tumour.
const ON_TUMOUR: &str =
    "position = [0.09865, 0.04888, 0.14317]\ntarget = [0.01163, 0.02678, 0.02836]";

/// A nephrectomy trace: the grasper held aside, the laser at its first pose on the tumour
/// throughout, the mark button clicked at `click_s` if given.
fn resting_trace(click_s: Option<f32>) -> String {
    let mut t = format!(
        "procedure = \"nephrectomy\"\n\n[[left]]\nt_s = 0.0\nposition = [-0.03135, 0.04888, 0.14317]\ntarget = [-0.03135, 0.1, 0.14317]\n\n[[right]]\nt_s = 0.0\n{ON_TUMOUR}\n\n"
    );
    if let Some(c) = click_s {
        t += &format!("[[right]]\nt_s = {c}\n{ON_TUMOUR}\nmark = true\n\n");
        t += &format!("[[right]]\nt_s = {}\n{ON_TUMOUR}\n\n", c + 0.05);
    }
    t + &format!("[[right]]\nt_s = 3.0\n{ON_TUMOUR}\n")
}

#[test]
fn a_beam_resting_on_the_tumour_from_the_start_identifies_it_only_with_a_click() {
    let dir = common::tmp("trainer", "rest");
    for click in [None, Some(1.0)] {
        let trace = dir.join("rest.toml");
        std::fs::write(&trace, resting_trace(click)).expect("trace");
        let out = dir.join(if click.is_some() { "click" } else { "still" });
        common::ok(
            &common::bin()
                .args(["run", "nephrectomy", "--headless", "--trace"])
                .arg(&trace)
                .arg("--out")
                .arg(&out)
                .output()
                .expect("runs"),
        );
        let events = std::fs::read_to_string(out.join("events.jsonl")).expect("events");
        let found: Vec<u64> = events
            .lines()
            .filter(|l| l.contains("\"tumour_identified\""))
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .filter_map(|v| v["step"].as_u64())
            .collect();
        match click {
            // Three seconds on the tumour without moving or clicking: not identified.
            None => assert!(found.is_empty(), "{events}"),
            // The click at 1 s (step 250 at 4 ms) identifies it then.
            Some(_) => assert!(
                found.len() == 1 && (245..=260).contains(&found[0]),
                "{found:?}"
            ),
        }
    }
}

fn xvfb_run(args: &[&std::ffi::OsStr]) -> String {
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1920x1080x24"])
        .arg(env!("CARGO_BIN_EXE_vesalius"))
        .args(args)
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)");
    common::ok(&o)
}

fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).expect("report.json"))
        .expect("JSON")
}

#[test]
fn the_start_pose_identifies_nothing_and_the_results_screen_follows_the_session() {
    let dir = common::tmp("trainer", "idle");
    let shot = dir.join("shot.png");
    let out = dir.join("out");
    // The mouse stays off the window (the 1280x720 window opens at the screen's top left):
    // nothing deliberate happens for 2.5 s.
    let script = r#"
xdotool mousemove 1900 1050
"$0" run nephrectomy --start --window-size 1280x720 --screenshot "$1/shot.png" --screenshot-at 2.5 --out "$1/out"
"#;
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1920x1080x24", "sh", "-c", script])
        .arg(env!("CARGO_BIN_EXE_vesalius"))
        .arg(&*dir)
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth xdotool)");
    common::ok(&o);
    let r = report(&out);
    assert!(r["simulated_s"].as_f64().unwrap_or(0.0) >= 2.5, "{r}");
    assert!(r["events"].get("tumour_identified").is_none(), "{r}");
    assert_eq!(r["metrics"]["steps_done"], serde_json::json!([]), "{r}");
    // The results screen is drawn over the view: its header in the level's colour.
    let level = r["level"].as_str().expect("level");
    let c = vesalius::ui::screens::level_colour(level);
    let (size, px) = vesalius::render::gpu::read_png(&shot).expect("screenshot");
    let header = px
        .chunks_exact(4)
        .filter(|p| {
            p[0].abs_diff(c.r()) <= 6 && p[1].abs_diff(c.g()) <= 6 && p[2].abs_diff(c.b()) <= 6
        })
        .count();
    assert!(
        header > 5000,
        "{header} pixels of the {level} header in a {size:?} screenshot"
    );
}

#[test]
fn a_cut_before_the_margin_is_marked_is_recorded_out_of_order() {
    let dir = common::tmp("trainer", "order");
    // The laser aims at the parenchyma and cuts at once, before anything is identified or
    // marked.
    let trace = dir.join("cut-first.toml");
    let key = |t: f32, trigger: f32| {
        format!(
            "[[right]]\nt_s = {t}\nposition = [-0.01644, 0.03811, 0.12005]\ntarget = [-0.00975, 0.01970, 0.01751]\ntrigger = {trigger}\n\n"
        )
    };
    let text = format!(
        "procedure = \"nephrectomy\"\n\n[[left]]\nt_s = 0.0\nposition = [-0.03135, 0.04888, 0.14317]\ntarget = [-0.03135, 0.1, 0.14317]\n\n{}{}{}{}",
        key(0.0, 0.0),
        key(0.3, 1.0),
        key(1.0, 1.0),
        key(1.2, 0.0)
    );
    std::fs::write(&trace, text).expect("trace");
    let out = dir.join("out");
    xvfb_run(&[
        "run".as_ref(),
        "nephrectomy".as_ref(),
        "--trace".as_ref(),
        trace.as_os_str(),
        "--window-size".as_ref(),
        "1280x720".as_ref(),
        "--screenshot".as_ref(),
        dir.join("shot.png").as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let events = std::fs::read_to_string(out.join("events.jsonl")).expect("events");
    let first = events
        .lines()
        .find(|l| l.contains("\"out_of_order\""))
        .unwrap_or_else(|| panic!("no out_of_order event: {events}"));
    assert!(
        first.contains("\"step\":\"cut\"") && first.contains("\"expected\":\"identify\""),
        "{first}"
    );
    let r = report(&out);
    assert!(
        r["metrics"]["out_of_order"].as_u64().unwrap_or(0) >= 1,
        "{r}"
    );
    // The assessment counts it: the order's leaf is below full marks.
    let nodes = r["assessment"]["nodes"].to_string();
    assert!(nodes.contains("quality/step_order"), "{nodes}");
    let instruction = events
        .lines()
        .any(|l| l.contains("\"instruction\"") && l.contains("step_order"));
    assert!(instruction, "the rule told the trainee: {events}");
}
