//! The validation table of a calibration as one self-contained HTML page (`vesalius records
//! calibrate --html FILE`): per metric both groups' medians and IQRs, the Mann-Whitney test,
//! the effect size, whether it separates the groups, and the references it set.

use super::calibrate::{Calibration, Row};
use std::fmt::Write;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A value for the table: 0 decimals from 100, 2 from 1, 3 from 0.01, else 3 significant
/// digits in scientific notation.
pub fn num(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.2}")
    } else if v.abs() >= 0.01 {
        format!("{v:.3}")
    } else {
        format!("{v:.2e}")
    }
}

fn cell_spread(s: Option<super::stats::Spread>) -> String {
    s.map_or("<td>-</td><td>-</td>".into(), |s| {
        format!(
            "<td>{}</td><td>{}&ndash;{}</td>",
            num(s.median),
            num(s.q1),
            num(s.q3)
        )
    })
}

fn row(out: &mut String, r: &Row) {
    let (p, u) = r.test.map_or(("-".into(), "-".into()), |t| {
        (
            format!("{:.4}{}", t.p, if t.exact { "" } else { "*" }),
            format!("{}", t.u),
        )
    });
    let refs = r
        .now
        .map_or(String::new(), |n| format!("{}, {}", num(n.0), num(n.1)));
    let was = r
        .was
        .filter(|w| Some(*w) != r.now)
        .map_or(String::new(), |w| {
            format!(" <small>(was {}, {})</small>", num(w.0), num(w.1))
        });
    let _ = writeln!(
        out,
        "<tr class=\"{}\"><td>{}<br><small>{}</small></td><td>{}</td><td>{}</td>{}<td>{}</td>{}<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}{}</td><td>{}</td></tr>",
        if r.separates { "yes" } else { "no" },
        esc(&r.metric),
        esc(&r.path),
        if r.better == super::tree::Better::Lower {
            "lower"
        } else {
            "higher"
        },
        r.expert.map_or(0, |s| s.n),
        cell_spread(r.expert),
        r.novice.map_or(0, |s| s.n),
        cell_spread(r.novice),
        u,
        p,
        r.effect.map_or("-".into(), |e| format!("{e:+.2}")),
        if r.separates { "yes" } else { "no" },
        refs,
        was,
        esc(&r.note),
    );
}

/// The page.
pub fn page(c: &Calibration) -> String {
    let mut out = String::new();
    let title = format!("Construct validity: {}", c.procedure);
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\
         <style>body{{font-family:sans-serif;margin:2em;color:#222}}\
         table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:4px 8px;\
         text-align:right}}td:first-child,th:first-child{{text-align:left}}\
         tr.yes td{{background:#eef8ee}}tr.no td{{background:#fbf1f1}}small{{color:#666}}\
         </style></head><body>\n<h1>{}</h1>\n<p>{} sessions of the group <b>{}</b> (experts) \
         against {} of <b>{}</b> (novices). Each leaf's expert reference is the experts' median, \
         its novice reference the novices' median; where the medians do not differ the leaf's \
         way the references are kept.</p>\n<table>\n<tr><th>metric</th><th>better</th>\
         <th>n</th><th>experts median</th><th>IQR</th><th>n</th><th>novices median</th>\
         <th>IQR</th><th>U (experts)</th><th>p</th><th>effect</th><th>separates</th>\
         <th>references (expert, novice)</th><th>note</th></tr>\n",
        esc(&title),
        esc(&title),
        c.expert_sessions,
        esc(&c.expert_group),
        c.novice_sessions,
        esc(&c.novice_group),
    );
    for r in &c.rows {
        row(&mut out, r);
    }
    let separated = c.rows.iter().filter(|r| r.separates).count();
    let _ = write!(
        out,
        "</table>\n<p>{separated} of {} rows separate the groups. p: the two-sided Mann-Whitney \
         U test, exact where neither group has ties and each has at most 20 sessions (* the \
         normal approximation with the tie correction and a continuity correction). Effect: \
         the rank-biserial correlation, oriented so that +1 means every expert did better than \
         every novice. Separates: p &lt; 0.05 with the experts the better way.</p>\n\
         </body></html>\n",
        c.rows.len()
    );
    out
}
