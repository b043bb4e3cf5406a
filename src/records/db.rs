//! The records wherever they are: an SQLite file (a path) or a PostgreSQL server (a
//! `postgres://` or `postgresql://` URL), behind one set of calls.

use super::postgres::PgRecords;
use super::{Records, RecordsError, SessionDetail, SessionRow, Trainee};
use crate::assess::questionnaire::{Answers, Questionnaire, Report};
use std::path::Path;

/// Open records.
pub enum Db {
    Sqlite(Records),
    Postgres(PgRecords),
}

/// Whether `spec` names a PostgreSQL server.
pub fn is_url(spec: &str) -> bool {
    spec.starts_with("postgres://") || spec.starts_with("postgresql://")
}

impl Db {
    /// Opens the records `spec` names: a server URL, else an SQLite file's path.
    pub fn open(spec: &Path) -> Result<Db, RecordsError> {
        match spec.to_str().filter(|s| is_url(s)) {
            Some(url) => Ok(Db::Postgres(PgRecords::open(url)?)),
            None => Ok(Db::Sqlite(Records::open(spec)?)),
        }
    }

    /// Where the records are, for people (a server's URL without its password).
    pub fn shown(&self) -> String {
        match self {
            Db::Sqlite(r) => r.path.clone(),
            Db::Postgres(p) => p.shown().to_string(),
        }
    }

    pub fn version(&mut self) -> Result<i64, RecordsError> {
        match self {
            Db::Sqlite(r) => r.version(),
            Db::Postgres(p) => p.version(),
        }
    }

    pub fn put_trainee(
        &mut self,
        pseudonym: &str,
        name: &str,
        group: &str,
    ) -> Result<(), RecordsError> {
        match self {
            Db::Sqlite(r) => r.put_trainee(pseudonym, name, group),
            Db::Postgres(p) => p.put_trainee(pseudonym, name, group),
        }
    }

    pub fn store_dir(&mut self, dir: &Path, trainee: &str) -> Result<String, RecordsError> {
        match self {
            Db::Sqlite(r) => r.store_dir(dir, trainee),
            Db::Postgres(p) => p.store_dir(dir, trainee),
        }
    }

    pub fn sessions(&mut self, trainee: Option<&str>) -> Result<Vec<SessionRow>, RecordsError> {
        match self {
            Db::Sqlite(r) => r.sessions(trainee),
            Db::Postgres(p) => p.sessions(trainee),
        }
    }

    pub fn session(&mut self, id: &str) -> Result<Option<SessionDetail>, RecordsError> {
        match self {
            Db::Sqlite(r) => r.session(id),
            Db::Postgres(p) => p.session(id),
        }
    }

    pub fn group_reports(
        &mut self,
        procedure: &str,
        group: &str,
    ) -> Result<Vec<super::GroupReport>, RecordsError> {
        match self {
            Db::Sqlite(r) => r.group_reports(procedure, group),
            Db::Postgres(p) => p.group_reports(procedure, group),
        }
    }

    pub fn trainees(&mut self) -> Result<Vec<Trainee>, RecordsError> {
        match self {
            Db::Sqlite(r) => r.trainees(),
            Db::Postgres(p) => p.trainees(),
        }
    }

    pub fn level_distribution(
        &mut self,
        procedure: Option<&str>,
    ) -> Result<[(&'static str, u64); 4], RecordsError> {
        match self {
            Db::Sqlite(r) => r.level_distribution(procedure),
            Db::Postgres(p) => p.level_distribution(procedure),
        }
    }

    pub fn store_answers(
        &mut self,
        q: &Questionnaire,
        file: &str,
        answers: &[Answers],
    ) -> Result<(), RecordsError> {
        match self {
            Db::Sqlite(r) => r.store_answers(q, file, answers),
            Db::Postgres(p) => p.store_answers(q, file, answers),
        }
    }

    /// The statistics of the stored answers to `q`.
    pub fn questionnaire_report(&mut self, q: &Questionnaire) -> Result<Report, RecordsError> {
        match self {
            Db::Sqlite(r) => r.questionnaire_report(q),
            Db::Postgres(p) => {
                let answers = p.answers(&q.id)?;
                super::answers::report_of(p.shown(), q, &answers)
            }
        }
    }
}
