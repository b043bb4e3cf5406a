//! The learning centre's records: trainees and their scored sessions in an SQLite file
//! (rusqlite, SQLite bundled). The file is created owner-only (0600), runs in WAL mode with
//! foreign keys on, and carries its schema version in `PRAGMA user_version`: an older file is
//! migrated forward in one transaction, a newer one refused. A session is stored from its
//! output folder (`report.json` and `input.vtrace`) in one transaction, so a kill at any
//! moment leaves the database valid and the session either absent or whole; its folder stays
//! where it was, so it can be stored again later (`vesalius records import DIR`).

mod answers;
mod db;
pub mod postgres;
mod schema;
pub mod spool;
#[cfg(test)]
mod tests;

use rusqlite::{Connection, OptionalExtension, params};
use serde::Serialize;
use std::path::{Path, PathBuf};

pub use db::Db;
pub use schema::SCHEMA_VERSION;

/// Where records go when no `--db` is given: `$VESALIUS_RECORDS`, else the demo's file.
pub fn default_path() -> PathBuf {
    std::env::var_os("VESALIUS_RECORDS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("vesalius-demo/records.sqlite"))
}

#[derive(Debug, thiserror::Error)]
pub enum RecordsError {
    #[error("{path}: {source}")]
    Sqlite {
        path: String,
        source: rusqlite::Error,
    },
    #[error("{path}: {source}")]
    Postgres {
        path: String,
        source: ::postgres::Error,
    },
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

/// An open records file.
pub struct Records {
    conn: Connection,
    path: String,
}

/// A trainee as the learning centre lists them: a pseudonymous id and what an educator
/// entered.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Trainee {
    pub pseudonym: String,
    pub name: String,
    pub group: String,
    pub sessions: u64,
}

/// One stored session, as lists show it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SessionRow {
    pub session_id: String,
    pub trainee: String,
    pub procedure: String,
    pub completed: bool,
    pub score: f64,
    pub level: String,
    pub simulated_s: f64,
    pub tree_version: i64,
    pub stored_at: String,
}

/// A stored session in full: its row, its recording, its nodes' values and its report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SessionDetail {
    #[serde(flatten)]
    pub row: SessionRow,
    pub recording: String,
    pub recording_crc32: String,
    pub scenario_digest: String,
    pub tree_digest: String,
    /// Each node's path, measure, value and score.
    pub nodes: Vec<NodeValue>,
    /// The whole report as it was written.
    pub report: serde_json::Value,
}

/// A stored session's report, as calibrating reads it.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupReport {
    pub session_id: String,
    pub trainee: String,
    pub report: serde_json::Value,
}

impl GroupReport {
    /// A stored report's text, checked to be a JSON object (`path`: the records, in errors).
    pub fn parse(
        path: &str,
        session_id: String,
        trainee: String,
        text: &str,
    ) -> Result<GroupReport, RecordsError> {
        match serde_json::from_str::<serde_json::Value>(text) {
            Ok(report) if report.is_object() => Ok(GroupReport {
                session_id,
                trainee,
                report,
            }),
            _ => Err(RecordsError::Invalid {
                path: path.to_string(),
                message: format!("session {session_id}: its stored report is not a JSON object"),
            }),
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NodeValue {
    pub path: String,
    pub metric: Option<String>,
    pub value: Option<f64>,
    pub score: Option<f64>,
}

impl Records {
    /// Opens (creating owner-only, then migrating) the records file at `path`.
    pub fn open(path: &Path) -> Result<Records, RecordsError> {
        let shown = path.display().to_string();
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|source| RecordsError::Io {
                path: dir.display().to_string(),
                source,
            })?;
        }
        create_owner_only(path).map_err(|source| RecordsError::Io {
            path: shown.clone(),
            source,
        })?;
        let sql = |source| RecordsError::Sqlite {
            path: shown.clone(),
            source,
        };
        let mut conn = Connection::open(path).map_err(sql)?;
        conn.busy_timeout(std::time::Duration::from_secs(10))
            .map_err(sql)?;
        conn.pragma_update(None, "foreign_keys", "ON")
            .map_err(sql)?;
        let mode: String = conn
            .query_row("PRAGMA journal_mode=WAL", [], |r| r.get(0))
            .map_err(sql)?;
        if !mode.eq_ignore_ascii_case("wal") {
            return Err(RecordsError::Invalid {
                path: shown,
                message: format!("cannot switch to WAL (journal mode stays {mode})"),
            });
        }
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(sql)?;
        schema::migrate(&mut conn, &shown)?;
        Ok(Records { conn, path: shown })
    }

    fn sql(&self) -> impl Fn(rusqlite::Error) -> RecordsError + '_ {
        |source| RecordsError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }

