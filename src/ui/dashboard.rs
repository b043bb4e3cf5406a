//! The supervising surgeon's panels: the procedure's steps as a checklist, live metrics, the
//! alarm banner and log, the profiler's counters with a time plot, and at the end the session
//! report. The state here is plain data fed from the simulation's status and the renderer's
//! counters; `show` draws it with egui, so the panels can be tested without a window.

use crate::assess::alarms::{Alarm, AlarmRules, AlarmWatch};
use crate::procedures::{ProcedureInfo, Tunable};
use crate::profiler::FrameCounters;
use crate::session::{Report, Status};
use std::collections::VecDeque;

/// Samples of the profiler plot kept (about 10 s at 90 frames a second).
const PLOT_SAMPLES: usize = 900;
/// Past alarms shown in the log.
const LOG_LINES: usize = 200;

/// One frame's timings for the plot, milliseconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameTimes {
    pub time_s: f64,
    pub frame_ms: f32,
    pub render_ms: f32,
    pub ui_ms: f32,
}

/// The end of a session: the report's headline and where its files went.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    pub completed: bool,
    pub score: f32,
    /// The level of expertise the score gives (novice ... expert).
    pub level: String,
    pub simulated_s: f64,
    pub cuts: u64,
    pub errors: u32,
    pub written_to: Option<String>,
}

impl Summary {
    pub fn from_report(r: &Report, written_to: Option<String>) -> Summary {
        Summary {
            completed: r.completed,
            score: r.score,
            level: r.level.clone(),
            simulated_s: r.simulated_s,
            cuts: r.events.get("cut").copied().unwrap_or(0),
            errors: r.errors,
            written_to,
        }
    }
}

/// What the panels show.
pub struct Dashboard {
    pub info: &'static ProcedureInfo,
    /// Where the view and input come from ("playing demo.toml", "mouse and keyboard").
    pub source: String,
    pub status: Status,
    watch: AlarmWatch,
    /// Alarms whose condition holds now (the banner).
    pub active: Vec<Alarm>,
    /// Alarms raised so far, oldest first.
    pub log: VecDeque<Alarm>,
    pub counters: FrameCounters,
    pub plot: VecDeque<FrameTimes>,
    pub summary: Option<Summary>,
    /// Lines of the key map shown under the view (desktop mode).
    pub key_map: Vec<(String, String)>,
    /// The instrument the mouse drives (desktop mode).
    pub driving: Option<&'static str>,
    /// What the 3D view shows of an XR session.
    pub viewing: Option<&'static str>,
    /// The tissue sliders' values (from the simulation until the first edit).
    pub edit: Option<Vec<Tunable>>,
    /// Where the tuned scenario was last written, or why it was not.
    pub saved: Option<String>,
    /// The Learning Centre panel, when the window has records.
    pub learning: Option<super::learning::LearningCentre>,
}

/// What the supervisor asked for this frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Actions {
    /// Apply these values of this model now.
    pub tune: Option<(String, Vec<(String, f32)>)>,
    /// Write the current parameters into the scenario file.
    pub save: bool,
}

impl Dashboard {
    pub fn new(info: &'static ProcedureInfo, source: &str, rules: AlarmRules) -> Dashboard {
        Dashboard {
            info,
            source: source.to_string(),
            status: Status::default(),
            watch: AlarmWatch::new(rules),
            active: Vec::new(),
            log: VecDeque::new(),
            counters: FrameCounters::default(),
            plot: VecDeque::new(),
            summary: None,
            key_map: Vec::new(),
            driving: None,
            viewing: None,
            edit: None,
            saved: None,
            learning: None,
        }
    }

    /// Takes the simulation's newest status: updates the metrics, the banner and the log.
    pub fn update(&mut self, status: Status) {
        let (now, raised) = self.watch.update(&status);
        self.active = now;
        for a in raised {
            if self.log.len() == LOG_LINES {
                self.log.pop_front();
            }
            self.log.push_back(a);
        }
        self.status = status;
    }

    /// Takes one rendered frame's counters and timings.
    pub fn frame(&mut self, counters: FrameCounters, times: FrameTimes) {
        self.counters = counters;
        if self.plot.len() == PLOT_SAMPLES {
            self.plot.pop_front();
        }
        self.plot.push_back(times);
    }

    /// Index of the step the trainee is on (the first not done), `None` when all are done.
    pub fn current_step(&self) -> Option<usize> {
        self.info
            .steps
            .iter()
            .position(|step| !self.status.steps_done.iter().any(|d| d == step.id))
    }

