//! The desktop window under Xvfb (CI installs `xvfb xauth` and the X11 client libraries): the
//! demo trace plays in the window in real time, and `--screenshot` saves the whole window at
//! the end. The screenshot must show the kidney in the 3D view and text in the side panels,
//! and the session's report must be the headless one.

mod common;
use common::Scratch;
use std::path::{Path, PathBuf};
use std::process::Command;

/// `vesalius` on a virtual 1920 x 1080 display of its own (`xvfb-run -a`), its arguments to
/// follow.
fn in_xvfb() -> Command {
    let mut c = Command::new("xvfb-run");
    c.args(["-a", "-s", "-screen 0 1920x1080x24"])
        .arg(env!("CARGO_BIN_EXE_vesalius"));
    c
}

fn read_png(p: &Path) -> (u32, u32, Vec<u8>) {
    let d = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(p).expect("screenshot written"),
    ));
    let mut r = d.read_info().expect("png");
    let mut buf = vec![0; r.output_buffer_size().expect("size")];
    let info = r.next_frame(&mut buf).expect("frame");
    buf.truncate(info.buffer_size());
    assert_eq!(info.color_type, png::ColorType::Rgba);
    (info.width, info.height, buf)
}

/// The command's stdout, after checking it succeeded (else its output is the failure).
fn succeeded(o: &std::process::Output) -> String {
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    stdout
}

/// A session's report.json.
fn read_report(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).expect("report.json"))
        .expect("JSON")
}

/// Fraction of the pixels in the box (fractions of width and height) that `pick` accepts.
fn share(img: &(u32, u32, Vec<u8>), x: (f32, f32), y: (f32, f32), pick: fn(&[u8]) -> bool) -> f64 {
    let (w, h, px) = img;
    let (x0, x1) = ((x.0 * *w as f32) as usize, (x.1 * *w as f32) as usize);
    let (y0, y1) = ((y.0 * *h as f32) as usize, (y.1 * *h as f32) as usize);
    let mut n = 0usize;
    for yy in y0..y1 {
        for xx in x0..x1 {
            let i = (yy * *w as usize + xx) * 4;
            n += usize::from(pick(&px[i..i + 4]));
        }
    }
    n as f64 / ((x1 - x0) * (y1 - y0)) as f64
}

/// Kidney parenchyma: dark red, red well above green and blue.
fn kidney(p: &[u8]) -> bool {
    p[0] > 60 && f32::from(p[0]) > 2.0 * f32::from(p[1]) && f32::from(p[0]) > 2.0 * f32::from(p[2])
}

/// Text on the panels' dark grey (27-32): a light pixel (egui's text is 140 grey).
fn light(p: &[u8]) -> bool {
    p[0] > 100 && p[1] > 100 && p[2] > 100
}

/// `procedure`'s demo trace played in a window under Xvfb, a screenshot at its end: the
/// scratch folder (`shot.png`, `out/`), the trace and how the run went.
fn demo_in_window(procedure: &str, name: &str) -> (Scratch, PathBuf, std::process::Output) {
    let dir = common::tmp("window", name);
    let trace = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/traces")
        .join(format!("{procedure}-demo.toml"));
    let o = in_xvfb()
        .args(["run", procedure, "--trace"])
        .arg(&trace)
        .arg("--screenshot")
        .arg(dir.join("shot.png"))
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)");
    (dir, trace, o)
}

#[test]
fn the_demo_plays_in_a_window_and_the_screenshot_shows_the_kidney_and_the_panels() {
    let (dir, trace, o) = demo_in_window("nephrectomy", "window");
    let shot = dir.join("shot.png");
    let stdout = succeeded(&o);
    // The window's session is the headless session: same trace, same report.
    let report = read_report(&dir.join("out"));
    assert_eq!(report["completed"], true, "{report}");
    let headless = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["run", "nephrectomy", "--headless", "--trace"])
        .arg(&trace)
        .arg("--out")
        .arg(dir.join("headless"))
        .output()
        .expect("runs");
    succeeded(&headless);
    let same = read_report(&dir.join("headless"));
    assert_eq!(report["state_hash"], same["state_hash"]);
    // The screenshot: the whole 1600x900 window.
    let img = read_png(&shot);
    assert!(img.0 >= 1280 && img.1 >= 720, "{}x{}", img.0, img.1);
    assert!(stdout.contains(&format!("screenshot {}x{}", img.0, img.1)));
    // The kidney fills a good part of the middle of the 3D view (between the panels).
    let organ = share(&img, (0.3, 0.7), (0.2, 0.9), kidney);
    assert!(
        organ > 0.08,
        "kidney in {:.1}% of the view's middle",
        organ * 100.0
    );
    // Side panels: text (light pixels, a few percent), not empty, not a flood of white.
    for (name, x) in [("left", (0.0, 0.15)), ("right", (0.83, 1.0))] {
        let text = share(&img, x, (0.05, 0.27), light);
        assert!(
            (0.003..0.3).contains(&text),
            "{name} panel: {:.2}% light pixels",
            text * 100.0
        );
        // No kidney colours there: the 3D view stays in the middle.
        let red = share(&img, x, (0.05, 0.27), kidney);
        assert!(red < 0.01, "{name} panel: {:.2}% kidney red", red * 100.0);
    }
}

