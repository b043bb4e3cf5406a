//! `vesalius report SESSION --html FILE` loaded in headless Chromium (Debian's `chromium`):
//! a session with rendered frames, stored in the records, gives one self-contained page
//! whether it is named by its folder or by its id; Chromium's DOM holds the score tree, the
//! level and the plots, and its screenshot shows the plots' lines and the score bars.

mod common;
use common::{bin, ok, report, run_sandbox, tmp};
use std::path::Path;
use std::process::{Command, Stdio};
use vesalius::assess::html::{LEFT, RIGHT, SCORE};

/// Headless Chromium with the flags this closed machine needs (no background networking).
fn chromium(profile: &Path) -> Command {
    let mut c = Command::new("chromium");
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

/// Pixels within 12 of `rgb` on every channel.
fn pixels_like(png: &Path, rgb: [u8; 3]) -> usize {
    let file = std::fs::File::open(png).expect("screenshot");
    let mut dec = png::Decoder::new(std::io::BufReader::new(file));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec.read_info().expect("PNG");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("frame");
    let channels = info.color_type.samples();
    buf[..info.buffer_size()]
        .chunks(channels)
        .filter(|p| (0..3).all(|k| p[k].abs_diff(rgb[k]) <= 12))
        .count()
}

fn hex(c: &str) -> [u8; 3] {
    let v = u32::from_str_radix(c.trim_start_matches('#'), 16).expect("colour");
    [(v >> 16) as u8, (v >> 8) as u8, v as u8]
}

#[test]
fn the_html_report_renders_in_chromium_with_its_tree_and_plots() {
    let d = tmp("report_html", "page");
    let out = d.join("out");
    let db = d.join("records.sqlite");
    let more = ["--frames", "2", "--eye-size", "160x120", "--records"];
    let mut args: Vec<&std::ffi::OsStr> = more.iter().map(|a| std::ffi::OsStr::new(*a)).collect();
    args.push(db.as_os_str());
    args.extend(["--trainee", "res-07"].map(std::ffi::OsStr::new));
    run_sandbox(&out, &args);
    let r = report(&out);
    let id = r["session_id"].as_str().unwrap_or("?").to_string();
    let by_dir = d.join("by-folder.html");
    let said = ok(&bin()
        .arg("report")
        .arg(&out)
        .arg("--html")
        .arg(&by_dir)
        .output()
        .expect("runs"));
    assert!(said.contains("2 key frames"), "{said}");
    let by_id = d.join("by-id.html");
    ok(&bin()
        .args(["report", &id, "--html"])
        .arg(&by_id)
        .arg("--db")
        .arg(&db)
        .output()
        .expect("runs"));
    let page = std::fs::read_to_string(&by_dir).expect("page");
    assert_eq!(page, std::fs::read_to_string(&by_id).expect("page"));
    // Self-contained: nothing is fetched (the SVG namespace is a name, not a fetch).
    assert!(
        !page.contains("src=\"http") && !page.contains("href="),
        "fetches"
    );
    assert_eq!(page.matches("src=\"data:image/png;base64,").count(), 2);
    let timeline = r["timeline"].as_array().map_or(0, Vec::len);
    assert!(timeline >= 60, "{timeline} samples over 7 s");

    let dom = chromium(&d.join("profile1"))
        .arg("--dump-dom")
        .stderr(Stdio::null())
        .arg(format!("file://{}", by_dir.display()))
        .output()
        .expect("chromium (apt-get install chromium)");
    let dom = String::from_utf8_lossy(&dom.stdout);
    let level = r["level"].as_str().unwrap_or("?");
    assert!(dom.contains(&format!(": {level}</h2>")), "{dom}");
    assert!(dom.contains("id=\"tree\"") && dom.contains("completion time"));
    // The motion analysis, the tips' path as the report has it (4 decimals below 1 m).
    let path = r["motion"]["path_m"].as_f64().expect("the motion analysis");
    assert!(
        dom.contains("id=\"motion\"") && dom.contains(&format!("<td>{path:.4}</td>")),
        "{dom}"
    );
    assert_eq!(
        dom.matches("<polyline").count(),
        5,
        "two speeds, two forces, the score"
    );

    let shot = d.join("shot.png");
    let o = chromium(&d.join("profile2"))
        .arg("--window-size=1100,1800")
        .arg(format!("--screenshot={}", shot.display()))
        .arg(format!("file://{}", by_dir.display()))
        .output()
        .expect("chromium (apt-get install chromium)");
    assert!(shot.exists(), "{}", String::from_utf8_lossy(&o.stderr));
    let (left, right, green) = (
        pixels_like(&shot, hex(LEFT)),
        pixels_like(&shot, hex(RIGHT)),
        pixels_like(&shot, hex(SCORE)),
    );
    eprintln!("pixels: left {left}, right {right}, score green {green}");
    // Each instrument's lines span the plots; the score bars are 160 px wide, 10 high.
    assert!(left > 300 && right > 300, "left {left}, right {right}");
    assert!(green > 6 * 1000, "green {green}");
}