    /// The metrics panel's rows: label and value.
    pub fn metric_rows(&self) -> Vec<(String, String)> {
        let s = &self.status;
        let [left, right] = self.info.tools.map(|t| t.name);
        let mut rows = vec![
            ("Elapsed".to_string(), format!("{:.1} s", s.time_s)),
            (
                format!("Path, {left}"),
                format!("{:.0} mm", s.path_m[0] * 1000.0),
            ),
            (
                format!("Path, {right}"),
                format!("{:.0} mm", s.path_m[1] * 1000.0),
            ),
        ];
        rows.extend(s.figures.iter().cloned());
        rows.push(("Errors".to_string(), s.errors.to_string()));
        for (t, f) in self.info.tools.iter().zip(s.force_n) {
            if t.kind != crate::procedures::ToolKind::Laser {
                rows.push((format!("Force, {}", t.name), format!("{f:.2} N")));
            }
        }
        rows.push(("Score so far".to_string(), format!("{:.1}", s.score)));
        rows
    }

    /// Draws the panels around `view`, which draws the 3D view into the central panel; returns
    /// what the supervisor asked for.
    pub fn show(&mut self, ui: &mut egui::Ui, view: impl FnOnce(&mut egui::Ui)) -> Actions {
        let mut actions = Actions::default();
        egui::Panel::top("title").show(ui, |ui| {
            ui.horizontal(|ui| {
                ui.heading(format!("Vesalius: {}", self.info.title));
                ui.separator();
                ui.label(&self.source);
                if let Some(tool) = self.driving {
                    ui.separator();
                    ui.strong(format!("the mouse drives {tool}"));
                }
                if let Some(what) = self.viewing {
                    ui.separator();
                    ui.strong(format!("showing {what}"));
                }
            });
            self.banner(ui);
        });
        egui::Panel::left("task")
            .default_size(270.0)
            .show(ui, |ui| {
                self.steps(ui);
                ui.separator();
                self.metrics(ui);
                ui.separator();
                self.alarm_log(ui);
                ui.separator();
                self.instructions(ui);
            });
        egui::Panel::right("profiler")
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    self.profiler(ui);
                    ui.separator();
                    actions = self.tissue(ui);
                    if let Some(s) = &self.summary {
                        ui.separator();
                        summary(ui, s);
                    }
                    if let Some(l) = &mut self.learning {
                        ui.separator();
                        l.show(ui);
                    }
                });
            });
        if !self.key_map.is_empty() {
            egui::Panel::bottom("keys").show(ui, |ui| {
                ui.horizontal_wrapped(|ui| {
                    for (key, what) in &self.key_map {
                        ui.strong(key);
                        ui.label(what);
                        ui.separator();
                    }
                });
            });
        }
        egui::CentralPanel::no_frame().show(ui, view);
        actions
    }

    /// The tunable models' sliders: applied when a slider is let go, and saved on request.
    fn tissue(&mut self, ui: &mut egui::Ui) -> Actions {
        let now = self.status.tunables.clone();
        let mut edit = self.edit.take().unwrap_or_else(|| now.clone());
        let mut actions = Actions::default();
        let mut heading: Option<String> = None;
        for (k, t) in edit.iter_mut().enumerate() {
            if heading.as_deref() != Some(t.model.as_str()) {
                ui.heading(format!("Tissue ({})", t.model));
                heading = Some(t.model.clone());
            }
            let mut shown = t.value * t.scale;
            let r = ui.add(
                egui::Slider::new(&mut shown, t.min * t.scale..=t.max * t.scale).text(t.label),
            );
            t.value = shown / t.scale;
            let apply = r.drag_stopped() || (r.changed() && !r.dragged());
            let before = now.get(k).map(|n| n.value);
            if apply && before != Some(t.value) {
                let values = vec![(t.key.to_string(), t.value)];
                actions.tune = Some((t.model.clone(), values));
            }
        }
        self.edit = Some(edit);
        if !now.is_empty() {
            actions.save = ui.button("Save to scenario file").clicked();
        }
        if let Some(s) = &self.saved {
            ui.label(s);
        }
        actions
    }

    fn banner(&self, ui: &mut egui::Ui) {
        if self.active.is_empty() {
            ui.colored_label(egui::Color32::from_rgb(90, 170, 90), "No alarm");
            return;
        }
        egui::Frame::new()
            .fill(egui::Color32::from_rgb(170, 30, 30))
            .inner_margin(6.0)
            .show(ui, |ui| {
                for a in &self.active {
                    ui.colored_label(egui::Color32::WHITE, format!("ALARM: {}", a.message()));
                }
            });
    }

    fn steps(&self, ui: &mut egui::Ui) {
        ui.heading("Procedure");
        let current = self.current_step();
        for (k, step) in self.info.steps.iter().enumerate() {
            let done = self.status.steps_done.iter().any(|d| d == step.id);
            let mark = if done { "[x]" } else { "[ ]" };
            let text = egui::RichText::new(format!("{mark} {}", step.text));
            if current == Some(k) {
                ui.label(text.strong().color(egui::Color32::from_rgb(240, 200, 60)));
            } else {
                ui.label(text);
            }
        }
    }

    fn metrics(&self, ui: &mut egui::Ui) {
        ui.heading("Metrics");
        egui::Grid::new("metrics").striped(true).show(ui, |ui| {
            for (label, value) in self.metric_rows() {
                ui.label(label);
                ui.label(value);
                ui.end_row();
            }
        });
    }

    fn alarm_log(&self, ui: &mut egui::Ui) {
        ui.heading("Alarms");
        if self.log.is_empty() {
            ui.label("none so far");
        }
        egui::ScrollArea::vertical()
            .max_height(160.0)
            .stick_to_bottom(true)
            .show(ui, |ui| {
                for a in &self.log {
                    ui.label(format!("{:6.2} s  {}", a.time_s, a.message()));
                }
            });
    }

    fn profiler(&self, ui: &mut egui::Ui) {
        ui.heading("Profiler");
        let c = &self.counters;
        let mb = |b: u64| format!("{:.1} MB", b as f64 / 1e6);
        egui::Grid::new("counters").striped(true).show(ui, |ui| {
            for (label, value) in [
                ("Batches", c.batches.to_string()),
                ("Draw calls", c.draw_calls.to_string()),
                ("SetPass calls", c.setpass_calls.to_string()),
                ("Triangles", c.triangles.to_string()),
                ("Vertices", c.vertices.to_string()),
                ("VRAM", mb(c.vram_bytes)),
                ("Total memory", mb(c.total_memory_bytes)),
                ("Objects", c.objects.to_string()),
            ] {
                ui.label(label);
                ui.label(value);
                ui.end_row();
            }
        });
        if let Some(last) = self.plot.back() {
            ui.label(format!(
                "frame {:.1} ms (render {:.1}, panels {:.1})",
                last.frame_ms, last.render_ms, last.ui_ms
            ));
        }
        let line = |pick: fn(&FrameTimes) -> f32, name: &str| {
            let points: Vec<[f64; 2]> = self
                .plot
                .iter()
                .map(|t| [t.time_s, f64::from(pick(t))])
                .collect();
            egui_plot::Line::new(name, egui_plot::PlotPoints::from(points))
        };
        egui_plot::Plot::new("frame times")
            .height(140.0)
            .legend(egui_plot::Legend::default())
            .allow_scroll(false)
            .allow_drag(false)
            .allow_zoom(false)
            .show(ui, |p| {
                p.line(line(|t| t.frame_ms, "frame ms"));
                p.line(line(|t| t.render_ms, "render ms"));
                p.line(line(|t| t.ui_ms, "panels ms"));
            });
    }
}