/// Desktop mode, driven like a trainee would (begun at once with --start): xdotool moves the
/// mouse onto the tumour, clicks the right button there (the laser identifies it), and holds
/// the left button, so the laser cuts; the screenshot at 12 s ends the session. The mouse
/// waits 3 s after the window appears: on a loaded machine (this file's tests run side by
/// side on lavapipe) the first frames come slowly, and a click before the view is laid out
/// found nothing.
#[test]
fn desktop_mode_the_mouse_points_the_laser_and_the_button_cuts() {
    let dir = common::tmp("window", "desktop");
    // The window opens at the top left of the virtual screen: its 3D view spans about 270 to
    // 1300 pixels across, the kidney in its middle and the tumour at about (824, 374).
    let script = r#"
"$0" run nephrectomy --start --screenshot "$1/shot.png" --screenshot-at 12 --out "$1/out" &
app=$!
xdotool search --sync --name "Vesalius" > /dev/null
sleep 3
xdotool mousemove 824 374
sleep 0.3
xdotool click 3
sleep 0.3
xdotool mousemove 760 420
sleep 0.3
xdotool mousedown 1
for x in 765 770 775 780 785 790 795 800; do xdotool mousemove $x 430; sleep 0.2; done
xdotool mouseup 1
wait $app
"#;
    let o = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1920x1080x24", "sh", "-c", script])
        .arg(env!("CARGO_BIN_EXE_vesalius"))
        .arg(&*dir)
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth xdotool)");
    succeeded(&o);
    let report = read_report(&dir.join("out"));
    // The laser found the tumour and cut tissue.
    assert!(
        report["events"]["cut"].as_u64().unwrap_or(0) >= 1,
        "{report}"
    );
    assert!(report["metrics"]["cut_faces"].as_u64().unwrap_or(0) > 0);
    let steps = report["metrics"]["steps_done"].to_string();
    assert!(steps.contains("identify"), "{steps}");
    let simulated = report["simulated_s"].as_f64().expect("simulated_s");
    // The session ends with the screenshot, at the first window frame from 12 s on.
    assert!(simulated >= 12.0, "ended at {simulated} s");
    // The recorded input has the trigger pulled while the beam swept to the right.
    let rec = vesalius::trace::Recording::read(&dir.join("out/input.vtrace")).expect("recording");
    let pulled: Vec<glam::Vec3> = rec
        .frames
        .iter()
        .filter(|f| f.hands[1].buttons.trigger == 1.0)
        .map(|f| f.hands[1].pose.forward())
        .collect();
    // How many steps that is depends on how fast this machine steps the kidney while it also
    // renders (lavapipe on the CPU); a sweep needs a few.
    assert!(
        pulled.len() >= 10,
        "{} steps with the trigger pulled",
        pulled.len()
    );
    let (first, last) = (pulled[0], pulled[pulled.len() - 1]);
    assert!(last.x > first.x, "the beam swept right: {first} -> {last}");
    // The screenshot shows the key map under the view.
    let img = read_png(&dir.join("shot.png"));
    let keys = share(&img, (0.2, 0.8), (0.96, 1.0), light);
    assert!(
        keys > 0.01,
        "{:.2}% light pixels in the key map",
        keys * 100.0
    );
}

