//! `vesalius records`: the learning centre's records from the command line: list, show,
//! export (CSV or JSON), import session folders, add trainees, the distribution of levels,
//! and questionnaire answers with their statistics.

use super::CliError;
use clap::{Subcommand, ValueEnum};
use std::path::{Path, PathBuf};
use vesalius::assess::questionnaire::{Answers, Questionnaire};
use vesalius::records::{Db, default_path, spool};

#[derive(Debug, Subcommand)]
pub enum RecordsCommand {
    /// Stored sessions, newest first: id, trainee, procedure, score, level.
    List {
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
        /// Only this trainee's sessions.
        #[arg(long, value_name = "ID")]
        trainee: Option<String>,
        /// One JSON object a line.
        #[arg(long)]
        json: bool,
    },
    /// One stored session: its scores node by node, its recording and its report.
    Show {
        session: String,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
        /// The whole record as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Every stored session as CSV (one row a session) or JSON (one object a line).
    Export {
        #[arg(long, value_enum, default_value = "csv")]
        format: Format,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// Stores session folders (report.json + input.vtrace, as run --out writes them) for a
    /// trainee, each in one transaction; a session stored before is replaced.
    Import {
        #[arg(required = true, value_name = "DIR")]
        dirs: Vec<PathBuf>,
        #[arg(long, value_name = "ID")]
        trainee: String,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// Adds a trainee (or updates their name and group).
    Trainee {
        /// The pseudonymous id sessions are stored under.
        pseudonym: String,
        #[arg(long, default_value = "")]
        name: String,
        #[arg(long, default_value = "")]
        group: String,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// Stores participants' answers to a questionnaire (assets/questionnaires/*.toml): a
    /// JSON array of {"participant", "group", "scores": {item: score}}, all checked, then
    /// stored in one transaction.
    Answers {
        /// The questionnaire's file.
        form: PathBuf,
        /// The answers (JSON).
        answers: PathBuf,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// Statistics of a questionnaire's stored answers per group: per item n, mean, SD,
    /// median and IQR; per scale Cronbach's alpha.
    Stats {
        /// The questionnaire's file.
        form: PathBuf,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
        /// One JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Stores the sessions the spool lists (those a server could not take when they ended;
    /// $VESALIUS_SPOOL, else $XDG_DATA_HOME/vesalius/pending-records.txt); what still fails
    /// stays listed.
    Sync {
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// Sets a tree's expert and novice references from two groups' stored sessions (each
    /// leaf: the group's median) and prints the validation table: per metric both groups'
    /// medians and IQRs, the Mann-Whitney U test's p, the effect size, and whether it
    /// separates the groups.
    Calibrate {
        /// The tree: a file, or a procedure's name for its built-in tree.
        #[arg(long, value_name = "TREE")]
        tree: String,
        /// The expert group (trainees' `--group`).
        #[arg(long, value_name = "GROUP")]
        expert: String,
        /// The novice group.
        #[arg(long, value_name = "GROUP")]
        novice: String,
        /// Writes the calibrated tree here (its version one up, comments kept).
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// Writes the validation table as an HTML page.
        #[arg(long, value_name = "FILE")]
        html: Option<PathBuf>,
        /// The table as one JSON object.
        #[arg(long)]
        json: bool,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
    /// How many trainees are at each level by their latest session (of one procedure, or of
    /// any), and the trainees with their session counts.
    Levels {
        /// One procedure's sessions only.
        #[arg(long)]
        procedure: Option<String>,
        #[arg(long, value_name = "FILE")]
        db: Option<PathBuf>,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    Csv,
    Json,
}

fn open(db: Option<PathBuf>) -> Result<Db, CliError> {
    Ok(Db::open(&db.unwrap_or_else(default_path))?)
}

/// Stores one session folder (after `run --records` or in `demo`). When a server cannot be
/// reached (its retries spent), the folder is listed in the spool for `records sync` and the
/// command goes on: the session is whole in its folder.
pub fn store(db: &Path, dir: &Path, trainee: &str) -> Result<(), CliError> {
    let stored = Db::open(db).and_then(|mut r| {
        let id = r.store_dir(dir, trainee)?;
        Ok((id, r.shown()))
    });
    match stored {
        Ok((id, shown)) => {
            say!("stored session {id} for {trainee} in {shown}");
            Ok(())
        }
        Err(e @ vesalius::records::RecordsError::Postgres { .. }) => {
            let list = spool::path();
            spool::add(&list, dir, trainee)?;
            tell!(
                "{e}\nthe session is kept in {} and listed in {}: `vesalius records sync --db URL` stores it",
                dir.display(),
                list.display()
            );
            Ok(())
        }
        Err(e) => Err(e.into()),
    }
}

/// A CSV field, quoted when it needs to be.
fn csv(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

pub fn run(c: RecordsCommand) -> Result<(), CliError> {
    match c {
        RecordsCommand::List { db, trainee, json } => {
            let mut r = open(db)?;
            let rows = r.sessions(trainee.as_deref())?;
            if !json {
                say!(
                    "{:<16}  {:<12}  {:<16}  {:>5}  {:<12}  {:<9}  stored",
                    "session",
                    "trainee",
                    "procedure",
                    "score",
                    "level",
                    "completed"
                );
            }
            for s in &rows {
                if json {
                    say!("{}", serde_json::to_string(s).unwrap_or_default());
                } else {
                    say!(
                        "{:<16}  {:<12}  {:<16}  {:>5.1}  {:<12}  {:<9}  {}",
                        s.session_id,
                        s.trainee,
                        s.procedure,
                        s.score,
                        s.level,
                        if s.completed { "yes" } else { "no" },
                        s.stored_at
                    );
                }
            }
            Ok(())
        }
        RecordsCommand::Show { session, db, json } => {
            let mut r = open(db)?;
            let Some(d) = r.session(&session)? else {
                return Err(CliError::Failed(format!(
                    "session {session}: not in the records"
                )));
            };
            if json {
                say!("{}", serde_json::to_string_pretty(&d).unwrap_or_default());
                return Ok(());
            }
            let s = &d.row;
            say!("session    {}", s.session_id);
            say!("trainee    {}", s.trainee);
            say!(
                "procedure  {} (tree version {})",
                s.procedure,
                s.tree_version
            );
            say!("score      {:.1} / 100, {}", s.score, s.level);
            say!("completed  {}", if s.completed { "yes" } else { "no" });
            say!("recording  {} (CRC-32 {})", d.recording, d.recording_crc32);
            for n in &d.nodes {
                let depth = n.path.matches('/').count();
                let value = n.value.map_or(String::new(), |v| format!("  = {v}"));
                let score = n
                    .score
                    .map_or("left out".to_string(), |v| format!("{v:.1}"));
                say!(
                    "  {}{:<40} {:>8}{}",
                    "  ".repeat(depth),
                    n.path.rsplit('/').next().unwrap_or_default(),
                    score,
                    value
                );
            }
            Ok(())
        }
        RecordsCommand::Export { format, db } => {
            let mut r = open(db)?;
            let rows = r.sessions(None)?;
            if format == Format::Csv {
                say!(
                    "session_id,trainee,procedure,completed,score,level,simulated_s,tree_version,stored_at"
                );
            }
            for s in &rows {
                match format {
                    Format::Json => {
                        let d = r.session(&s.session_id)?;
                        say!("{}", serde_json::to_string(&d).unwrap_or_default());
                    }
                    Format::Csv => say!(
                        "{},{},{},{},{},{},{},{},{}",
                        csv(&s.session_id),
                        csv(&s.trainee),
                        csv(&s.procedure),
                        u8::from(s.completed),
                        s.score,
                        csv(&s.level),
                        s.simulated_s,
                        s.tree_version,
                        csv(&s.stored_at)
                    ),
                }
            }
            Ok(())
        }
        RecordsCommand::Import { dirs, trainee, db } => {
            let path = db.unwrap_or_else(default_path);
            let mut r = Db::open(&path)?;
            for d in &dirs {
                let id = r.store_dir(d, &trainee)?;
                say!("stored session {id} ({}) for {trainee}", d.display());
            }
            Ok(())
        }
        RecordsCommand::Trainee {
            pseudonym,
            name,
            group,
            db,
        } => {
            let mut r = open(db)?;
            r.put_trainee(&pseudonym, &name, &group)?;
            say!("trainee {pseudonym} stored");
            Ok(())
        }
        RecordsCommand::Answers { form, answers, db } => {
            let q = Questionnaire::load_file(&form)?;
            let file = answers.display().to_string();
            let text = std::fs::read_to_string(&answers)
                .map_err(|e| CliError::Failed(format!("{file}: cannot read: {e}")))?;
            let list: Vec<Answers> = serde_json::from_str(&text).map_err(|e| {
                CliError::Failed(format!(
                    "{file}: expected a JSON array of {{\"participant\", \"group\", \"scores\"}}: {e}"
                ))
            })?;
            let mut r = open(db)?;
            r.store_answers(&q, &file, &list)?;
            say!(
                "stored the answers of {} participants to {}",
                list.len(),
                q.id
            );
            Ok(())
        }
        RecordsCommand::Stats { form, db, json } => {
            let q = Questionnaire::load_file(&form)?;
            let report = open(db)?.questionnaire_report(&q)?;
            if json {
                say!(
                    "{}",
                    serde_json::to_string_pretty(&report).unwrap_or_default()
                );
                return Ok(());
            }
            let num = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.2}"));
            say!("{} ({} to {})", q.title, q.rating.min, q.rating.max);
            for g in &report.groups {
                say!("group {} (n = {})", g.group, g.n);
                say!(
                    "  {:<44} {:>3} {:>6} {:>6} {:>6} {:>6}",
                    "item",
                    "n",
                    "mean",
                    "sd",
                    "median",
                    "iqr"
                );
                for i in &g.items {
                    let text = q
                        .items
                        .iter()
                        .find(|x| x.id == i.item)
                        .map_or(i.item.as_str(), |x| x.text.as_str());
                    let s = &i.summary;
                    say!(
                        "  {:<44} {:>3} {:>6.2} {:>6} {:>6.2} {:>6.2}",
                        text.chars().take(44).collect::<String>(),
                        s.n,
                        s.mean,
                        num(s.sd),
                        s.median,
                        s.iqr
                    );
                }
                for sc in &g.scales {
                    say!(
                        "  scale {}: {} items, Cronbach's alpha {}",
                        sc.scale,
                        sc.k,
                        num(sc.alpha)
                    );
                }
            }
            Ok(())
        }
        RecordsCommand::Sync { db } => {
            let mut r = open(db)?;
            let list = spool::path();
            let (stored, failed) = spool::sync(&list, &mut r)?;
            for id in &stored {
                say!("stored session {id} in {}", r.shown());
            }
            for (dir, why) in &failed {
                tell!("{}: still not stored: {why}", dir.display());
            }
            say!(
                "{} stored, {} still listed in {}",
                stored.len(),
                failed.len(),
                list.display()
            );
            if failed.is_empty() {
                Ok(())
            } else {
                Err(CliError::Failed(format!(
                    "{} sessions could not be stored",
                    failed.len()
                )))
            }
        }
        RecordsCommand::Calibrate {
            tree,
            expert,
            novice,
            out,
            html,
            json,
            db,
        } => super::calibrate::run(
            &tree,
            (&expert, &novice),
            out.as_deref(),
            html.as_deref(),
            json,
            &mut open(db)?,
        ),
        RecordsCommand::Levels { procedure, db } => {
            let mut r = open(db)?;
            let dist = r.level_distribution(procedure.as_deref())?;
            let total: u64 = dist.iter().map(|(_, n)| n).sum();
            for (level, n) in dist {
                let bar = "#".repeat(usize::try_from(n).unwrap_or(0).min(60));
                say!("{level:<12} {n:>4}  {bar}");
            }
            say!("trainees with a session: {total}");
            for t in r.trainees()? {
                say!(
                    "  {:<16} {:<24} {:<16} {} sessions",
                    t.pseudonym,
                    t.name,
                    t.group,
                    t.sessions
                );
            }
            Ok(())
        }
    }
}

/// `report SESSION --html FILE`: the page for an output folder, or for a session in the
/// records (its files found beside its recording).
pub fn report(session: &str, html: &Path, db: Option<PathBuf>) -> Result<(), CliError> {
    let given = Path::new(session);
    let (report, dir) = if given.join(vesalius::session::REPORT).is_file() {
        let file = given.join(vesalius::session::REPORT);
        let text = std::fs::read_to_string(&file)
            .map_err(|e| CliError::Failed(format!("{}: cannot read: {e}", file.display())))?;
        let report: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            CliError::Failed(format!("{}: not a session report: {e}", file.display()))
        })?;
        (report, Some(given.to_path_buf()))
    } else {
        let mut r = open(db)?;
        let Some(d) = r.session(session)? else {
            return Err(CliError::Failed(format!(
                "{session}: neither an output folder (with report.json) nor a session in the records"
            )));
        };
        let dir = Path::new(&d.recording).parent().map(Path::to_path_buf);
        (d.report, dir)
    };
    let mut events = Vec::new();
    let mut frames = Vec::new();
    if let Some(dir) = &dir {
        if let Ok(text) = std::fs::read_to_string(dir.join(vesalius::session::EVENTS)) {
            events = text
                .lines()
                .filter_map(|l| serde_json::from_str(l).ok())
                .collect();
        }
        // The procedure's own pictures where it has them (a fluoroscope's: what the trainee
        // worked by), else the left eyes.
        let pictures = |prefix: &str| -> Vec<PathBuf> {
            let mut found: Vec<PathBuf> = std::fs::read_dir(dir.join("frames"))
                .map(|d| {
                    d.filter_map(|e| e.ok().map(|e| e.path()))
                        .filter(|p| {
                            p.file_name()
                                .and_then(|n| n.to_str())
                                .is_some_and(|n| n.starts_with(prefix) && n.ends_with(".png"))
                        })
                        .collect()
                })
                .unwrap_or_default();
            found.sort();
            found
        };
        let mut lefts = pictures("fluoro_");
        if lefts.is_empty() {
            lefts = pictures("left_");
        }
        let step = lefts.len().div_ceil(KEY_FRAMES).max(1);
        frames = lefts
            .iter()
            .step_by(step)
            .filter_map(|p| std::fs::read(p).ok())
            .collect();
    }
    let page = vesalius::assess::html::page(&report, &events, &frames);
    let tmp = html.with_extension("html.partial");
    std::fs::write(&tmp, page)
        .and_then(|()| std::fs::rename(&tmp, html))
        .map_err(|e| CliError::Failed(format!("{}: cannot write: {e}", html.display())))?;
    say!(
        "wrote {} ({} events marked, {} key frames)",
        html.display(),
        events.len(),
        frames.len()
    );
    Ok(())
}

/// Key frames a page shows at most.
const KEY_FRAMES: usize = 4;
