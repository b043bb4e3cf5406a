//! `vesalius records calibrate`: a tree's references from two groups' stored sessions, and
//! the validation table (text, JSON or an HTML page).

use super::CliError;
use std::path::Path;
use vesalius::assess::calibrate::{self, Calibration, Row};
use vesalius::assess::validation::num;
use vesalius::assess::{self, Tree};
use vesalius::records::Db;

/// The tree `spec` names (a file, else a procedure's built-in tree), its file name and text.
fn tree_of(spec: &str) -> Result<(Tree, String, String), CliError> {
    let path = Path::new(spec);
    if path.is_file() {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| CliError::Failed(format!("{file}: cannot read: {e}")))?;
        let tree = assess::load(&vesalius::registry::CATALOG, &file, &text)?;
        return Ok((tree, file, text));
    }
    let Some(info) = vesalius::registry::find(spec) else {
        return Err(CliError::Failed(format!(
            "--tree {spec}: neither a tree file nor a procedure ({})",
            vesalius::registry::CATALOG
                .names()
                .collect::<Vec<_>>()
                .join(", ")
        )));
    };
    let file = format!("assets/assessment/{}.toml", info.name);
    let tree = assess::load(&vesalius::registry::CATALOG, &file, info.assessment)?;
    Ok((tree, file, info.assessment.to_string()))
}

pub fn run(
    spec: &str,
    groups: (&str, &str),
    out: Option<&Path>,
    html: Option<&Path>,
    json: bool,
    db: &mut Db,
) -> Result<(), CliError> {
    let (tree, file, text) = tree_of(spec)?;
    let info = vesalius::registry::find(&tree.procedure).ok_or_else(|| {
        CliError::Failed(format!("{file}: '{}' is not a procedure", tree.procedure))
    })?;
    let measures = |group: &str, db: &mut Db| -> Result<Vec<_>, CliError> {
        Ok(db
            .group_reports(&tree.procedure, group)?
            .iter()
            .map(|s| calibrate::report_measures(&s.report, info.steps.len()))
            .collect())
    };
    let expert = measures(groups.0, db)?;
    let novice = measures(groups.1, db)?;
    let c = calibrate::calibrate(&tree, &file, &text, groups, &expert, &novice)?;
    if json {
        say!("{}", serde_json::to_string_pretty(&c).unwrap_or_default());
    } else {
        for line in table(&c) {
            say!("{line}");
        }
    }
    if let Some(out) = out {
        write(out, &c.tree_text)?;
        say!("calibrated tree written to {}", out.display());
    }
    if let Some(html) = html {
        write(html, &vesalius::assess::validation::page(&c))?;
        say!("validation table written to {}", html.display());
    }
    Ok(())
}

/// Writes `text` to `path` whole or not at all (a temporary file renamed over it).
fn write(path: &Path, text: &str) -> Result<(), CliError> {
    let tmp = path.with_extension("part");
    std::fs::write(&tmp, text)
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| CliError::Failed(format!("{}: cannot write: {e}", path.display())))
}

fn spread(s: Option<vesalius::assess::stats::Spread>) -> String {
    s.map_or("-".into(), |s| {
        format!("{} [{}-{}] {}", num(s.median), num(s.q1), num(s.q3), s.n)
    })
}

/// The validation table as text lines.
pub fn table(c: &Calibration) -> Vec<String> {
    let mut out = vec![
        format!(
            "{}: {} sessions of '{}' (experts) against {} of '{}' (novices)",
            c.procedure, c.expert_sessions, c.expert_group, c.novice_sessions, c.novice_group
        ),
        format!(
            "{:<34} {:<30} {:<30} {:>8} {:>6} {:<9} references (expert, novice)",
            "metric",
            "experts: median [IQR] n",
            "novices: median [IQR] n",
            "p",
            "effect",
            "separates"
        ),
    ];
    for r in &c.rows {
        out.push(line(r));
    }
    out.push(
        "p: two-sided Mann-Whitney U (exact without ties up to 20 a group); effect: rank-biserial \
         correlation, 1 = every expert better than every novice; separates: p < 0.05 the better way"
            .into(),
    );
    out
}

fn line(r: &Row) -> String {
    let p = r.test.map_or("-".into(), |t| format!("{:.4}", t.p));
    let effect = r.effect.map_or("-".into(), |e| format!("{e:+.2}"));
    let refs = match (r.was, r.now) {
        (Some(w), Some(n)) if w != n => format!(
            "{}, {} (was {}, {})",
            num(n.0),
            num(n.1),
            num(w.0),
            num(w.1)
        ),
        (_, Some(n)) => format!("{}, {}", num(n.0), num(n.1)),
        _ => String::new(),
    };
    let note = if r.note.is_empty() || r.path == "score" {
        String::new()
    } else {
        format!("  ({})", r.note)
    };
    format!(
        "{:<34} {:<30} {:<30} {:>8} {:>6} {:<9} {refs}{note}",
        r.metric,
        spread(r.expert),
        spread(r.novice),
        p,
        effect,
        if r.separates { "yes" } else { "no" }
    )
}
