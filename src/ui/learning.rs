//! The Learning Centre panel (the dissection paper's Fig. 14): the trainees in the records
//! with their sessions, the selected trainee's scores over their sessions, and how many
//! trainees are at each level of expertise by their latest session, as a bar chart. It reads
//! the records file the window was given and again after each session is stored.

use crate::records::{Db, RecordsError, SessionRow, Trainee};

/// What the panel shows, read from the records.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LearningCentre {
    /// Where the records are, for the heading.
    pub file: String,
    pub trainees: Vec<Trainee>,
    /// Every session, newest first.
    pub sessions: Vec<SessionRow>,
    /// Trainees at each level (novice first) by their latest session.
    pub levels: [(&'static str, u64); 4],
    /// The trainee whose sessions are listed and plotted (none: all sessions listed).
    pub selected: Option<String>,
}

/// Sessions the panel lists at most.
const LISTED: usize = 12;

impl LearningCentre {
    /// Reads what the panel shows from open records.
    pub fn read(file: &str, r: &mut Db) -> Result<LearningCentre, RecordsError> {
        Ok(LearningCentre {
            file: file.to_string(),
            trainees: r.trainees()?,
            sessions: r.sessions(None)?,
            levels: r.level_distribution(None)?,
            selected: None,
        })
    }

    /// The sessions listed: the selected trainee's, else everyone's (newest first).
    pub fn listed(&self) -> Vec<&SessionRow> {
        self.sessions
            .iter()
            .filter(|s| self.selected.as_ref().is_none_or(|t| &s.trainee == t))
            .take(LISTED)
            .collect()
    }

    /// The selected trainee's scores, oldest session first: (session number, score).
    pub fn progress(&self) -> Vec<[f64; 2]> {
        let Some(t) = &self.selected else {
            return Vec::new();
        };
        let mut mine: Vec<&SessionRow> = self.sessions.iter().filter(|s| &s.trainee == t).collect();
        mine.reverse();
        mine.iter()
            .enumerate()
            .map(|(k, s)| [(k + 1) as f64, s.score])
            .collect()
    }

    /// Draws the panel.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        ui.heading("Learning Centre");
        ui.label(format!("Records: {}", self.file));
        ui.strong("Trainees");
        let mut pick = None;
        egui::Grid::new("trainees").striped(true).show(ui, |ui| {
            for t in &self.trainees {
                let chosen = self.selected.as_ref() == Some(&t.pseudonym);
                if ui.selectable_label(chosen, &t.pseudonym).clicked() {
                    pick = Some(if chosen {
                        None
                    } else {
                        Some(t.pseudonym.clone())
                    });
                }
                ui.label(&t.name);
                ui.label(&t.group);
                ui.label(match t.sessions {
                    1 => "1 session".to_string(),
                    n => format!("{n} sessions"),
                });
                ui.end_row();
            }
        });
        if let Some(p) = pick {
            self.selected = p;
        }
        ui.strong(match &self.selected {
            Some(t) => format!("Sessions of {t}"),
            None => "Sessions".to_string(),
        });
        egui::Grid::new("sessions").striped(true).show(ui, |ui| {
            for s in self.listed() {
                ui.label(&s.procedure);
                ui.label(format!("{:.1}", s.score));
                ui.label(&s.level);
                ui.label(s.stored_at.get(..16).unwrap_or(&s.stored_at));
                ui.end_row();
            }
        });
        let progress = self.progress();
        if !progress.is_empty() {
            egui_plot::Plot::new("progress")
                .height(110.0)
                .include_y(0.0)
                .include_y(100.0)
                .allow_scroll(false)
                .allow_drag(false)
                .allow_zoom(false)
                .show(ui, |p| {
                    p.line(egui_plot::Line::new(
                        "score by session",
                        egui_plot::PlotPoints::from(progress),
                    ));
                });
        }
        ui.strong("Levels of expertise (latest session of each trainee)");
        for (level, n) in self.levels {
            ui.label(format!("{level}: {n}"));
        }
        let bars: Vec<egui_plot::Bar> = self
            .levels
            .iter()
            .enumerate()
            .map(|(k, (name, n))| egui_plot::Bar::new(k as f64, *n as f64).name(*name))
            .collect();
        egui_plot::Plot::new("levels")
            .height(110.0)
            .include_y(0.0)
            .allow_scroll(false)
            .allow_drag(false)
            .allow_zoom(false)
            .show(ui, |p| {
                p.bar_chart(egui_plot::BarChart::new("trainees", bars));
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::Scratch;
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;

    /// Two trainees' sessions in a records file: one stored twice (improving), one once; and
    /// the file's scratch folder (removed when the test passes).
    fn centre() -> (LearningCentre, Scratch) {
        let d = Scratch::new("learning", "centre");
        let mut r = Db::open(&d.join("records.sqlite")).expect("records");
        r.put_trainee("res-01", "A. Resident", "residents")
            .expect("trainee");
        let tree = crate::assess::Tree::parse("t", crate::testing::SANDBOX_TREE).expect("tree");
        for (k, (who, time_s)) in [("res-01", 34.0), ("res-02", 8.0), ("res-01", 8.0)]
            .into_iter()
            .enumerate()
        {
            let m = crate::assess::tree::measures(
                &serde_json::json!({"completion_time_s": time_s, "grasper_overloads": 0}),
                true,
                0,
                4,
                4,
                time_s,
            );
            let a = tree.score(&m);
            let s = d.join(format!("s{k}"));
            std::fs::create_dir_all(&s).expect("dir");
            let report = serde_json::json!({
                "procedure": "sandbox", "session_id": format!("{k:016x}"), "completed": true,
                "simulated_s": time_s, "assessment": a,
            });
            std::fs::write(s.join("report.json"), report.to_string()).expect("report");
            std::fs::write(s.join("input.vtrace"), b"rec").expect("rec");
            r.store_dir(&s, who).expect("stored");
        }
        let c = LearningCentre::read("records.sqlite", &mut r).expect("read");
        (c, d)
    }

    #[test]
    fn the_panel_lists_trainees_their_progress_and_the_levels() {
        let (mut c, _dir) = centre();
        assert_eq!(c.trainees.len(), 2);
        // Latest sessions: res-01 at 100 (expert), res-02 at 100 (expert); res-01's first
        // session (34 s: 76 points) was proficient.
        assert_eq!(
            c.levels,
            [
                ("novice", 0),
                ("intermediate", 0),
                ("proficient", 0),
                ("expert", 2)
            ]
        );
        assert!(c.progress().is_empty());
        c.selected = Some("res-01".into());
        assert_eq!(c.progress(), [[1.0, 76.0], [2.0, 100.0]]);
        assert_eq!(c.listed().len(), 2);
        let harness = Harness::new_ui(|ui| c.show(ui));
        harness.get_by_label("Learning Centre");
        harness.get_by_label("Sessions of res-01");
        harness.get_by_label("A. Resident");
        harness.get_by_label("expert: 2");
        harness.get_by_label("proficient: 0");
    }
}