impl Dashboard {
    /// The dynamic assessment's newest instructions to the trainee.
    fn instructions(&self, ui: &mut egui::Ui) {
        ui.heading("Instructions");
        if self.status.instructions.is_empty() {
            ui.label("None so far");
        }
        for line in &self.status.instructions {
            ui.label(line);
        }
    }
}

fn summary(ui: &mut egui::Ui, s: &Summary) {
    ui.heading("Session report");
    ui.label(if s.completed {
        "Procedure completed"
    } else {
        "Procedure not completed"
    });
    ui.label(format!("Score {:.1} / 100: {}", s.score, s.level));
    ui.label(format!(
        "{:.2} s simulated, {} cuts, {} errors",
        s.simulated_s, s.cuts, s.errors
    ));
    match &s.written_to {
        Some(dir) => ui.label(format!("Written to {dir}")),
        None => ui.label("Not saved (no --out)"),
    };
}

#[cfg(test)]
mod tests {
    use super::*;
    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;

    fn info() -> &'static ProcedureInfo {
        crate::registry::REGISTRY[0]
    }

    fn dashboard() -> Dashboard {
        Dashboard::new(
            info(),
            "playing demo.toml",
            AlarmRules::for_procedure(info()),
        )
    }

    #[test]
    fn a_tool_near_a_vulnerable_structure_shows_a_banner_logs_once_and_the_checklist_moves_on() {
        let mut d = dashboard();
        let steps = info().steps;
        let left = info().tools[0].name;
        let mut s = Status {
            time_s: 1.5,
            steps_done: vec![steps[0].id.into()],
            score: 31.25,
            path_m: [0.12, 0.4],
            ..Status::default()
        };
        s.near[0] = Some(("renal_artery".into(), 0.004));
        d.update(s.clone());
        s.time_s = 1.6;
        d.update(s);
        assert_eq!(d.current_step(), Some(1));
        assert_eq!(d.log.len(), 1, "one episode, one log line");
        let harness = Harness::new_ui(|ui| {
            d.show(ui, |_| {});
        });
        // In words: the structure's name as people say it.
        harness.get_by_label(&format!(
            "ALARM: The {left} is 4.0 mm from the renal artery"
        ));
        harness.get_by_label_contains(&format!(
            "1.50 s  The {left} is 4.0 mm from the renal artery"
        ));
        harness.get_by_label(&format!("[x] {}", steps[0].text));
        harness.get_by_label(&format!("[ ] {}", steps[1].text));
        harness.get_by_label("31.2");
        harness.get_by_label("120 mm");
        assert!(harness.query_by_label("No alarm").is_none());
        assert!(harness.query_by_label("Session report").is_none());
    }

    #[test]
    fn the_dynamic_assessments_instructions_are_shown_newest_first() {
        let mut d = dashboard();
        let harness = Harness::new_ui(|ui| {
            d.show(ui, |_| {});
        });
        harness.get_by_label("None so far");
        drop(harness);
        d.update(Status {
            instructions: vec![
                "4.2 s: Keep clear of the renal artery and vein".into(),
                "1.0 s: Grip more gently".into(),
            ],
            ..Status::default()
        });
        let harness = Harness::new_ui(|ui| {
            d.show(ui, |_| {});
        });
        harness.get_by_label("4.2 s: Keep clear of the renal artery and vein");
        harness.get_by_label("1.0 s: Grip more gently");
        assert!(harness.query_by_label("None so far").is_none());
    }

    #[test]
    fn the_end_of_a_session_shows_its_report_and_where_it_went() {
        let mut d = dashboard();
        let steps = info().steps;
        d.update(Status {
            time_s: 22.9,
            steps_done: steps.iter().map(|s| s.id.to_string()).collect(),
            ..Status::default()
        });
        d.summary = Some(Summary {
            completed: true,
            score: 95.2,
            level: "expert".into(),
            simulated_s: 22.95,
            cuts: 199,
            errors: 0,
            written_to: Some("/tmp/session".into()),
        });
        assert_eq!(d.current_step(), None);
        let harness = Harness::new_ui(|ui| {
            d.show(ui, |_| {});
        });
        harness.get_by_label("No alarm");
        harness.get_by_label("Procedure completed");
        harness.get_by_label("Score 95.2 / 100: expert");
        harness.get_by_label("22.95 s simulated, 199 cuts, 0 errors");
        harness.get_by_label("Written to /tmp/session");
        harness.get_by_label(&format!("[x] {}", steps[steps.len() - 1].text));
    }

    #[test]
    fn a_slider_moved_with_the_keyboard_asks_for_the_new_value_and_save_asks_to_save() {
        let mut d = dashboard();
        let slider = |key: &'static str, label: &'static str, value: f32, max: f32| Tunable {
            model: "tissue".into(),
            key,
            label,
            min: 0.0,
            max,
            scale: 1.0,
            value,
        };
        let start = vec![
            slider("foundation_pa_per_m", "foundation (N/m^3)", 1.6e6, 1e7),
            slider("damping_per_s", "damping (1/s)", 8.0, 50.0),
        ];
        d.update(Status {
            tunables: start.clone(),
            ..Status::default()
        });
        let mut asked = Vec::new();
        {
            let mut harness = Harness::new_ui(|ui| {
                let a = d.show(ui, |_| {});
                if a != Actions::default() {
                    asked.push(a);
                }
            });
            harness
                .get_by_role_and_label(egui::accesskit::Role::Slider, "foundation (N/m^3)")
                .focus();
            harness.run();
            harness.key_press(egui::Key::ArrowRight);
            harness.run();
            harness.get_by_label("Save to scenario file").click();
            harness.run();
        }
        let tuned: Vec<(String, Vec<(String, f32)>)> =
            asked.iter().filter_map(|a| a.tune.clone()).collect();
        assert_eq!(tuned.len(), 1, "{asked:?}");
        let (model, values) = &tuned[0];
        assert_eq!(model, "tissue");
        assert_eq!(values.len(), 1, "only the moved slider: {values:?}");
        assert_eq!(values[0].0, "foundation_pa_per_m");
        assert!(values[0].1 > 1.6e6, "{values:?}");
        assert_eq!(asked.iter().filter(|a| a.save).count(), 1);
    }
}
