//! The trainee's screens over the 3D view in desktop mode: the start screen (the task and how
//! to work the instruments; the session waits for Start), the pause screen, and the results
//! screen once the session has ended (score, level, key figures), which stays until the
//! trainee closes it.

use super::dashboard::Summary;
use crate::procedures::ProcedureInfo;

/// What the trainee asked for on a screen this frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScreenActions {
    pub start: bool,
    pub resume: bool,
    pub close: bool,
}

/// The header colour of the results screen for a level of expertise (sRGB), so the level
/// reads at a glance (and a screenshot shows which one it was).
pub fn level_colour(level: &str) -> egui::Color32 {
    match level {
        "expert" => egui::Color32::from_rgb(30, 120, 60),
        "proficient" => egui::Color32::from_rgb(40, 90, 160),
        "intermediate" => egui::Color32::from_rgb(190, 130, 20),
        _ => egui::Color32::from_rgb(170, 40, 40),
    }
}

fn card(ui: &mut egui::Ui, id: &str, body: impl FnOnce(&mut egui::Ui)) {
    let rect = ui.max_rect();
    let width = (rect.width() * 0.6).clamp(280.0, 560.0);
    egui::Area::new(egui::Id::unique(id))
        .order(egui::Order::Foreground)
        .anchor(egui::Align2::CENTER_CENTER, egui::vec2(0.0, 0.0))
        .show(ui.ctx(), |ui| {
            egui::Frame::window(ui.style())
                .inner_margin(16)
                .show(ui, |ui| {
                    ui.set_width(width);
                    body(ui);
                });
        });
}

/// The start screen: the procedure, its steps in order, the controls; Start begins it.
pub fn start(ui: &mut egui::Ui, info: &ProcedureInfo) -> ScreenActions {
    let mut a = ScreenActions::default();
    card(ui, "start screen", |ui| {
        ui.heading(info.title);
        ui.add_space(6.0);
        ui.label("Do the steps in this order:");
        for (k, s) in info.steps.iter().enumerate() {
            ui.label(format!("{}. {}", k + 1, s.text));
        }
        ui.add_space(6.0);
        ui.label(
            "Mouse: move the selected instrument (1 and 2 choose); left button: its main \
             action; wheel: depth. Arrows orbit the camera; P pauses.",
        );
        ui.add_space(8.0);
        if ui.button(egui::RichText::new("Start").size(20.0)).clicked() {
            a.start = true;
        }
    });
    a
}

/// The pause screen: Resume (or P) goes on.
pub fn paused(ui: &mut egui::Ui) -> ScreenActions {
    let mut a = ScreenActions::default();
    card(ui, "pause screen", |ui| {
        ui.heading("Paused");
        ui.label("The simulation waits; nothing you do is counted.");
        if ui
            .button(egui::RichText::new("Resume").size(20.0))
            .clicked()
        {
            a.resume = true;
        }
    });
    a
}

/// The results screen: the level in its colour, the score and the key figures; Close ends.
pub fn results(ui: &mut egui::Ui, s: &Summary, steps_done: usize, steps: usize) -> ScreenActions {
    let mut a = ScreenActions::default();
    card(ui, "results screen", |ui| {
        let colour = level_colour(&s.level);
        egui::Frame::new()
            .fill(colour)
            .inner_margin(12)
            .show(ui, |ui| {
                ui.set_width(ui.available_width());
                ui.set_min_height(56.0);
                ui.label(
                    egui::RichText::new(format!("{}  ·  {:.0} / 100", s.level, s.score))
                        .size(26.0)
                        .color(egui::Color32::WHITE),
                );
            });
        ui.add_space(8.0);
        egui::Grid::new("results figures").show(ui, |ui| {
            let mut row = |k: &str, v: String| {
                ui.label(k);
                ui.label(v);
                ui.end_row();
            };
            row(
                "task",
                if s.completed {
                    "completed".into()
                } else {
                    "not completed".into()
                },
            );
            row("steps done", format!("{steps_done} of {steps}"));
            row("time", format!("{:.1} s", s.simulated_s));
            row("errors", s.errors.to_string());
            row("cuts", s.cuts.to_string());
        });
        if let Some(w) = &s.written_to {
            ui.label(format!("The session is saved in {w}."));
        }
        ui.add_space(8.0);
        if ui.button(egui::RichText::new("Close").size(20.0)).clicked() {
            a.close = true;
        }
    });
    a
}
