//! Questionnaire answers in the records (schema version 2): each participant's scores per
//! item, with their group, stored checked and in one transaction; the statistics are made
//! from what is stored (see [`crate::assess::questionnaire`]).

use super::{Records, RecordsError};
use crate::assess::questionnaire::{Answers, Questionnaire, Report};
use rusqlite::params;
use std::collections::BTreeMap;

impl Records {
    /// Stores participants' answers to `q` (`file` names the answers in errors): all are
    /// checked first, then written in one transaction; a participant who answered before
    /// has their answers replaced.
    pub fn store_answers(
        &mut self,
        q: &Questionnaire,
        file: &str,
        answers: &[Answers],
    ) -> Result<(), RecordsError> {
        check(q, file, answers)?;
        let path = self.path.clone();
        let sql = |source| RecordsError::Sqlite {
            path: path.clone(),
            source,
        };
        let tx = self.conn.transaction().map_err(sql)?;
        for a in answers {
            tx.execute(
                "DELETE FROM questionnaire_answers WHERE questionnaire = ?1 AND participant = ?2",
                params![q.id, a.participant],
            )
            .map_err(sql)?;
            for (item, score) in &a.scores {
                tx.execute(
                    "INSERT INTO questionnaire_answers (questionnaire, participant, group_name,
                         item, score) VALUES (?1, ?2, ?3, ?4, ?5)",
                    params![q.id, a.participant, a.group, item, score],
                )
                .map_err(sql)?;
            }
        }
        tx.commit().map_err(sql)
    }

    /// Every participant's stored answers to questionnaire `id`, by participant.
    pub fn answers(&self, id: &str) -> Result<Vec<Answers>, RecordsError> {
        let mut st = self
            .conn
            .prepare(
                "SELECT participant, group_name, item, score FROM questionnaire_answers
                 WHERE questionnaire = ?1 ORDER BY participant, item",
            )
            .map_err(self.sql())?;
        let rows = st
            .query_map(params![id], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, String>(1)?,
                    r.get::<_, String>(2)?,
                    r.get::<_, f64>(3)?,
                ))
            })
            .map_err(self.sql())?
            .collect::<Result<Vec<_>, _>>()
            .map_err(self.sql())?;
        Ok(grouped(rows))
    }

    /// The statistics of the stored answers to `q`, per group and item.
    pub fn questionnaire_report(&self, q: &Questionnaire) -> Result<Report, RecordsError> {
        report_of(&self.path, q, &self.answers(&q.id)?)
    }
}

/// The statistics of answers read back from records at `shown`.
pub(super) fn report_of(
    shown: &str,
    q: &Questionnaire,
    answers: &[Answers],
) -> Result<Report, RecordsError> {
    q.report(shown, answers).map_err(|e| RecordsError::Invalid {
        path: shown.to_string(),
        message: format!(
            "the stored answers to {} no longer fit its file ({}: {}); store them again",
            q.id, e.key, e.message
        ),
    })
}

/// Answers from rows of (participant, group, item, score), one set a participant, by
/// participant.
pub(super) fn grouped(rows: Vec<(String, String, String, f64)>) -> Vec<Answers> {
    let mut by: BTreeMap<String, Answers> = BTreeMap::new();
    for (participant, group, item, score) in rows {
        by.entry(participant.clone())
            .or_insert_with(|| Answers {
                participant,
                group,
                scores: BTreeMap::new(),
            })
            .scores
            .insert(item, score);
    }
    by.into_values().collect()
}

/// Checks every participant's answers to `q` before anything is written (`file` names them).
pub(super) fn check(
    q: &Questionnaire,
    file: &str,
    answers: &[Answers],
) -> Result<(), RecordsError> {
    q.report(file, answers)
        .map(|_| ())
        .map_err(|e| RecordsError::Invalid {
            path: e.file.clone(),
            message: format!("{}: {}", e.key, e.message),
        })
}