    /// The schema version the file is at.
    pub fn version(&self) -> Result<i64, RecordsError> {
        self.conn
            .pragma_query_value(None, "user_version", |r| r.get(0))
            .map_err(self.sql())
    }

    /// Adds a trainee, or updates the name and group of one already there.
    pub fn put_trainee(
        &mut self,
        pseudonym: &str,
        name: &str,
        group: &str,
    ) -> Result<(), RecordsError> {
        check_pseudonym(&self.path, pseudonym)?;
        self.conn
            .execute(
                "INSERT INTO trainees (pseudonym, name, group_name) VALUES (?1, ?2, ?3)
                 ON CONFLICT (pseudonym) DO UPDATE SET name = ?2, group_name = ?3",
                params![pseudonym, name, group],
            )
            .map_err(self.sql())?;
        Ok(())
    }

    /// Stores the session in output folder `dir` (its `report.json` and `input.vtrace`) for
    /// `trainee` (created when new), all in one transaction. A session stored before (the same
    /// id: a replay, a re-scoring) is replaced. Returns the session's id.
    pub fn store_dir(&mut self, dir: &Path, trainee: &str) -> Result<String, RecordsError> {
        check_pseudonym(&self.path, trainee)?;
        let Folder {
            text,
            stored: s,
            recording,
            crc,
        } = Folder::read(dir)?;
        let path = self.path.clone();
        let sql = |source| RecordsError::Sqlite {
            path: path.clone(),
            source,
        };
        let tx = self.conn.transaction().map_err(sql)?;
        tx.execute(
            "INSERT INTO trainees (pseudonym) VALUES (?1) ON CONFLICT (pseudonym) DO NOTHING",
            params![trainee],
        )
        .map_err(sql)?;
        let trainee_id: i64 = tx
            .query_row(
                "SELECT id FROM trainees WHERE pseudonym = ?1",
                params![trainee],
                |r| r.get(0),
            )
            .map_err(sql)?;
        tx.execute("DELETE FROM sessions WHERE id = ?1", params![s.id])
            .map_err(sql)?;
        tx.execute(
            "INSERT INTO sessions (id, trainee_id, procedure, completed, score, level,
                 simulated_s, tree, tree_version, tree_digest, scenario_digest, recording,
                 recording_crc32, report)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)",
            params![
                s.id,
                trainee_id,
                s.procedure,
                s.completed,
                s.score,
                s.level,
                s.simulated_s,
                s.tree,
                s.tree_version,
                s.tree_digest,
                s.scenario_digest,
                recording,
                crc,
                text
            ],
        )
        .map_err(sql)?;
        for n in &s.nodes {
            tx.execute(
                "INSERT INTO metric_values (session_id, path, metric, value, score)
                 VALUES (?1, ?2, ?3, ?4, ?5)",
                params![s.id, n.path, n.metric, n.value, n.score],
            )
            .map_err(sql)?;
        }
        for (scope, m) in &s.levels {
            tx.execute(
                "INSERT INTO levels (session_id, scope, novice, intermediate, proficient, expert)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                params![s.id, scope, m[0], m[1], m[2], m[3]],
            )
            .map_err(sql)?;
        }
        tx.commit().map_err(sql)?;
        Ok(s.id)
    }

    /// Stored sessions, newest first (one trainee's, or all).
    pub fn sessions(&self, trainee: Option<&str>) -> Result<Vec<SessionRow>, RecordsError> {
        let mut st = self
            .conn
            .prepare(
                "SELECT s.id, t.pseudonym, s.procedure, s.completed, s.score, s.level,
                        s.simulated_s, s.tree_version, s.stored_at
                 FROM sessions s JOIN trainees t ON t.id = s.trainee_id
                 WHERE ?1 IS NULL OR t.pseudonym = ?1
                 ORDER BY s.stored_at DESC, s.rowid DESC",
            )
            .map_err(self.sql())?;
        let rows = st
            .query_map(params![trainee], row_of)
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        Ok(rows)
    }

    /// One stored session in full, if stored.
    pub fn session(&self, id: &str) -> Result<Option<SessionDetail>, RecordsError> {
        let found = self
            .conn
            .query_row(
                "SELECT s.id, t.pseudonym, s.procedure, s.completed, s.score, s.level,
                        s.simulated_s, s.tree_version, s.stored_at, s.recording,
                        s.recording_crc32, s.scenario_digest, s.tree_digest, s.report
                 FROM sessions s JOIN trainees t ON t.id = s.trainee_id WHERE s.id = ?1",
                params![id],
                |r| {
                    Ok((
                        row_of(r)?,
                        r.get::<_, String>(9)?,
                        r.get::<_, String>(10)?,
                        r.get::<_, String>(11)?,
                        r.get::<_, String>(12)?,
                        r.get::<_, String>(13)?,
                    ))
                },
            )
            .optional()
            .map_err(self.sql())?;
        let Some((row, recording, recording_crc32, scenario_digest, tree_digest, report)) = found
        else {
            return Ok(None);
        };
        let mut st = self
            .conn
            .prepare(
                "SELECT path, metric, value, score FROM metric_values
                 WHERE session_id = ?1 ORDER BY rowid",
            )
            .map_err(self.sql())?;
        let nodes = st
            .query_map(params![id], |r| {
                Ok(NodeValue {
                    path: r.get(0)?,
                    metric: r.get(1)?,
                    value: r.get(2)?,
                    score: r.get(3)?,
                })
            })
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        Ok(Some(SessionDetail {
            row,
            recording,
            recording_crc32,
            scenario_digest,
            tree_digest,
            nodes,
            report: serde_json::from_str(&report).unwrap_or_default(),
        }))
    }

    /// The stored reports of one procedure's sessions by the trainees of one group: (session
    /// id, trainee, report), by session id.
    pub fn group_reports(
        &self,
        procedure: &str,
        group: &str,
    ) -> Result<Vec<GroupReport>, RecordsError> {
        let mut st = self
            .conn
            .prepare(
                "SELECT s.id, t.pseudonym, s.report
                 FROM sessions s JOIN trainees t ON t.id = s.trainee_id
                 WHERE s.procedure = ?1 AND t.group_name = ?2
                 ORDER BY s.id",
            )
            .map_err(self.sql())?;
        let rows = st
            .query_map(params![procedure, group], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, String>(2)?,
                ))
            })
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        rows.into_iter()
            .map(|(id, trainee, text)| GroupReport::parse(&self.path, id, trainee, &text))
            .collect()
    }

    /// Trainees with their session counts, by pseudonym.
    pub fn trainees(&self) -> Result<Vec<Trainee>, RecordsError> {
        let mut st = self
            .conn
            .prepare(
                "SELECT t.pseudonym, t.name, t.group_name, COUNT(s.id)
                 FROM trainees t LEFT JOIN sessions s ON s.trainee_id = t.id
                 GROUP BY t.id ORDER BY t.pseudonym",
            )
            .map_err(self.sql())?;
        let rows = st
            .query_map([], |r| {
                Ok(Trainee {
                    pseudonym: r.get(0)?,
                    name: r.get(1)?,
                    group: r.get(2)?,
                    sessions: r.get::<_, i64>(3)?.max(0) as u64,
                })
            })
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        Ok(rows)
    }

    /// How many trainees are at each level by their latest session of `procedure` (all
    /// procedures: their latest session of any), in the levels' order (the paper's Fig. 14b).
    pub fn level_distribution(
        &self,
        procedure: Option<&str>,
    ) -> Result<[(&'static str, u64); 4], RecordsError> {
        let mut st = self
            .conn
            .prepare(
                "SELECT s.level FROM sessions s
                 WHERE (?1 IS NULL OR s.procedure = ?1) AND s.rowid = (
                     SELECT s2.rowid FROM sessions s2
                     WHERE s2.trainee_id = s.trainee_id AND (?1 IS NULL OR s2.procedure = ?1)
                     ORDER BY s2.stored_at DESC, s2.rowid DESC LIMIT 1)",
            )
            .map_err(self.sql())?;
        let levels = st
            .query_map(params![procedure], |r| r.get::<_, String>(0))
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        Ok(count_levels(&levels))
    }

    /// `PRAGMA integrity_check`'s answer ("ok" when the file is sound).
    pub fn integrity(&self) -> Result<String, RecordsError> {
        self.conn
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .map_err(self.sql())
    }
}

