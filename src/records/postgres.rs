//! The same records on a PostgreSQL server, for a training centre whose stations share them
//! (`--db postgres://user@host/dbname`). The schema is SQLite's in PostgreSQL's types, its
//! version in a `schema_version` table; stations that start at once migrate one after the
//! other (an advisory lock). A connection that fails is tried again with back-off
//! (0.2 s doubling, up to `$VESALIUS_RECORDS_RETRY_S`, default 10 s); a transaction that
//! meets another station's (two storing the same session, a deadlock) is run again.

use super::{Folder, NodeValue, RecordsError, SessionDetail, SessionRow, Trainee, check_pseudonym};
use crate::assess::questionnaire::Answers;
use postgres::{Client, NoTls, Row};
use std::time::{Duration, Instant};

/// The schema's version on a server.
pub const PG_SCHEMA_VERSION: i32 = 2;

/// The stamp a row gets when written: UTC with milliseconds, as SQLite's.
const NOW: &str = "to_char(now() AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS.MS\"Z\"')";

/// Migration `k` takes the server's schema from version `k` to `k + 1`.
fn migrations() -> [String; PG_SCHEMA_VERSION as usize] {
    [
        format!(
            "CREATE TABLE trainees (
                 id BIGSERIAL PRIMARY KEY,
                 pseudonym TEXT NOT NULL UNIQUE,
                 name TEXT NOT NULL DEFAULT '',
                 group_name TEXT NOT NULL DEFAULT '',
                 created_at TEXT NOT NULL DEFAULT {NOW});
             CREATE TABLE sessions (
                 id TEXT PRIMARY KEY,
                 trainee_id BIGINT NOT NULL REFERENCES trainees (id) ON DELETE RESTRICT,
                 procedure TEXT NOT NULL,
                 completed BOOLEAN NOT NULL,
                 score DOUBLE PRECISION NOT NULL CHECK (score BETWEEN 0 AND 100),
                 level TEXT NOT NULL
                     CHECK (level IN ('novice', 'intermediate', 'proficient', 'expert')),
                 simulated_s DOUBLE PRECISION NOT NULL,
                 tree TEXT NOT NULL,
                 tree_version BIGINT NOT NULL,
                 tree_digest TEXT NOT NULL,
                 scenario_digest TEXT NOT NULL,
                 recording TEXT NOT NULL,
                 recording_crc32 TEXT NOT NULL,
                 report TEXT NOT NULL,
                 stored_at TEXT NOT NULL DEFAULT {NOW});
             CREATE INDEX sessions_by_trainee ON sessions (trainee_id, stored_at);
             CREATE TABLE metric_values (
                 session_id TEXT NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
                 ord INTEGER NOT NULL,
                 path TEXT NOT NULL,
                 metric TEXT,
                 value DOUBLE PRECISION,
                 score DOUBLE PRECISION,
                 PRIMARY KEY (session_id, path));
             CREATE TABLE levels (
                 session_id TEXT NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
                 scope TEXT NOT NULL,
                 novice DOUBLE PRECISION NOT NULL,
                 intermediate DOUBLE PRECISION NOT NULL,
                 proficient DOUBLE PRECISION NOT NULL,
                 expert DOUBLE PRECISION NOT NULL,
                 PRIMARY KEY (session_id, scope));"
        ),
        format!(
            "CREATE TABLE questionnaire_answers (
                 questionnaire TEXT NOT NULL,
                 participant TEXT NOT NULL,
                 group_name TEXT NOT NULL,
                 item TEXT NOT NULL,
                 score DOUBLE PRECISION NOT NULL,
                 stored_at TEXT NOT NULL DEFAULT {NOW},
                 PRIMARY KEY (questionnaire, participant, item));"
        ),
    ]
}

