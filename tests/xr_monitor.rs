//! What the headset shows, as the scenario says: under the simulated runtime (through the
//! Khronos loader), the myotomy's scenario (`[headset] view = "monitor"`) shows the
//! laparoscope's round picture on a 16:9 monitor standing in a dim room where the trainee
//! looks; the same scenario set to `"scope"` fills the view with the operative field. The
//! catheterisation's monitor shows the fluoroscope's grey picture instead of a scene.

mod common;
use common::Scratch;

use glam::Vec3;
use std::path::Path;
use vesalius::render::monitor::ROOM;
use vesalius::xr::room::{MONITOR_IN_STAGE_M, MONITOR_WIDTH_M};
use xr_bindings::stage::{DEFAULT_HEAD, stage_to_field};

const EYE: (u32, u32) = (270, 300);

/// One test's scratch folder (each its own: the tests run at once and each removes its own).
fn scratch(name: &str) -> Scratch {
    common::tmp("xr-monitor", name)
}

/// The myotomy's demo with the head turned to the monitor; its left eye at 0.33 s.
fn run(base: &Path, name: &str, scenario: &str) -> Vec<u8> {
    run_procedure(
        base,
        name,
        &vesalius::procedures::myotomy::INFO,
        scenario,
        30,
    )
}

/// A procedure's demo with the head turned to the monitor; its left eye at `frame` (90 a
/// second).
fn run_procedure(
    base: &Path,
    name: &str,
    info: &vesalius::sim::ProcedureInfo,
    scenario: &str,
    frame: u32,
) -> Vec<u8> {
    let out = base.join(name);
    let _ = std::fs::remove_dir_all(&out);
    let demo = info.demo_trace;
    let centre = stage_to_field(Vec3::from(MONITOR_IN_STAGE_M));
    let head = Vec3::from(DEFAULT_HEAD.0);
    let trace = base.join("trace.toml");
    std::fs::write(
        &trace,
        format!(
            "{demo}\n[[head]]\nt_s = 0.0\nposition = {:?}\ntarget = {:?}\n",
            head.to_array(),
            centre.to_array()
        ),
    )
    .expect("trace");
    let file = base.join(format!("{name}.toml"));
    std::fs::write(&file, scenario).expect("scenario");
    let mut c = common::bin();
    let duration = format!("{:.2}", f64::from(frame) / 90.0 + 0.07);
    c.args(["run", info.name, "--xr-sim"])
        .arg(&trace)
        .arg("--scenario")
        .arg(&file)
        .arg("--out")
        .arg(&out)
        .args([
            "--xr-duration",
            &duration,
            "--eye-size",
            "270x300",
            "--no-window",
        ]);
    common::ok(&c.output().expect("runs"));
    let (size, rgba) =
        vesalius::render::gpu::read_png(&out.join(format!("xr-sim/frames/{frame:04}_left.png")))
            .expect("frame");
    assert_eq!(size, EYE);
    rgba
}

