//! The Done-when of the XR issue: the nephrectomy demo trace, played by the simulated runtime
//! through the Khronos loader, drives `vesalius run --xr-sim` to a completed procedure with
//! vibration recorded and stereo frames dumped; a second run gives the same report (drawn
//! smaller: what the trainee sees does not change what the simulation does).

mod common;
use std::path::Path;
use std::process::Command;
use vesalius::procedures::nephrectomy;
use vesalius::sim::Hand;
use vesalius::xr::{HapticProfile, Pulse};

fn run(out: &Path, eye_size: &str) -> serde_json::Value {
    let _ = std::fs::remove_dir_all(out);
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/nephrectomy-demo.toml");
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["run", "nephrectomy", "--xr-sim"])
        .arg(&trace)
        .arg("--out")
        .arg(out)
        .args(["--eye-size", eye_size, "--no-window"])
        .output()
        .expect("runs");
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&std::fs::read(out.join("report.json")).expect("report.json"))
        .expect("JSON report")
}

/// Mean absolute difference between two RGBA images, per channel level.
fn difference(a: &Path, b: &Path) -> f64 {
    let read = |p: &Path| {
        let d = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(p).expect("frame dumped"),
        ));
        let mut r = d.read_info().expect("png");
        let mut buf = vec![0; r.output_buffer_size().expect("size")];
        let info = r.next_frame(&mut buf).expect("frame");
        buf.truncate(info.buffer_size());
        (info.width, info.height, buf)
    };
    let (wa, ha, pa) = read(a);
    let (wb, hb, pb) = read(b);
    assert_eq!((wa, ha), (270, 300));
    assert_eq!((wa, ha), (wb, hb));
    let sum: u64 = pa.iter().zip(&pb).map(|(x, y)| x.abs_diff(*y) as u64).sum();
    sum as f64 / pa.len() as f64
}

#[test]
fn the_demo_trace_under_the_simulated_runtime_completes_with_vibration_and_stereo_frames() {
    let base = common::tmp("xr-demo", "demo");
    // A quarter of the Vive's panel per side: the same path, less software rasterising.
    let first = run(&base.join("a"), "270x300");
    assert_eq!(first["completed"], true, "{first}");
    assert_eq!(first["events"]["tumour_removed"], 1, "{first}");
    let sim = base.join("a/xr-sim");
    // The session walked the whole OpenXR state graph, once.
    let states: Vec<String> = std::fs::read_to_string(sim.join("session-states.log"))
        .expect("state log")
        .lines()
        .map(|l| l.rsplit(' ').next().unwrap_or("").to_string())
        .collect();
    assert_eq!(
        states,
        [
            "IDLE",
            "READY",
            "SYNCHRONIZED",
            "VISIBLE",
            "FOCUSED",
            "VISIBLE",
            "SYNCHRONIZED",
            "STOPPING",
            "IDLE",
            "EXITING"
        ]
    );
    // Vibration: the laser's pulses while it cuts, the grasper's while it holds the tumour,
    // each hand's pulses ended by a stop.
    let haptics = std::fs::read_to_string(sim.join("haptics.jsonl")).expect("haptics log");
    let lines: Vec<serde_json::Value> = haptics
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object a line"))
        .collect();
    let pulses = |hand: &str| {
        lines
            .iter()
            .filter(|l| l["hand"] == hand && l.get("amplitude").is_some())
            .count()
    };
    assert!(pulses("right") >= 100, "{} laser pulses", pulses("right"));
    assert!(pulses("left") >= 10, "{} grasper pulses", pulses("left"));
    for l in &lines {
        if let Some(a) = l["amplitude"].as_f64() {
            assert!((0.0..=1.0).contains(&a) && l["frequency_hz"].as_f64().is_some());
        }
    }
    // The laser's pulses are its cuts' ticks and the buzz of its beam's pressure on the
    // tissue, nothing else. The grasper's hand feels the jaws take hold of the tumour as a
    // knock of its own.
    let at = |hand: &str, hz: f32| {
        lines
            .iter()
            .filter(|l| l["hand"] == hand && l["frequency_hz"] == f64::from(hz))
            .count()
    };
    let cut_hz = Pulse::Cut { faces: 1 }.buzz().frequency_hz;
    let beam_hz = HapticProfile::for_tool(nephrectomy::INFO.tool(Hand::Right)).frequency_hz;
    let ticks = at("right", cut_hz);
    assert!(ticks >= 50, "{ticks} cut ticks");
    assert_eq!(ticks + at("right", beam_hz), pulses("right"));
    let knocks = at("left", Pulse::Grasp.buzz().frequency_hz);
    assert!(knocks >= 1, "{knocks} grasp pulses");
    assert!(
        knocks < pulses("left"),
        "the grasper also buzzes while it holds"
    );
    // Stereo frames, every 30th: the organ is drawn and the eyes see it from 63 mm apart.
    let frames = std::fs::read_dir(sim.join("frames"))
        .expect("frames")
        .count();
    assert!(frames >= 2 * 60, "{frames} eye images");
    let disparity = difference(
        &sim.join("frames/0600_left.png"),
        &sim.join("frames/0600_right.png"),
    );
    assert!(disparity > 0.5, "left and right differ by {disparity}");
    let drawn = difference(
        &sim.join("frames/0600_left.png"),
        &sim.join("frames/0000_left.png"),
    );
    assert!(drawn > 0.1, "the scene changes over the procedure: {drawn}");
    // Same trace, same bytes, whatever the eyes' size.
    let mut second = run(&base.join("b"), "64x72");
    // Two sessions, two ids; everything else is the same.
    assert_ne!(first["session_id"], second["session_id"]);
    second["session_id"] = first["session_id"].clone();
    assert_eq!(first, second);
}