/// The URL without a password, for messages.
pub fn redact(url: &str) -> String {
    match (url.find("://"), url.rfind('@')) {
        (Some(s), Some(at)) if at > s => {
            let user = &url[s + 3..at];
            let user = user.split(':').next().unwrap_or("");
            format!("{}{user}@{}", &url[..s + 3], &url[at + 1..])
        }
        _ => url.to_string(),
    }
}

/// Records on a PostgreSQL server.
pub struct PgRecords {
    client: Client,
    url: String,
    shown: String,
}

/// How long connecting may keep trying, s.
fn retry_budget() -> Duration {
    let s = std::env::var("VESALIUS_RECORDS_RETRY_S")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .unwrap_or(10.0);
    Duration::from_secs_f64(s)
}

/// Whether a failed transaction should simply be run again (another station's transaction
/// met this one: a duplicate key of a session stored at the same time, a serialisation
/// failure, a deadlock).
fn transient(e: &postgres::Error) -> bool {
    use postgres::error::SqlState;
    e.code().is_some_and(|c| {
        *c == SqlState::UNIQUE_VIOLATION
            || *c == SqlState::T_R_SERIALIZATION_FAILURE
            || *c == SqlState::T_R_DEADLOCK_DETECTED
    })
}

impl PgRecords {
    /// Connects (trying again with back-off) and migrates the schema.
    pub fn open(url: &str) -> Result<PgRecords, RecordsError> {
        let shown = redact(url);
        let client = connect(url, &shown)?;
        let mut r = PgRecords {
            client,
            url: url.to_string(),
            shown,
        };
        r.migrate()?;
        Ok(r)
    }

