//! The records' schema and its migrations. `PRAGMA user_version` holds the version a file is
//! at; each migration takes it one step on, all of them in one transaction, so a file is
//! never left between two versions. A file from a newer Vesalius is refused, not touched.

use super::RecordsError;
use rusqlite::Connection;

/// The version this build writes.
pub const SCHEMA_VERSION: i64 = 2;

/// Migration `k` takes a file from version `k` to `k + 1`.
pub(super) const MIGRATIONS: [&str; SCHEMA_VERSION as usize] = [
    // 0 -> 1: trainees, sessions, their nodes' values and their levels.
    "CREATE TABLE trainees (
         id INTEGER PRIMARY KEY,
         pseudonym TEXT NOT NULL UNIQUE,
         name TEXT NOT NULL DEFAULT '',
         group_name TEXT NOT NULL DEFAULT '',
         created_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))
     );
     CREATE TABLE sessions (
         id TEXT PRIMARY KEY,
         trainee_id INTEGER NOT NULL REFERENCES trainees (id) ON DELETE RESTRICT,
         procedure TEXT NOT NULL,
         completed INTEGER NOT NULL CHECK (completed IN (0, 1)),
         score REAL NOT NULL CHECK (score BETWEEN 0 AND 100),
         level TEXT NOT NULL
             CHECK (level IN ('novice', 'intermediate', 'proficient', 'expert')),
         simulated_s REAL NOT NULL,
         tree TEXT NOT NULL,
         tree_version INTEGER NOT NULL,
         tree_digest TEXT NOT NULL,
         scenario_digest TEXT NOT NULL,
         recording TEXT NOT NULL,
         recording_crc32 TEXT NOT NULL,
         report TEXT NOT NULL,
         stored_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now'))
     );
     CREATE INDEX sessions_by_trainee ON sessions (trainee_id, stored_at);
     CREATE TABLE metric_values (
         session_id TEXT NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
         path TEXT NOT NULL,
         metric TEXT,
         value REAL,
         score REAL,
         PRIMARY KEY (session_id, path)
     );
     CREATE TABLE levels (
         session_id TEXT NOT NULL REFERENCES sessions (id) ON DELETE CASCADE,
         scope TEXT NOT NULL,
         novice REAL NOT NULL,
         intermediate REAL NOT NULL,
         proficient REAL NOT NULL,
         expert REAL NOT NULL,
         PRIMARY KEY (session_id, scope)
     );",
    // 1 -> 2: questionnaire answers about the simulator, per participant and group.
    "CREATE TABLE questionnaire_answers (
         questionnaire TEXT NOT NULL,
         participant TEXT NOT NULL,
         group_name TEXT NOT NULL,
         item TEXT NOT NULL,
         score REAL NOT NULL,
         stored_at TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ', 'now')),
         PRIMARY KEY (questionnaire, participant, item)
     );",
];

/// Brings the file at `path` to [`SCHEMA_VERSION`].
pub fn migrate(conn: &mut Connection, path: &str) -> Result<(), RecordsError> {
    let sql = |source| RecordsError::Sqlite {
        path: path.to_string(),
        source,
    };
    let tx = conn
        .transaction_with_behavior(rusqlite::TransactionBehavior::Immediate)
        .map_err(sql)?;
    let at: i64 = tx
        .pragma_query_value(None, "user_version", |r| r.get(0))
        .map_err(sql)?;
    if at > SCHEMA_VERSION {
        return Err(RecordsError::Invalid {
            path: path.to_string(),
            message: format!(
                "the records are at schema version {at}, newer than this Vesalius reads \
                 ({SCHEMA_VERSION}); use a newer Vesalius"
            ),
        });
    }
    for (k, step) in MIGRATIONS.iter().enumerate().skip(at.max(0) as usize) {
        tx.execute_batch(step).map_err(sql)?;
        tx.pragma_update(None, "user_version", k as i64 + 1)
            .map_err(sql)?;
    }
    tx.commit().map_err(sql)
}
