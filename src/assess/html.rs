//! A session's report as one self-contained HTML page (`vesalius report SESSION --html
//! FILE`): the score and the level with its fuzzy memberships, the score tree node by node
//! with each leaf's value beside its expert's and novice's references, plots of the session
//! over time (the instruments' speeds and forces, the score) with its alarms, instructions and
//! task steps marked, and its rendered key frames. Everything is inline (SVG plots, PNG frames
//! as data URIs, one style sheet): the file opens anywhere, with nothing fetched.

use serde_json::Value;
use std::fmt::Write;

/// Colours of the plots' series (left instrument, right instrument, score) and markers.
pub const LEFT: &str = "#1f77b4";
pub const RIGHT: &str = "#d62728";
pub const SCORE: &str = "#2ca02c";
const ALARM: &str = "#e6550d";
const INSTRUCTION: &str = "#9467bd";
const STEP: &str = "#7f7f7f";

/// Escapes text for HTML.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Standard base64 (for PNG data URIs).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= c.len() {
                out.push(char::from(A[((n >> (18 - 6 * k)) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A number for people: a few significant digits.
fn num(v: Option<f64>) -> String {
    match v {
        None => "-".into(),
        Some(0.0) => "0".into(),
        Some(x) if x.abs() >= 100.0 => format!("{x:.0}"),
        Some(x) if x.abs() >= 1.0 => format!("{x:.2}"),
        Some(x) => format!("{x:.4}"),
    }
}

/// One series of a plot.
pub struct Series<'a> {
    pub name: &'a str,
    pub colour: &'a str,
    pub points: Vec<(f64, f64)>,
}

/// A marker on a plot's time axis.
pub struct Marker {
    pub t_s: f64,
    pub colour: &'static str,
    pub label: String,
}

/// A line plot as inline SVG: axes with their ranges (the values' up to `y_max`, else 5 %
/// above the largest), the series, vertical markers.
pub fn plot(
    title: &str,
    unit: &str,
    y_max: Option<f64>,
    series: &[Series],
    markers: &[Marker],
) -> String {
    let (w, h, left, bottom) = (640.0, 220.0, 56.0, 28.0);
    let all = series.iter().flat_map(|s| s.points.iter());
    let (mut t1, mut y1) = (0.0f64, 0.0f64);
    for &(t, y) in all {
        t1 = t1.max(t);
        y1 = y1.max(y);
    }
    let t1 = if t1 > 0.0 { t1 } else { 1.0 };
    let y1 = match y_max {
        Some(m) if m > 0.0 => m,
        _ if y1 > 0.0 => y1 * 1.05,
        _ => 1.0,
    };
    let x = |t: f64| left + (w - left - 8.0) * t / t1;
    let y = |v: f64| (h - bottom) - (h - bottom - 8.0) * v / y1;
    let mut svg = format!(
        "<figure><figcaption>{}</figcaption><svg xmlns=\"http://www.w3.org/2000/svg\" \
         width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" role=\"img\" aria-label=\"{}\">\
         <rect x=\"{left}\" y=\"8\" width=\"{}\" height=\"{}\" fill=\"#fafafa\" stroke=\"#ccc\"/>",
        esc(title),
        esc(title),
        w - left - 8.0,
        h - bottom - 8.0
    );
    for m in markers {
        let _ = write!(
            svg,
            "<line x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"8\" y2=\"{1}\" stroke=\"{2}\" \
             stroke-dasharray=\"3 3\"><title>{3}</title></line>",
            x(m.t_s),
            h - bottom,
            m.colour,
            esc(&m.label)
        );
    }
    for s in series {
        let pts: Vec<String> = s
            .points
            .iter()
            .map(|&(t, v)| format!("{:.1},{:.1}", x(t), y(v)))
            .collect();
        let _ = write!(
            svg,
            "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"2\" points=\"{}\">\
             <title>{}</title></polyline>",
            s.colour,
            pts.join(" "),
            esc(s.name)
        );
    }
    let _ = write!(
        svg,
        "<text x=\"{left}\" y=\"{}\" font-size=\"11\">0 s</text>\
         <text x=\"{}\" y=\"{}\" font-size=\"11\" text-anchor=\"end\">{t1:.1} s</text>\
         <text x=\"{}\" y=\"20\" font-size=\"11\">{} {}</text>\
         <text x=\"{}\" y=\"{}\" font-size=\"11\" text-anchor=\"end\">0</text></svg>",
        h - 10.0,
        w - 8.0,
        h - 10.0,
        left + 4.0,
        num(Some(y1)),
        esc(unit),
        left - 4.0,
        h - bottom
    );
    let legend: Vec<String> = series
        .iter()
        .map(|s| {
            format!(
                "<span style=\"color:{}\">&#9632; {}</span>",
                s.colour,
                esc(s.name)
            )
        })
        .collect();
    let _ = write!(
        svg,
        "<div class=\"legend\">{}</div></figure>",
        legend.join(" ")
    );
    svg
}

/// The markers of a session's events: alarms, instructions and task steps at their times.
pub fn markers(events: &[Value], dt_s: f64) -> Vec<Marker> {
    events
        .iter()
        .filter_map(|e| {
            let t_s = e["step"].as_f64()? * dt_s;
            let (colour, label) = match e["kind"].as_str()? {
                "alarm" => (ALARM, format!("alarm: {}", e["message"].as_str()?)),
                "instruction" => (
                    INSTRUCTION,
                    format!("instruction: {}", e["message"].as_str()?),
                ),
                "task_step" => (STEP, format!("step done: {}", e["name"].as_str()?)),
                _ => return None,
            };
            Some(Marker { t_s, colour, label })
        })
        .collect()
}

/// The page for a session's report (`report.json`), its events (`events.jsonl`, each line
/// parsed; may be empty) and its key frames (PNG bytes, left eyes).
pub fn page(report: &Value, events: &[Value], frames: &[Vec<u8>]) -> String {
    let a = &report["assessment"];
    let proc_ = report["procedure"].as_str().unwrap_or("?");
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Vesalius session {id}: {proc_}</title><style>\
         body{{font-family:sans-serif;margin:24px;color:#222}}table{{border-collapse:collapse}}\
         td,th{{padding:3px 8px;border-bottom:1px solid #ddd;text-align:left}}\
         .bar{{background:#2ca02c;height:10px}}.barbox{{background:#eee;width:160px}}\
         figure{{margin:12px 0}}figcaption{{font-weight:bold}}.legend{{font-size:12px}}\
         .frames img{{width:320px;margin-right:8px}}</style></head><body>\
         <h1>{title}: {proc_}</h1><p>Session {id}, {done}, {sim} s simulated, {err} errors.</p>\
         <h2 id=\"score\">Score {score} / 100: {level}</h2>",
        id = esc(report["session_id"].as_str().unwrap_or("?")),
        proc_ = esc(proc_),
        title = esc(a["title"].as_str().unwrap_or("Assessment")),
        done = if report["completed"].as_bool() == Some(true) {
            "completed"
        } else {
            "not completed"
        },
        sim = num(report["simulated_s"].as_f64()),
        err = report["errors"].as_u64().unwrap_or(0),
        score = num(a["score"].as_f64()),
        level = esc(a["level"].as_str().unwrap_or("?")),
    );
    h.push_str("<table id=\"levels\"><tr><th>level</th><th>membership</th><th></th></tr>");
    for l in super::fuzzy::LEVELS {
        let m = a["memberships"][l].as_f64().unwrap_or(0.0);
        let _ = write!(
            h,
            "<tr><td>{l}</td><td>{:.2}</td><td><div class=\"barbox\"><div class=\"bar\" \
             style=\"width:{:.0}%\"></div></div></td></tr>",
            m,
            100.0 * m
        );
    }
    h.push_str(
        "</table><h2>Score tree</h2><table id=\"tree\"><tr><th>node</th><th>share</th>\
         <th>measure</th><th>value</th><th>expert</th><th>novice</th><th>score</th><th></th></tr>",
    );
    for n in a["nodes"].as_array().into_iter().flatten() {
        let path = n["path"].as_str().unwrap_or("");
        let depth = path.matches('/').count();
        let name = path.rsplit('/').next().unwrap_or(path);
        let score = n["score"].as_f64();
        let _ = write!(
            h,
            "<tr><td style=\"padding-left:{}px\">{}</td><td>{:.0} %</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td>{}</td><td><div class=\"barbox\"><div class=\"bar\" \
             style=\"width:{:.0}%\"></div></div></td></tr>",
            8 + 18 * depth,
            esc(&name.replace('_', " ")),
            100.0 * n["weight"].as_f64().unwrap_or(0.0),
            esc(n["metric"].as_str().unwrap_or("")),
            num(n["value"].as_f64()),
            num(n["expert"].as_f64()),
            num(n["novice"].as_f64()),
            score.map_or("left out".into(), |s| format!("{s:.1}")),
            score.unwrap_or(0.0)
        );
    }
    h.push_str("</table>");
    motion_table(&mut h, &report["motion"]);
    console_table(&mut h, &report["metrics"]["fluoroscopy"]);
    h.push_str("<h2>Over time</h2>");
    let timeline = report["timeline"].as_array().cloned().unwrap_or_default();
    let dt = report["dt_s"].as_f64().unwrap_or(0.0);
    let marks = markers(events, dt);
    let series = |field: &str, k: usize| -> Vec<(f64, f64)> {
        timeline
            .iter()
            .filter_map(|s| Some((s["t_s"].as_f64()?, s[field][k].as_f64()?)))
            .collect()
    };
    let score_series: Vec<(f64, f64)> = timeline
        .iter()
        .filter_map(|s| Some((s["t_s"].as_f64()?, s["score"].as_f64()?)))
        .collect();
    for (title, unit, field) in [
        ("Instrument speed", "m/s", "speed_m_per_s"),
        ("Force on the instruments", "N", "force_n"),
    ] {
        h.push_str(&plot(
            title,
            unit,
            None,
            &[
                Series {
                    name: "left",
                    colour: LEFT,
                    points: series(field, 0),
                },
                Series {
                    name: "right",
                    colour: RIGHT,
                    points: series(field, 1),
                },
            ],
            &marks,
        ));
    }
    h.push_str(&plot(
        "Score so far",
        "points",
        Some(100.0),
        &[Series {
            name: "score",
            colour: SCORE,
            points: score_series,
        }],
        &marks,
    ));
    h.push_str("<p class=\"legend\">Dashed lines: ");
    for (c, what) in [
        (ALARM, "alarms"),
        (INSTRUCTION, "instructions"),
        (STEP, "task steps"),
    ] {
        let _ = write!(h, "<span style=\"color:{c}\">&#9474; {what}</span> ");
    }
    h.push_str("</p>");
    if !frames.is_empty() {
        h.push_str("<h2>Key frames</h2><div class=\"frames\">");
        for f in frames {
            let _ = write!(
                h,
                "<img alt=\"key frame\" src=\"data:image/png;base64,{}\">",
                base64(f)
            );
        }
        h.push_str("</div>");
    }
    h.push_str("</body></html>\n");
    h
}

/// The motion analysis (`report.json`'s `motion`), one row a measure (nothing for an old
/// report without it).
fn motion_table(h: &mut String, motion: &Value) {
    const ROWS: [(&str, &str, &str); 10] = [
        ("path_m", "path of both tips", "m"),
        ("left_path_m", "path of the left tip", "m"),
        ("right_path_m", "path of the right tip", "m"),
        ("movements", "movements", ""),
        ("economy", "economy of motion", ""),
        ("ldlj", "smoothness (log dimensionless jerk)", ""),
        ("idle_s", "idle time", "s"),
        ("speed_m_per_s", "mean speed while moving", "m/s"),
        ("bimanual", "bimanual speed correlation", ""),
        ("instruments", "instruments that worked", ""),
    ];
    measures(h, ("Motion analysis", "motion"), motion, &ROWS, false);
}

/// An interventional console's figures (`metrics.fluoroscopy`, where the procedure works
/// under fluoroscopy): the dose and contrast an interventional educator reads first.
fn console_table(h: &mut String, console: &Value) {
    const ROWS: [(&str, &str, &str); 9] = [
        ("fluoro_time_s", "fluoroscopy time", "s"),
        ("fluoro_runs", "fluoroscopy runs", ""),
        ("pulses", "pulses", ""),
        (
            "reference_kerma_mgy",
            "air kerma at the reference point",
            "mGy",
        ),
        ("dap_gy_cm2", "dose-area product", "Gy cm²"),
        ("contrast_ml", "contrast", "mL"),
        ("contrast_runs", "contrast puffs", ""),
        ("lao_deg", "C-arm at the end: LAO (negative: RAO)", "°"),
        (
            "cranial_deg",
            "C-arm at the end: cranial (negative: caudal)",
            "°",
        ),
    ];
    measures(
        h,
        ("Fluoroscopy and contrast", "console"),
        console,
        &ROWS,
        true,
    );
}

/// A table of measures under a heading (`title`, the table's `id`): one row for each of
/// `rows` (key in `values`, label, unit); nothing where `values` is not an object. Counts
/// are written as integers where `counts` says so; measures as [`num`] writes them.
fn measures(
    h: &mut String,
    (title, id): (&str, &str),
    values: &Value,
    rows: &[(&str, &str, &str)],
    counts: bool,
) {
    let Some(m) = values.as_object() else { return };
    let _ = write!(
        h,
        "<h2>{title}</h2><table id=\"{id}\"><tr><th>measure</th><th>value</th>\
         <th>unit</th></tr>"
    );
    for (key, label, unit) in rows {
        let value = match m.get(*key) {
            Some(v) if counts && v.is_u64() => v.to_string(),
            v => num(v.and_then(Value::as_f64)),
        };
        let _ = write!(
            h,
            "<tr><td>{label}</td><td>{value}</td><td>{unit}</td></tr>"
        );
    }
    h.push_str("</table>");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_examples() {
        // RFC 4648, section 10.
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(plain.as_bytes()), coded, "{plain}");
        }
    }

    #[test]
    fn a_plot_scales_its_series_into_the_frame_and_marks_its_events() {
        let svg = plot(
            "speed <m/s>",
            "m/s",
            None,
            &[Series {
                name: "left",
                colour: LEFT,
                points: vec![(0.0, 0.0), (2.0, 1.0)],
            }],
            &[Marker {
                t_s: 1.0,
                colour: ALARM,
                label: "alarm: near".into(),
            }],
        );
        // x from 56 to 632 over 0-2 s; y from 192 (0) to 8 + (184 - 184 / 1.05).
        assert!(svg.contains("points=\"56.0,192.0 632.0,16.8\""), "{svg}");
        assert!(svg.contains("x1=\"344.0\""), "{svg}");
        assert!(svg.contains("speed &lt;m/s&gt;"));
    }

    /// A report with an interventional console gets its table, each figure as `num` writes
    /// it; one without gets none.
    #[test]
    fn the_console_shows_where_the_report_has_one() {
        let report = serde_json::json!({
            "metrics": {"fluoroscopy": {
                "fluoro_time_s": 4.8, "fluoro_runs": 3, "pulses": 38,
                "reference_kerma_mgy": 0.76, "dap_gy_cm2": 0.0921, "contrast_ml": 3.6,
                "contrast_runs": 2, "lao_deg": -15.0, "cranial_deg": 0.0
            }}
        });
        let page = page(&report, &[], &[]);
        assert!(page.contains("<table id=\"console\">"));
        for row in [
            format!(
                "<td>fluoroscopy time</td><td>{}</td><td>s</td>",
                num(Some(4.8))
            ),
            format!("<td>dose-area product</td><td>{}</td>", num(Some(0.0921))),
            format!("<td>contrast</td><td>{}</td><td>mL</td>", num(Some(3.6))),
            format!("(negative: RAO)</td><td>{}</td>", num(Some(-15.0))),
            "<td>fluoroscopy runs</td><td>3</td>".to_string(),
        ] {
            assert!(page.contains(&row), "{row}");
        }
        let plain = super::page(&serde_json::json!({"metrics": {}}), &[], &[]);
        assert!(!plain.contains("id=\"console\""));
    }
}