fn row_of(r: &rusqlite::Row<'_>) -> rusqlite::Result<SessionRow> {
    Ok(SessionRow {
        session_id: r.get(0)?,
        trainee: r.get(1)?,
        procedure: r.get(2)?,
        completed: r.get(3)?,
        score: r.get(4)?,
        level: r.get(5)?,
        simulated_s: r.get(6)?,
        tree_version: r.get(7)?,
        stored_at: r.get(8)?,
    })
}

/// A trainee's pseudonym: 1-64 letters, digits, `-`, `_` or `.` (no names in ids).
fn check_pseudonym(path: &str, p: &str) -> Result<(), RecordsError> {
    let fine = !p.is_empty()
        && p.len() <= 64
        && p.chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
    if fine {
        Ok(())
    } else {
        Err(RecordsError::Invalid {
            path: path.to_string(),
            message: format!("trainee '{p}': a pseudonym is 1-64 letters, digits, '-', '_' or '.'"),
        })
    }
}

/// Creates `path` empty with owner-only permissions when it does not exist (an existing file
/// keeps its own).
fn create_owner_only(path: &Path) -> std::io::Result<()> {
    use std::os::unix::fs::OpenOptionsExt;
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
    {
        Ok(_) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Ok(()),
        Err(e) => Err(e),
    }
}

