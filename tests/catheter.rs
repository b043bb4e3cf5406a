//! The catheterisation through the command line: the demo trace leads the guidewire into the
//! -y branch (the left hand's wrist rolled half a turn turns its angled tip) and runs the
//! catheter over it without a puncture, the head's force within the paper's 0.5-3.5 N, the
//! force over time in the report; 1 and 2 worker threads give the same bytes, the recording
//! replays byte for byte, and the headset's controllers (the roll through the simulated
//! runtime) lead the wire the same way.

mod common;
use common::{bin, ok, report, tmp, without_id};
use std::path::Path;

fn run(dir: &Path, threads: &str) -> Vec<u8> {
    std::fs::create_dir_all(dir).expect("dir");
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/catheter-demo.toml");
    let o = bin()
        .args([
            "--threads",
            threads,
            "run",
            "catheter",
            "--headless",
            "--trace",
        ])
        .arg(&trace)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(dir.join("out/report.json")).expect("report")
}

#[test]
fn the_demo_reaches_the_target_branch_the_same_on_one_and_two_threads_and_replays() {
    let d = tmp("catheter", "threads");
    let a = run(&d.join("t1"), "1");
    let b = run(&d.join("t2"), "2");
    assert_eq!(without_id(&a), without_id(&b), "1 and 2 threads differ");
    let r = report(&d.join("t1/out"));
    assert_eq!(r["procedure"], "catheter");
    assert_eq!(r["completed"], true, "{r}");
    let m = &r["metrics"];
    assert_eq!(m["punctures"], 0, "{r}");
    assert_eq!(m["wrong_branch"], 0, "{r}");
    assert!(m["reach_m"].as_f64().unwrap_or(0.0) >= 0.03, "{r}");
    let head = m["peak_head_normal_n"].as_f64().unwrap_or(0.0);
    assert!((0.5..=3.5).contains(&head), "head force {head} N");
    assert!(m["wall_contacts"].as_u64().unwrap_or(0) >= 1, "{r}");
    assert!(m["force_time_n_s"].as_f64().unwrap_or(0.0) > 0.0, "{r}");
    // The left hand's imaging: three runs of the pedal, two puffs of 4 mL/s (0.5 and 0.4 s),
    // 7.5 pulses a second over 5.0 s of fluoroscopy, each pulse's dose-area product the
    // same (one field, never collimated).
    let f = &m["fluoroscopy"];
    let num = |k: &str| f[k].as_f64().unwrap_or(f64::NAN);
    assert_eq!(
        (num("fluoro_runs"), num("contrast_runs")),
        (3.0, 2.0),
        "{f}"
    );
    assert!((num("contrast_ml") - 3.6).abs() < 1e-3, "{f}");
    assert!((num("fluoro_time_s") - 5.0).abs() < 0.01, "{f}");
    assert!((36.0..=39.0).contains(&num("pulses")), "{f}");
    let per_pulse = num("dap_gy_cm2") / num("pulses");
    assert!((1e-4..1e-2).contains(&per_pulse), "{f}");
    // The wire led: 30 mm and more into the target branch, well ahead of the catheter,
    // without entering the other branch or puncturing; the wall's force on it stays below
    // its puncture force (0.27 N).
    let w = &m["guidewire"];
    let wnum = |k: &str| w[k].as_f64().unwrap_or(f64::NAN);
    assert!(wnum("reach_m") >= 0.03, "{w}");
    assert!(wnum("lead_m") >= 0.05, "{w}");
    assert_eq!((wnum("wrong_branch"), wnum("punctures")), (0.0, 0.0), "{w}");
    assert!((0.0..0.27).contains(&wnum("peak_force_n")), "{w}");
    // The force over time: a sample every 20 ms over the 8.25 s session.
    let trace = m["force_trace"].as_array().cloned().unwrap_or_default();
    assert!(trace.len() >= 300, "{} samples", trace.len());
    let models: Vec<&str> = r["models"]
        .as_array()
        .map(|m| m.iter().filter_map(|x| x["name"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(models, ["catheter", "vessel", "collision", "guidewire"]);
    let o = bin()
        .args(["--threads", "2", "replay"])
        .arg(d.join("t1/out/input.vtrace"))
        .arg("--out")
        .arg(d.join("replay"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["report.json", "events.jsonl"] {
        assert_eq!(
            std::fs::read(d.join("replay").join(f)).expect("replayed"),
            std::fs::read(d.join("t1/out").join(f)).expect("original"),
            "{f}"
        );
    }
}

/// Headless frames of the catheterisation carry the fluoroscope's picture beside the eyes'
/// teaching view: grey, the picture's size, the catheter dark in the last one.
#[test]
fn headless_frames_write_the_fluoroscopes_picture() {
    let d = tmp("catheter", "fluoro");
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/catheter-demo.toml");
    let o = bin()
        .args([
            "run",
            "catheter",
            "--headless",
            "--frames",
            "3",
            "--eye-size",
            "64x48",
            "--trace",
        ])
        .arg(&trace)
        .arg("--out")
        .arg(d.join("out"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = d.join("out/frames/fluoro_0002.png");
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&png).expect("the last frame's picture"),
    ));
    let mut reader = decoder.read_info().expect("a png");
    let mut buf = vec![0; reader.output_buffer_size().expect("a size")];
    let info = reader.next_frame(&mut buf).expect("pixels");
    assert_eq!((info.width, info.height), (256, 256));
    let px = &buf[..info.buffer_size()];
    let channels = px.len() / (256 * 256);
    let grey: Vec<u8> = px.chunks(channels).map(|c| c[0]).collect();
    assert!(
        px.chunks(channels).all(|c| c[0] == c[1] && c[1] == c[2]),
        "grey"
    );
    // Dense is dark: the catheter and the contrast's roadmap take the darkest few percent,
    // the open field around the patient's tissue the lightest.
    let dark = grey.iter().filter(|&&g| g < 40).count();
    let light = grey.iter().filter(|&&g| g > 200).count();
    assert!(dark > 300 && light > 10_000, "dark {dark}, light {light}");
    // The HTML report's key frames are those pictures, and it has the console's table.
    let html = d.join("report.html");
    let said = ok(&bin()
        .arg("report")
        .arg(d.join("out"))
        .arg("--html")
        .arg(&html)
        .output()
        .expect("runs"));
    assert!(said.contains("3 key frames"), "{said}");
    let page = std::fs::read_to_string(&html).expect("the page");
    let last = std::fs::read(&png).expect("the picture");
    assert!(page.contains(&vesalius::assess::html::base64(&last)));
    assert!(page.contains("<td>fluoroscopy runs</td><td>3</td>"));
}

/// The C-arm under the pads, headless and in the headset under the simulated runtime: the
/// left pad held at its right edge for a second turns the arm 15 degrees LAO, at its top
/// edge for half a second 7.5 degrees cranial; the right pad at its top edge for 0.4 s
/// moves the table 2 cm towards the head. The headset reads the pads through the
/// trackpad's position and click; both runs agree within a display frame's worth.
#[test]
fn the_pads_turn_the_c_arm_and_move_the_table_headless_and_in_the_headset() {
    let d = tmp("catheter", "arm");
    std::fs::create_dir_all(d.join("in")).expect("dir");
    let hand = |side: &str, t: f64, at: &str, to: &str, pad: Option<&str>| {
        let pad = pad.map_or(String::new(), |p| format!("pad = \"{p}\"\n"));
        format!("[[{side}]]\nt_s = {t}\nposition = {at}\ntarget = {to}\n{pad}\n")
    };
    let (handle, ahead) = ("[-0.1, 0.0, 0.0]", "[0.0, 0.0, 0.0]");
    let (aside, away) = ("[-0.05, -0.04, 0.03]", "[0.0, -0.04, 0.03]");
    let mut trace = String::from("procedure = \"catheter\"\n\n");
    for (t, pad) in [
        (0.0, None),
        (0.2, Some("right")),
        (1.2, None),
        (1.4, Some("up")),
        (1.9, None),
        (2.2, None),
    ] {
        trace += &hand("left", t, aside, away, pad);
    }
    for (t, pad) in [(0.0, None), (0.2, Some("up")), (0.6, None), (2.2, None)] {
        trace += &hand("right", t, handle, ahead, pad);
    }
    let file = d.join("in/arm.toml");
    std::fs::write(&file, trace).expect("trace");
    let console = |out: &Path| {
        let r = report(out);
        let f = r["metrics"]["fluoroscopy"].clone();
        let num = |k: &str| f[k].as_f64().unwrap_or(f64::NAN);
        let table = f["table_cm"][0].as_f64().unwrap_or(f64::NAN);
        (num("lao_deg"), num("cranial_deg"), table)
    };
    ok(&bin()
        .args(["run", "catheter", "--headless", "--trace"])
        .arg(&file)
        .arg("--out")
        .arg(d.join("headless"))
        .output()
        .expect("runs"));
    let (lao, cranial, table) = console(&d.join("headless"));
    assert!((lao - 15.0).abs() < 0.05, "LAO {lao}");
    assert!((cranial - 7.5).abs() < 0.05, "cranial {cranial}");
    assert!((table - 2.0).abs() < 0.01, "table {table} cm");
    ok(&bin()
        .args(["run", "catheter", "--xr-sim"])
        .arg(&file)
        .arg("--out")
        .arg(d.join("xr"))
        .args(["--eye-size", "64x64", "--no-window", "--xr-duration", "2.3"])
        .output()
        .expect("runs"));
    let (xlao, xcranial, xtable) = console(&d.join("xr"));
    // A display frame is 11.1 ms: 0.17 degrees of turn, 0.06 cm of table.
    assert!(
        (xlao - lao).abs() < 0.35,
        "LAO {xlao} in the headset, {lao} headless"
    );
    assert!(
        (xcranial - cranial).abs() < 0.35,
        "cranial {xcranial}, {cranial}"
    );
    assert!((xtable - table).abs() < 0.12, "table {xtable}, {table}");
}

/// The demo's first 4.7 s in the headset (the simulated runtime plays the trace's roll as the
/// left controller's orientation, through the Khronos loader): the wire enters the target
/// branch as headless, its reach within 3 mm of the headless run's at the same time.
#[test]
fn the_headsets_wrist_roll_leads_the_wire_into_the_branch_as_headless() {
    let d = tmp("catheter", "wire_xr");
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/catheter-demo.toml");
    let cut = d.join("in/first.toml");
    std::fs::create_dir_all(d.join("in")).expect("dir");
    // The trace to 4.7 s: keys after it dropped, so the headless run ends there too.
    let text = std::fs::read_to_string(&trace).expect("demo");
    let mut kept = String::new();
    for block in text.split("\n\n") {
        let late = block
            .lines()
            .find_map(|l| l.strip_prefix("t_s = "))
            .and_then(|t| t.trim().parse::<f64>().ok())
            .is_some_and(|t| t > 4.7);
        if !late {
            kept += block;
            kept += "\n\n";
        }
    }
    std::fs::write(&cut, kept).expect("trace");
    ok(&bin()
        .args(["run", "catheter", "--headless", "--trace"])
        .arg(&cut)
        .arg("--out")
        .arg(d.join("headless"))
        .output()
        .expect("runs"));
    ok(&bin()
        .args(["run", "catheter", "--xr-sim"])
        .arg(&cut)
        .arg("--out")
        .arg(d.join("xr"))
        .args(["--eye-size", "64x64", "--no-window", "--xr-duration", "4.7"])
        .output()
        .expect("runs"));
    let wire = |out: &Path| report(out)["metrics"]["guidewire"].clone();
    let (h, x) = (wire(&d.join("headless")), wire(&d.join("xr")));
    let reach = |w: &serde_json::Value| w["reach_m"].as_f64().unwrap_or(f64::NAN);
    assert!(reach(&h) >= 0.03, "{h}");
    assert!(
        (reach(&x) - reach(&h)).abs() < 0.003,
        "headset {x}, headless {h}"
    );
    assert_eq!(x["wrong_branch"], 0, "{x}");
}