/// Under XR the window mirrors the headset: the left eye of each frame the headset got is
/// copied on the GPU into the window, which draws no scene of its own.
#[test]
fn the_xr_mirror_shows_the_headsets_eye_without_drawing_the_scene_again() {
    let dir = common::tmp("window", "mirror");
    // Two seconds of controllers held still beside the field, pointing away from it.
    let trace = dir.join("still.toml");
    std::fs::write(
        &trace,
        "procedure = \"nephrectomy\"\n\
         [[left]]\nt_s = 0.0\nposition = [-0.09, 0.07, 0.12]\ntarget = [-0.2, 0.1, 0.3]\n\
         [[left]]\nt_s = 2.0\nposition = [-0.09, 0.07, 0.12]\ntarget = [-0.2, 0.1, 0.3]\n\
         [[right]]\nt_s = 0.0\nposition = [0.12, 0.05, 0.15]\ntarget = [0.2, 0.1, 0.35]\n\
         [[right]]\nt_s = 2.0\nposition = [0.12, 0.05, 0.15]\ntarget = [0.2, 0.1, 0.35]\n",
    )
    .expect("trace written");
    let shot = dir.join("shot.png");
    // A monitor at 1.25 device pixels per point: the window and its panels scale with it.
    let o = in_xvfb()
        .env("WINIT_X11_SCALE_FACTOR", "1.25")
        .args(["run", "nephrectomy", "--xr-sim"])
        .arg(&trace)
        .arg("--out")
        .arg(dir.join("out"))
        .args(["--eye-size", "270x300", "--window-size", "1280x720"])
        .arg("--screenshot")
        .arg(&shot)
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)");
    let stdout = succeeded(&o);
    // The headset's session ran its frames; the window drew none of the scene itself.
    assert!(stdout.contains("1 session(s)"), "{stdout}");
    let line = stdout
        .lines()
        .find(|l| l.starts_with("window on"))
        .expect("window line");
    assert!(
        line.ends_with(" 0 of them drawing the scene (the rest mirrored an eye)"),
        "{line}"
    );
    let frames: u64 = line
        .split(": ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("window frames");
    assert!(frames >= 30, "{frames} window frames");
    // The mirrored eye shows the kidney in the middle of the view (the headset sees the field
    // from 16 cm; it is small in a 110-degree eye).
    let img = read_png(&shot);
    assert_eq!((img.0, img.1), (1600, 900), "1280 x 720 points at 1.25");
    let organ = share(&img, (0.35, 0.65), (0.3, 0.8), kidney);
    assert!(
        organ > 0.01,
        "kidney in {:.2}% of the view's middle",
        organ * 100.0
    );
    // And it is the headset's picture: the runtime's own dump of the left eye shows it too.
    let dumped = read_png(&dir.join("out/xr-sim/frames/0150_left.png"));
    let in_eye = share(&dumped, (0.3, 0.7), (0.3, 0.7), kidney);
    assert!(
        in_eye > 0.005,
        "kidney in {:.2}% of the dumped eye's middle",
        in_eye * 100.0
    );
}

/// Where the headset shows a monitor (the myotomy), the mirror shows the monitor's picture,
/// the scope's round image that the trainee operates by, not the dim room around it.
#[test]
fn the_xr_mirror_shows_the_monitors_picture_where_the_headset_shows_a_monitor() {
    let dir = common::tmp("window", "mirror-mon");
    let trace = dir.join("demo.toml");
    std::fs::write(&trace, vesalius::procedures::myotomy::INFO.demo_trace).expect("trace");
    let shot = dir.join("shot.png");
    let o = in_xvfb()
        .args(["run", "myotomy", "--xr-sim"])
        .arg(&trace)
        .arg("--out")
        .arg(dir.join("out"))
        .args(["--xr-duration", "1.0", "--eye-size", "270x300"])
        .args(["--window-size", "1280x720", "--screenshot"])
        .arg(&shot)
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)");
    let stdout = succeeded(&o);
    assert!(stdout.contains("1 session(s)"), "{stdout}");
    let img = read_png(&shot);
    // The room's colour (sRGB 53, 55, 60) is nowhere in the mirror; it fills the eye.
    let room =
        |p: &[u8]| p[0].abs_diff(53) <= 2 && p[1].abs_diff(55) <= 2 && p[2].abs_diff(60) <= 2;
    let in_mirror = share(&img, (0.0, 1.0), (0.0, 1.0), room);
    let eye = read_png(&dir.join("out/xr-sim/frames/0060_left.png"));
    let in_eye = share(&eye, (0.0, 1.0), (0.0, 1.0), room);
    assert!(in_eye > 0.8, "room in {:.1}% of the eye", in_eye * 100.0);
    assert!(
        in_mirror < 0.005,
        "room in {:.2}% of the mirror",
        in_mirror * 100.0
    );
    // The esophagus's red muscle in the middle of the picture: the scope's view, large.
    let organ = share(&img, (0.35, 0.65), (0.3, 0.8), kidney);
    assert!(
        organ > 0.05,
        "red tissue in {:.2}% of the middle",
        organ * 100.0
    );
}