/// A linear colour as the sRGB bytes the eye image stores.
fn srgb(c: f64) -> u8 {
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

#[test]
fn a_monitor_scenario_shows_the_scopes_round_picture_on_a_screen_in_a_dim_room() {
    let base = scratch("monitor");
    let own = vesalius::procedures::myotomy::INFO.scenario;
    assert!(
        own.contains("view = \"monitor\""),
        "the myotomy shows a monitor"
    );
    let monitor = run(&base, "monitor", own);
    let scope = run(
        &base,
        "scope",
        &own.replace("view = \"monitor\"", "view = \"scope\""),
    );
    let room = ROOM.map(srgb);
    let is_room = |p: &[u8]| (0..3).all(|k| p[k].abs_diff(room[k]) <= 1);
    let share = |img: &[u8]| {
        img.chunks_exact(4).filter(|p| is_room(p)).count() as f64 / (EYE.0 * EYE.1) as f64
    };
    // The scope view is the field all around; the monitor's room is most of the view.
    assert!(
        share(&scope) < 0.01,
        "room in the scope view: {}",
        share(&scope)
    );
    assert!(
        share(&monitor) > 0.8,
        "room around the monitor: {}",
        share(&monitor)
    );

    // The screen: everything that is not room, one rectangle as wide as the monitor seen from
    // the eye, 16:9.
    let (mut x0, mut x1, mut y0, mut y1) = (u32::MAX, 0, u32::MAX, 0);
    for (i, p) in monitor.chunks_exact(4).enumerate() {
        if !is_room(p) {
            let (x, y) = (i as u32 % EYE.0, i as u32 / EYE.0);
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
    }
    let (w, h) = ((x1 + 1 - x0) as f32, (y1 + 1 - y0) as f32);
    let [left, right, ..] = xr_bindings::vive::LEFT_FOV_RAD;
    let eye = Vec3::from(xr_bindings::stage::FIELD_ORIGIN_IN_STAGE_M) + head_offset();
    let distance = (Vec3::from(MONITOR_IN_STAGE_M) - eye).length();
    let expected = EYE.0 as f32 * MONITOR_WIDTH_M / distance / (right.tan() - left.tan());
    assert!(
        (w - expected).abs() < 4.0,
        "screen {w} px wide, expected {expected}"
    );
    assert!((w / h - 16.0 / 9.0).abs() < 0.2, "screen {w}x{h}");
    let at = |x: f32, y: f32| {
        let (x, y) = (x.round() as u32, y.round() as u32);
        let i = ((y * EYE.0 + x) * 4) as usize;
        [monitor[i], monitor[i + 1], monitor[i + 2]]
    };
    let (cx, cy) = (x0 as f32 + 0.5 * w, y0 as f32 + 0.5 * h);
    // In the middle of the picture: lit tissue (the esophagus's muscle is red).
    let mid = at(cx, cy);
    assert!(
        mid[0] > 60 && mid[0] > mid[2],
        "the picture's middle shows {mid:?}"
    );
    // At the screen's left and right ends the picture is black: the scope's image circle is
    // as tall as the screen, so its sides are outside it.
    for x in [x0 as f32 + 0.06 * w, x1 as f32 - 0.06 * w] {
        let side = at(x, cy);
        assert!(
            side.iter().all(|&v| v < 8),
            "outside the image circle at x {x}: {side:?}"
        );
    }
}

/// The left eye's place from the head's midpoint (stage frame): half the Vive's IPD left.
fn head_offset() -> Vec3 {
    Vec3::from(DEFAULT_HEAD.0) + Vec3::new(-0.5 * xr_bindings::vive::IPD_M, 0.0, 0.0)
}

/// The catheterisation (`[headset] view = "monitor"`) under the fluoroscope: the monitor in
/// the room shows the X-ray picture, grey, square and centred on the black screen, with the
/// dark catheter in a light field; no coloured scene.
#[test]
fn the_catheterisations_monitor_shows_the_fluoroscopes_grey_picture() {
    let base = scratch("catheter");
    let info = vesalius::procedures::catheter::INFO;
    assert!(info.scenario.contains("view = \"monitor\""));
    // 0.67 s: the pedal has been down since 0.3 s (the demo's first run).
    let eye = run_procedure(&base, "fluoro", &info, info.scenario, 60);
    let room = ROOM.map(srgb);
    let is_room = |p: &[u8]| (0..3).all(|k| p[k].abs_diff(room[k]) <= 1);
    let (mut x0, mut x1, mut y0, mut y1) = (u32::MAX, 0, u32::MAX, 0);
    for (i, p) in eye.chunks_exact(4).enumerate() {
        if !is_room(p) {
            let (x, y) = (i as u32 % EYE.0, i as u32 / EYE.0);
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
    }
    assert!(x1 > x0 && y1 > y0, "no screen in the eye");
    let (w, h) = ((x1 + 1 - x0) as f32, (y1 + 1 - y0) as f32);
    assert!((w / h - 16.0 / 9.0).abs() < 0.2, "screen {w}x{h}");
    let at = |x: f32, y: f32| {
        let (x, y) = (x.round() as u32, y.round() as u32);
        let i = ((y * EYE.0 + x) * 4) as usize;
        [eye[i], eye[i + 1], eye[i + 2]]
    };
    // The screen's ends are black (the square picture is as tall as the screen).
    let cy = y0 as f32 + 0.5 * h;
    for x in [x0 as f32 + 0.06 * w, x1 as f32 - 0.06 * w] {
        let side = at(x, cy);
        assert!(side.iter().all(|&v| v < 8), "the screen at x {x}: {side:?}");
    }
    // The picture: a square as tall as the screen, less a tenth at each edge. Every pixel is
    // grey (no hue: it is not the scope's coloured scene), with light field and dark parts
    // (the catheter, the collimator's blades).
    let side = 0.8 * h;
    let cx = x0 as f32 + 0.5 * w;
    let (mut light, mut dark, mut n) = (0, 0, 0);
    for y in (cy - 0.5 * side) as u32..(cy + 0.5 * side) as u32 {
        for x in (cx - 0.5 * side) as u32..(cx + 0.5 * side) as u32 {
            let p = at(x as f32, y as f32);
            let hue = p.iter().max().unwrap_or(&0) - p.iter().min().unwrap_or(&0);
            assert!(hue <= 2, "a coloured pixel {p:?} at {x},{y}");
            n += 1;
            light += usize::from(p[0] > 110);
            dark += usize::from(p[0] < 70);
        }
    }
    let (light, dark) = (light as f64 / n as f64, dark as f64 / n as f64);
    assert!(light > 0.3, "light field in {:.1} %", light * 100.0);
    assert!(dark > 0.005, "dark in {:.2} %", dark * 100.0);
}