    fn err(&self) -> impl Fn(postgres::Error) -> RecordsError + '_ {
        |source| RecordsError::Postgres {
            path: self.shown.clone(),
            source,
        }
    }

    fn migrate(&mut self) -> Result<(), RecordsError> {
        let shown = self.shown.clone();
        let err = |source| RecordsError::Postgres {
            path: shown.clone(),
            source,
        };
        let mut tx = self.client.transaction().map_err(err)?;
        tx.execute("SELECT pg_advisory_xact_lock(1447)", &[])
            .map_err(err)?;
        tx.batch_execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)")
            .map_err(err)?;
        let at: i32 = match tx
            .query_opt("SELECT version FROM schema_version", &[])
            .map_err(err)?
        {
            Some(row) => row.try_get(0).map_err(err)?,
            None => {
                tx.execute("INSERT INTO schema_version (version) VALUES (0)", &[])
                    .map_err(err)?;
                0
            }
        };
        if at > PG_SCHEMA_VERSION {
            return Err(RecordsError::Invalid {
                path: shown.clone(),
                message: format!(
                    "the records are at schema version {at}, newer than this Vesalius reads \
                     ({PG_SCHEMA_VERSION}); use a newer Vesalius"
                ),
            });
        }
        for (k, step) in migrations().iter().enumerate().skip(at.max(0) as usize) {
            tx.batch_execute(step).map_err(err)?;
            tx.execute("UPDATE schema_version SET version = $1", &[&(k as i32 + 1)])
                .map_err(err)?;
        }
        tx.commit().map_err(err)
    }

    /// The schema version the server is at.
    pub fn version(&mut self) -> Result<i64, RecordsError> {
        let row = self
            .client
            .query_one("SELECT version FROM schema_version", &[])
            .map_err(self.err())?;
        let v: i32 = row.try_get(0).map_err(self.err())?;
        Ok(i64::from(v))
    }

    /// Runs `f` in a transaction, again on a lost connection (reconnecting) or a transient
    /// conflict with another station, until the retry budget is spent.
    fn with_retry<T>(
        &mut self,
        mut f: impl FnMut(&mut postgres::Transaction<'_>) -> Result<T, postgres::Error>,
    ) -> Result<T, RecordsError> {
        let start = Instant::now();
        let mut wait = Duration::from_millis(20);
        loop {
            let tried = match self.client.transaction() {
                Ok(mut tx) => f(&mut tx).and_then(|v| tx.commit().map(|()| v)),
                Err(e) => Err(e),
            };
            match tried {
                Ok(v) => return Ok(v),
                Err(e) if start.elapsed() < retry_budget() && (transient(&e) || e.is_closed()) => {
                    std::thread::sleep(wait);
                    wait = (wait * 2).min(Duration::from_secs(2));
                    if self.client.is_closed() {
                        self.client = connect(&self.url, &self.shown)?;
                    }
                }
                Err(source) => {
                    return Err(RecordsError::Postgres {
                        path: self.shown.clone(),
                        source,
                    });
                }
            }
        }
    }

    /// See [`super::Records::put_trainee`].
    pub fn put_trainee(
        &mut self,
        pseudonym: &str,
        name: &str,
        group: &str,
    ) -> Result<(), RecordsError> {
        check_pseudonym(&self.shown, pseudonym)?;
        self.with_retry(|tx| {
            tx.execute(
                "INSERT INTO trainees (pseudonym, name, group_name) VALUES ($1, $2, $3)
                 ON CONFLICT (pseudonym) DO UPDATE SET name = $2, group_name = $3",
                &[&pseudonym, &name, &group],
            )
            .map(|_| ())
        })
    }

    /// See [`super::Records::store_dir`]: the same, in one server transaction.
    pub fn store_dir(
        &mut self,
        dir: &std::path::Path,
        trainee: &str,
    ) -> Result<String, RecordsError> {
        check_pseudonym(&self.shown, trainee)?;
        let f = Folder::read(dir)?;
        let s = &f.stored;
        self.with_retry(|tx| {
            tx.execute(
                "INSERT INTO trainees (pseudonym) VALUES ($1) ON CONFLICT (pseudonym) DO NOTHING",
                &[&trainee],
            )?;
            let tid: i64 = tx
                .query_one("SELECT id FROM trainees WHERE pseudonym = $1", &[&trainee])?
                .try_get(0)?;
            tx.execute("DELETE FROM sessions WHERE id = $1", &[&s.id])?;
            tx.execute(
                "INSERT INTO sessions (id, trainee_id, procedure, completed, score, level,
                     simulated_s, tree, tree_version, tree_digest, scenario_digest, recording,
                     recording_crc32, report)
                 VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13, $14)",
                &[
                    &s.id,
                    &tid,
                    &s.procedure,
                    &s.completed,
                    &s.score,
                    &s.level,
                    &s.simulated_s,
                    &s.tree,
                    &s.tree_version,
                    &s.tree_digest,
                    &s.scenario_digest,
                    &f.recording,
                    &f.crc,
                    &f.text,
                ],
            )?;
            for (k, n) in s.nodes.iter().enumerate() {
                tx.execute(
                    "INSERT INTO metric_values (session_id, ord, path, metric, value, score)
                     VALUES ($1, $2, $3, $4, $5, $6)",
                    &[&s.id, &(k as i32), &n.path, &n.metric, &n.value, &n.score],
                )?;
            }
            for (scope, m) in &s.levels {
                tx.execute(
                    "INSERT INTO levels (session_id, scope, novice, intermediate, proficient,
                         expert) VALUES ($1, $2, $3, $4, $5, $6)",
                    &[&s.id, scope, &m[0], &m[1], &m[2], &m[3]],
                )?;
            }
            Ok(s.id.clone())
        })
    }

    /// See [`super::Records::sessions`].
    pub fn sessions(&mut self, trainee: Option<&str>) -> Result<Vec<SessionRow>, RecordsError> {
        let rows = self
            .client
            .query(
                "SELECT s.id, t.pseudonym, s.procedure, s.completed, s.score, s.level,
                        s.simulated_s, s.tree_version, s.stored_at
                 FROM sessions s JOIN trainees t ON t.id = s.trainee_id
                 WHERE $1::TEXT IS NULL OR t.pseudonym = $1
                 ORDER BY s.stored_at DESC, s.id DESC",
                &[&trainee],
            )
            .map_err(self.err())?;
        rows.iter().map(|r| row_of(r).map_err(self.err())).collect()
    }

    /// See [`super::Records::group_reports`].
    pub fn group_reports(
        &mut self,
        procedure: &str,
        group: &str,
    ) -> Result<Vec<super::GroupReport>, RecordsError> {
        let rows = self
            .client
            .query(
                "SELECT s.id, t.pseudonym, s.report
                 FROM sessions s JOIN trainees t ON t.id = s.trainee_id
                 WHERE s.procedure = $1 AND t.group_name = $2
                 ORDER BY s.id",
                &[&procedure, &group],
            )
            .map_err(self.err())?;
        let shown = self.shown().to_string();
        rows.iter()
            .map(|r| {
                let (id, trainee, text): (String, String, String) = (
                    r.try_get(0).map_err(self.err())?,
                    r.try_get(1).map_err(self.err())?,
                    r.try_get(2).map_err(self.err())?,
                );
                super::GroupReport::parse(&shown, id, trainee, &text)
            })
            .collect()
    }

    /// See [`super::Records::session`].
    pub fn session(&mut self, id: &str) -> Result<Option<SessionDetail>, RecordsError> {
        let Some(r) = self
            .client
            .query_opt(
                "SELECT s.id, t.pseudonym, s.procedure, s.completed, s.score, s.level,
                        s.simulated_s, s.tree_version, s.stored_at, s.recording,
                        s.recording_crc32, s.scenario_digest, s.tree_digest, s.report
                 FROM sessions s JOIN trainees t ON t.id = s.trainee_id WHERE s.id = $1",
                &[&id],
            )
            .map_err(self.err())?
        else {
            return Ok(None);
        };
        let nodes = self
            .client
            .query(
                "SELECT path, metric, value, score FROM metric_values WHERE session_id = $1
                 ORDER BY ord",
                &[&id],
            )
            .map_err(self.err())?
            .iter()
            .map(|n| {
                Ok(NodeValue {
                    path: n.try_get(0)?,
                    metric: n.try_get(1)?,
                    value: n.try_get(2)?,
                    score: n.try_get(3)?,
                })
            })
            .collect::<Result<Vec<_>, postgres::Error>>()
            .map_err(self.err())?;
        let detail = (|| -> Result<SessionDetail, postgres::Error> {
            let report: String = r.try_get(13)?;
            Ok(SessionDetail {
                row: row_of(&r)?,
                recording: r.try_get(9)?,
                recording_crc32: r.try_get(10)?,
                scenario_digest: r.try_get(11)?,
                tree_digest: r.try_get(12)?,
                nodes,
                report: serde_json::from_str(&report).unwrap_or_default(),
            })
        })()
        .map_err(self.err())?;
        Ok(Some(detail))
    }

    /// See [`super::Records::trainees`].
    pub fn trainees(&mut self) -> Result<Vec<Trainee>, RecordsError> {
        let rows = self
            .client
            .query(
                "SELECT t.pseudonym, t.name, t.group_name, COUNT(s.id)
                 FROM trainees t LEFT JOIN sessions s ON s.trainee_id = t.id
                 GROUP BY t.id ORDER BY t.pseudonym",
                &[],
            )
            .map_err(self.err())?;
        rows.iter()
            .map(|r| {
                Ok(Trainee {
                    pseudonym: r.try_get(0)?,
                    name: r.try_get(1)?,
                    group: r.try_get(2)?,
                    sessions: r.try_get::<_, i64>(3)?.max(0) as u64,
                })
            })
            .collect::<Result<Vec<_>, postgres::Error>>()
            .map_err(self.err())
    }

    /// See [`super::Records::level_distribution`].
    pub fn level_distribution(
        &mut self,
        procedure: Option<&str>,
    ) -> Result<[(&'static str, u64); 4], RecordsError> {
        let rows = self
            .client
            .query(
                "SELECT DISTINCT ON (s.trainee_id) s.level FROM sessions s
                 WHERE $1::TEXT IS NULL OR s.procedure = $1
                 ORDER BY s.trainee_id, s.stored_at DESC, s.id DESC",
                &[&procedure],
            )
            .map_err(self.err())?;
        let levels = rows
            .iter()
            .map(|r| r.try_get::<_, String>(0))
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.err())?;
        Ok(super::count_levels(&levels))
    }

    /// See [`super::Records::store_answers`].
    pub fn store_answers(
        &mut self,
        q: &crate::assess::questionnaire::Questionnaire,
        file: &str,
        answers: &[Answers],
    ) -> Result<(), RecordsError> {
        super::answers::check(q, file, answers)?;
        self.with_retry(|tx| {
            for a in answers {
                tx.execute(
                    "DELETE FROM questionnaire_answers WHERE questionnaire = $1 AND participant = $2",
                    &[&q.id, &a.participant],
                )?;
                for (item, score) in &a.scores {
                    tx.execute(
                        "INSERT INTO questionnaire_answers (questionnaire, participant,
                             group_name, item, score) VALUES ($1, $2, $3, $4, $5)",
                        &[&q.id, &a.participant, &a.group, item, score],
                    )?;
                }
            }
            Ok(())
        })
    }

    /// See [`super::Records::answers`].
    pub fn answers(&mut self, id: &str) -> Result<Vec<Answers>, RecordsError> {
        let rows = self
            .client
            .query(
                "SELECT participant, group_name, item, score FROM questionnaire_answers
                 WHERE questionnaire = $1 ORDER BY participant, item",
                &[&id],
            )
            .map_err(self.err())?;
        let rows = rows
            .iter()
            .map(|r| Ok((r.try_get(0)?, r.try_get(1)?, r.try_get(2)?, r.try_get(3)?)))
            .collect::<Result<Vec<_>, postgres::Error>>()
            .map_err(self.err())?;
        Ok(super::answers::grouped(rows))
    }

    /// Where the records are, for people (no password).
    pub fn shown(&self) -> &str {
        &self.shown
    }
}