/// A force-feedback session in the window: the simulated stylus presses the sandbox's block
/// with the probe while the window draws it; the session ends at --seconds with its report,
/// its recording replays to the same state, and the servo loop's line is printed.
#[test]
fn a_stylus_drives_the_probe_in_the_window_and_the_session_replays() {
    let dir = common::tmp("window", "stylus");
    let o = in_xvfb()
        .args(["run", "sandbox", "--haptics", "sim", "--seconds", "2"])
        .arg("--screenshot")
        .arg(dir.join("shot.png"))
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--records")
        .arg(dir.join("records.sqlite"))
        .args(["--trainee", "res-03"])
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)");
    let report = the_stylus_pressed(&o, &dir.join("out"), "time_up");
    let replay = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .arg("replay")
        .arg(dir.join("out/input.vtrace"))
        .arg("--out")
        .arg(dir.join("replay"))
        .output()
        .expect("runs");
    succeeded(&replay);
    let again = read_report(&dir.join("replay"));
    assert_eq!(again["state_hash"], report["state_hash"]);
    assert_eq!(again["steps"], report["steps"]);
    // The window stored the session in the records it was given (its Learning Centre
    // panel shows them).
    let list = succeeded(
        &Command::new(env!("CARGO_BIN_EXE_vesalius"))
            .args(["records", "list", "--trainee", "res-03", "--db"])
            .arg(dir.join("records.sqlite"))
            .output()
            .expect("runs"),
    );
    let id = report["session_id"].as_str().unwrap_or("?");
    assert!(
        list.lines()
            .any(|l| l.starts_with(id) && l.contains("res-03")),
        "{list}"
    );
}

/// A stylus in the headset, with the supervisor's mirror window open: the controllers stay
/// over the block pointing away, the stylus drives the probe into it, and the window names
/// the headset and the device.
#[test]
fn a_stylus_drives_the_probe_in_the_headset_with_the_mirror_open() {
    let dir = common::tmp("window", "xr-stylus");
    let trace = common::controllers_held_away(&dir, 2.0);
    let o = in_xvfb()
        .args(["run", "sandbox", "--xr-sim"])
        .arg(&trace)
        .args([
            "--xr-duration",
            "2",
            "--eye-size",
            "64x64",
            "--haptics",
            "sim",
        ])
        .arg("--out")
        .arg(dir.join("out"))
        // The window closes once its picture is taken at the session's end.
        .arg("--screenshot")
        .arg(dir.join("shot.png"))
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)");
    the_stylus_pressed(&o, &dir.join("out"), "xr_exit");
}

/// A window session with the simulated stylus on the probe succeeded, ended as `ended`, and
/// printed the window's and the device's lines; the stylus came down 26 mm from 15 mm above
/// the block, so the probe touched and pushed. Its report.
fn the_stylus_pressed(o: &std::process::Output, out: &Path, ended: &str) -> serde_json::Value {
    let stdout = succeeded(o);
    assert!(stdout.contains("window on "), "{stdout}");
    assert!(
        stdout.contains("simulated stylus on the right hand"),
        "{stdout}"
    );
    let report = read_report(out);
    assert_eq!(report["ended"], ended, "{report}");
    let f = report["metrics"]["max_probe_force_n"]
        .as_f64()
        .unwrap_or(0.0);
    let depth = report["metrics"]["max_probe_depth_m"]
        .as_f64()
        .unwrap_or(0.0);
    assert!(
        f > 0.05 && depth > 0.005,
        "probe {f} N at {depth} m: {report}"
    );
    report
}

/// The catheterisation's demo in the window shows the fluoroscope, not the 3D view: the
/// middle of the view is grey (the monitor's picture), with the catheter and the roadmap
/// dark in it and the open field light.
#[test]
fn the_catheterisation_plays_under_fluoroscopy_in_the_window() {
    let (dir, _, o) = demo_in_window("catheter", "window-fluoro");
    let shot = dir.join("shot.png");
    succeeded(&o);
    let report = read_report(&dir.join("out"));
    assert_eq!(report["completed"], true, "{report}");
    let img = read_png(&shot);
    let grey = |p: &[u8]| p[0] == p[1] && p[1] == p[2];
    let middle = share(&img, (0.4, 0.6), (0.3, 0.8), grey);
    assert!(
        middle > 0.99,
        "grey in {:.1}% of the view's middle",
        middle * 100.0
    );
    let dark = share(&img, (0.4, 0.6), (0.3, 0.8), |p| p[0] < 60 && p[0] == p[2]);
    let light = share(&img, (0.4, 0.6), (0.3, 0.8), |p| p[0] > 180 && p[0] == p[2]);
    assert!(
        dark > 0.02 && light > 0.2,
        "dark {:.1}%, light {:.1}%",
        dark * 100.0,
        light * 100.0
    );
}