/// What a report gives the records.
struct Stored {
    id: String,
    procedure: String,
    completed: bool,
    score: f64,
    level: String,
    simulated_s: f64,
    tree: String,
    tree_version: i64,
    tree_digest: String,
    scenario_digest: String,
    nodes: Vec<NodeValue>,
    /// ("" for the whole, else a grade's path) and the four memberships.
    levels: Vec<(String, [f64; 4])>,
}

impl Stored {
    fn from_report(path: &str, r: &serde_json::Value) -> Result<Stored, RecordsError> {
        let bad = |what: &str| RecordsError::Invalid {
            path: path.to_string(),
            message: format!("{what}: missing or of the wrong type (is this a session report?)"),
        };
        let text = |k: &str| r[k].as_str().map(str::to_string).ok_or_else(|| bad(k));
        let id = text("session_id")?;
        let procedure = text("procedure")?;
        let a = &r["assessment"];
        let memberships = |m: &serde_json::Value| -> Option<[f64; 4]> {
            let l = crate::assess::fuzzy::LEVELS;
            Some([
                m[l[0]].as_f64()?,
                m[l[1]].as_f64()?,
                m[l[2]].as_f64()?,
                m[l[3]].as_f64()?,
            ])
        };
        let mut levels = vec![(
            String::new(),
            memberships(&a["memberships"]).ok_or_else(|| bad("assessment.memberships"))?,
        )];
        for g in a["grades"].as_array().into_iter().flatten() {
            if let (Some(p), Some(m)) = (g["path"].as_str(), memberships(&g["memberships"])) {
                levels.push((p.to_string(), m));
            }
        }
        let nodes = a["nodes"]
            .as_array()
            .ok_or_else(|| bad("assessment.nodes"))?
            .iter()
            .map(|n| NodeValue {
                path: n["path"].as_str().unwrap_or_default().to_string(),
                metric: n["metric"].as_str().map(str::to_string),
                value: n["value"].as_f64(),
                score: n["score"].as_f64(),
            })
            .collect();
        Ok(Stored {
            id,
            procedure,
            completed: r["completed"].as_bool().ok_or_else(|| bad("completed"))?,
            score: a["score"].as_f64().ok_or_else(|| bad("assessment.score"))?,
            level: a["level"]
                .as_str()
                .ok_or_else(|| bad("assessment.level"))?
                .to_string(),
            simulated_s: r["simulated_s"]
                .as_f64()
                .ok_or_else(|| bad("simulated_s"))?,
            tree: a["tree"]
                .as_str()
                .ok_or_else(|| bad("assessment.tree"))?
                .to_string(),
            tree_version: a["tree_version"]
                .as_i64()
                .ok_or_else(|| bad("assessment.tree_version"))?,
            tree_digest: a["tree_digest"].as_str().unwrap_or_default().to_string(),
            scenario_digest: r["scenario_digest"]
                .as_str()
                .unwrap_or_default()
                .to_string(),
            nodes,
            levels,
        })
    }
}

/// A session's output folder as the records take it: the report's text, what it gives, the
/// recording's path and CRC-32.
pub(crate) struct Folder {
    text: String,
    stored: Stored,
    recording: String,
    crc: String,
}

impl Folder {
    fn read(dir: &Path) -> Result<Folder, RecordsError> {
        let report_path = dir.join(crate::session::REPORT);
        let shown = report_path.display().to_string();
        let text = std::fs::read_to_string(&report_path).map_err(|source| RecordsError::Io {
            path: shown.clone(),
            source,
        })?;
        let report: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| RecordsError::Invalid {
                path: shown.clone(),
                message: format!("not a session report: {e}"),
            })?;
        let stored = Stored::from_report(&shown, &report)?;
        let recording = dir.join(crate::session::RECORDING);
        let crc = match std::fs::read(&recording) {
            Ok(bytes) => format!("{:08x}", crc32fast::hash(&bytes)),
            Err(source) => {
                return Err(RecordsError::Io {
                    path: recording.display().to_string(),
                    source,
                });
            }
        };
        let recording = recording
            .canonicalize()
            .unwrap_or(recording)
            .display()
            .to_string();
        Ok(Folder {
            text,
            stored,
            recording,
            crc,
        })
    }
}

/// How many of `levels` are each level of expertise, novice first.
fn count_levels(levels: &[String]) -> [(&'static str, u64); 4] {
    crate::assess::fuzzy::LEVELS.map(|l| (l, levels.iter().filter(|x| *x == l).count() as u64))
}