fn connect(url: &str, shown: &str) -> Result<Client, RecordsError> {
    let start = Instant::now();
    let mut wait = Duration::from_millis(200);
    loop {
        match Client::connect(url, NoTls) {
            Ok(c) => return Ok(c),
            // The server not (yet) reachable: wait and try again. A URL that cannot be
            // parsed, or a server that refuses (authentication), is no reason to wait.
            Err(e) if io_error(&e) && start.elapsed() + wait <= retry_budget() => {
                std::thread::sleep(wait);
                wait = (wait * 2).min(Duration::from_secs(2));
            }
            Err(source) => {
                return Err(RecordsError::Postgres {
                    path: shown.to_string(),
                    source,
                });
            }
        }
    }
}

/// A failure to reach the server (refused, reset, timed out), as opposed to a refusal by it.
fn io_error(e: &postgres::Error) -> bool {
    std::error::Error::source(e).is_some_and(|s| s.is::<std::io::Error>())
}

fn row_of(r: &Row) -> Result<SessionRow, postgres::Error> {
    Ok(SessionRow {
        session_id: r.try_get(0)?,
        trainee: r.try_get(1)?,
        procedure: r.try_get(2)?,
        completed: r.try_get(3)?,
        score: r.try_get(4)?,
        level: r.try_get(5)?,
        simulated_s: r.try_get(6)?,
        tree_version: r.try_get(7)?,
        stored_at: r.try_get(8)?,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_password_never_reaches_a_message() {
        assert_eq!(
            super::redact("postgres://centre:s3cret@db.local:5432/records"),
            "postgres://centre@db.local:5432/records"
        );
        assert_eq!(
            super::redact("postgresql://db.local/records"),
            "postgresql://db.local/records"
        );
    }
}
