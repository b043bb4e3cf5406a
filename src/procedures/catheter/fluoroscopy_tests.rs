use super::*;
use crate::procedures::catheter::{Catheterisation, INFO, Scenario, build_procedure};
use crate::sim::{Buttons, HandInput, Pose};
use glam::Vec3;

/// The builtin scenario without the spine, which lies under the trunk in a frontal view.
fn procedure() -> Catheterisation {
    let text = INFO
        .scenario
        .replace("bone_mu_per_m = 45.0", "bone_mu_per_m = 0.0");
    build_procedure(Scenario::parse("builtin", &text).expect("the builtin scenario"))
}

/// The right hand holds the handle where the demo starts (the tip at the inlet); the left
/// hand's trigger, grip and mark as given.
fn input(trigger: f32, grip: f32, mark: bool) -> InputFrame {
    let hand = |at: Vec3, buttons: Buttons| HandInput {
        pose: Pose {
            position: at,
            ..Pose::default()
        },
        buttons,
    };
    let mut f = InputFrame::default();
    let left = Buttons {
        trigger,
        grip,
        mark,
        pad: None,
    };
    f.hands[0] = hand(Vec3::new(-0.05, -0.04, 0.03), left);
    f.hands[1] = hand(Vec3::new(-0.1, 0.0, 0.0), Buttons::default());
    f
}

/// `seconds` of steps from step `from` with the left hand as `f` gives.
fn run(p: &mut Catheterisation, from: u64, seconds: f64, f: InputFrame) -> u64 {
    let mut events = Vec::new();
    let steps = (seconds / f64::from(p.scenario.dt_s)).round() as u64;
    for k in from..from + steps {
        p.step(&f, k, &mut events);
    }
    from + steps
}

/// Where world point `x` falls on the picture: (column, row), from the arm's geometry.
fn pixel_of(scope: &Fluoroscope, x: DVec3) -> (f64, f64) {
    let arm = scope.arm();
    let f = arm.forward.normalize();
    let r = arm.right.normalize();
    let up = f.cross(r);
    let d = x - arm.source;
    let hit = arm.source + d * (arm.distance_m / d.dot(f));
    let centre = arm.source + f * arm.distance_m;
    let (u, v) = ((hit - centre).dot(r), (hit - centre).dot(up));
    (
        u / arm.pixel_m + arm.width as f64 / 2.0 - 0.5,
        arm.height as f64 / 2.0 - v / arm.pixel_m - 0.5,
    )
}

/// The mean of `value` (by pixel index) at the pixels of 41 points along `a`-`b`.
fn mean_along(
    scope: &Fluoroscope,
    (width, height): (usize, usize),
    value: impl Fn(usize) -> f64,
    a: DVec3,
    b: DVec3,
) -> f64 {
    let mut sum = (0.0f64, 0.0f64);
    for k in 0..=40 {
        let (i, j) = pixel_of(scope, a + (b - a) * (k as f64 / 40.0));
        let (i, j) = (i.round() as usize, j.round() as usize);
        if i < width && j < height {
            sum.0 += value(j * width + i);
            sum.1 += 1.0;
        }
    }
    sum.0 / sum.1.max(1.0)
}

/// The last frame's line integral along `a`-`b` over that along the line 3 cm across
/// (towards +y: tissue alone).
fn shows(p: &Catheterisation, a: DVec3, b: DVec3) -> f64 {
    let scope = &p.imaging.scope;
    let f = scope.last().expect("a frame");
    let at =
        |a: DVec3, b: DVec3| mean_along(scope, (f.width, f.height), |k| f.line_integrals[k], a, b);
    let side = DVec3::new(0.0, 0.03, 0.0);
    at(a, b) - at(a + side, b + side)
}

/// The picture's grey along `a`-`b` less that along the line 3 cm across.
fn grey_shows(p: &Catheterisation, a: DVec3, b: DVec3) -> f64 {
    let scope = &p.imaging.scope;
    let pic = scope.picture().expect("a picture");
    let at = |a: DVec3, b: DVec3| {
        mean_along(
            scope,
            (pic.width, pic.height),
            |k| f64::from(pic.grey[k]),
            a,
            b,
        )
    };
    let side = DVec3::new(0.0, 0.03, 0.0);
    at(a, b) - at(a + side, b + side)
}

/// The trunk's axis from 10 to 30 mm past the inlet.
fn trunk_from_10_to_30_mm(p: &Catheterisation) -> (DVec3, DVec3) {
    let trunk = &p.scene.vessel().tubes[0];
    (
        trunk.start + trunk.dir * 0.01,
        trunk.start + trunk.dir * 0.03,
    )
}

#[test]
fn the_pedal_counts_pulses_and_dose_and_a_puff_its_contrast() {
    let mut p = procedure();
    // 0.5 s of pedal with a puff, 0.5 s of pedal alone, then 0.5 s of nothing.
    let at = run(&mut p, 0, 0.5, input(1.0, 1.0, false));
    let at = run(&mut p, at, 0.5, input(1.0, 0.0, false));
    run(&mut p, at, 0.5, input(0.0, 0.0, false));
    let c = p.metrics.fluoroscopy;
    // 7.5 pulses a second, the first at the press: 8 in the first second.
    assert_eq!((c.fluoro_runs, c.pulses, c.contrast_runs), (1, 8, 1));
    // 1,000 steps of 1 ms (as a float: 1.0000000475 ms).
    let dt = f64::from(p.scenario.dt_s);
    assert!(
        (c.fluoro_time_s - 1000.0 * dt).abs() < 1e-9,
        "{}",
        c.fluoro_time_s
    );
    // 4 mL/s for 0.5 s.
    assert!(
        (c.contrast_ml - 4.0 * 500.0 * dt).abs() < 1e-9,
        "{}",
        c.contrast_ml
    );
    // Each pulse 20 uGy at the reference point over the field there.
    let area = p.imaging.scope.reference_area_cm2();
    assert!((c.dap_gy_cm2 - 8.0 * 20e-6 * area).abs() < 1e-12);
    assert!((c.reference_kerma_mgy - 0.16).abs() < 1e-12);
}

#[test]
fn contrast_makes_the_trunk_show_and_it_washes_out() {
    let mut p = procedure();
    let (a, b) = trunk_from_10_to_30_mm(&p);
    // A first frame without contrast: the trunk (blood, as the tissue) does not show.
    let at = run(&mut p, 0, 0.01, input(1.0, 0.0, false));
    let clear = shows(&p, a, b);
    assert!(
        clear.abs() < 0.05,
        "the trunk shows without contrast: {clear}"
    );
    // A 0.5 s puff at the inlet; 0.3 s later the contrast (4 / 14 of the blood, moving at
    // 50 mm/s) fills the trunk from 10 to 30 mm.
    let at = run(&mut p, at, 0.5, input(1.0, 1.0, false));
    let at = run(&mut p, at, 0.3, input(1.0, 0.0, false));
    let (scene, filled) = p.imaging.scene(&p.scene);
    assert!(filled);
    assert!(scene.materials.len() > 3);
    // 4 / 14 of undiluted (230 /m) drawn at 2 / 8 of it over the lumen's 16 mm: 0.92 at
    // the axis, less off it; the pixels along the axis see most of it.
    let shown = shows(&p, a, b);
    assert!((0.6..1.0).contains(&shown), "the filled trunk: {shown}");
    // It washes out: 4 s on, the trunk and the branches (2.4 s to cross) are clear again.
    let at = run(&mut p, at, 4.0, input(0.0, 0.0, false));
    run(&mut p, at, 0.01, input(1.0, 0.0, false));
    assert!(!p.imaging.scene(&p.scene).1, "washed out");
    let after = shows(&p, a, b);
    assert!(after.abs() < 0.05, "{after}");
}

#[test]
fn the_roadmap_keeps_the_contrast_run_over_the_live_picture() {
    let mut p = procedure();
    let (a, b) = trunk_from_10_to_30_mm(&p);
    let at = run(&mut p, 0, 0.01, input(1.0, 0.0, false));
    let at = run(&mut p, at, 0.5, input(1.0, 1.0, false));
    let at = run(&mut p, at, 0.3, input(1.0, 0.0, false));
    // Washed out, a fresh frame; then the mark button: the roadmap comes on.
    let at = run(&mut p, at, 4.0, input(0.0, 0.0, false));
    let at = run(&mut p, at, 0.01, input(1.0, 0.0, false));
    assert!(!p.imaging.scope.roadmap_on);
    let at = run(&mut p, at, 0.01, input(0.0, 0.0, true));
    assert!(p.imaging.scope.roadmap_on);
    // The live frame has no contrast: the trunk is the tissue's grey, noise about it
    // (the window spans the noise); with the roadmap it is black.
    assert!(shows(&p, a, b).abs() < 0.05);
    let road = grey_shows(&p, a, b);
    assert!(road < -60.0, "the roadmap shows the trunk: {road}");
    // Held down it stays; a second press puts it off.
    let at = run(&mut p, at, 0.1, input(0.0, 0.0, true));
    assert!(p.imaging.scope.roadmap_on);
    let at = run(&mut p, at, 0.01, input(0.0, 0.0, false));
    run(&mut p, at, 0.01, input(0.0, 0.0, true));
    assert!(!p.imaging.scope.roadmap_on);
}

#[test]
fn the_catheter_is_radiopaque() {
    let mut p = procedure();
    // Push the catheter 40 mm in (the right hand forward), then one frame.
    let mut events = Vec::new();
    let mut f = input(0.0, 0.0, false);
    for k in 0..2000u64 {
        f.hands[1].pose.position.x = -0.1 + 0.04 * (k as f32 / 2000.0);
        p.step(&f, k, &mut events);
    }
    f.hands[0].buttons.trigger = 1.0;
    p.step(&f, 2000, &mut events);
    let x = &p.scene.catheter().balls.x;
    let tip = x[x.len() - 1];
    assert!(tip.x > 0.03, "the tip went in: {tip}");
    let behind = tip - p.scene.catheter().axis * 0.02;
    // 100 /m over its 10 mm: 1 at its axis.
    let shown = shows(&p, behind, tip);
    assert!(shown > 0.5, "the catheter shows: {shown}");
}

#[test]
fn a_scenario_without_fluoroscopy_gets_its_defaults_and_a_bad_value_is_named() {
    let text = INFO.scenario;
    let cut = text
        .find("[fluoroscopy]")
        .expect("the builtin has the table");
    let without = Scenario::parse("old.toml", &text[..cut]).expect("parses without it");
    assert_eq!(without.fluoroscopy, table_default());
    assert_eq!(
        Scenario::parse("builtin", text)
            .expect("parses")
            .fluoroscopy,
        table_default(),
        "the builtin's values are the defaults"
    );
    let bad = text.replace("pulse_hz = 7.5", "pulse_hz = 0.0");
    let e = Scenario::parse("tuned.toml", &bad).expect_err("no pulses");
    let said = e.to_string();
    assert!(
        said.contains("tuned.toml") && said.contains("fluoroscopy") && said.contains("pulse_hz"),
        "{said}"
    );
}

/// The left pad held at its right edge turns the arm towards LAO at the arm's rate, its top
/// edge tilts it cranial; the right pad moves the table and its centre click steps the zoom;
/// the pad's edge clicks do not toggle the roadmap, and turning the arm loses it.
#[test]
fn the_pads_turn_the_arm_move_the_table_and_zoom() {
    let mut p = procedure();
    let dt = f64::from(p.scenario.dt_s);
    let press = |left: Option<PadDirection>, right: Option<PadDirection>, right_click: bool| {
        let mut f = input(0.0, 0.0, left.is_some());
        f.hands[0].buttons.pad = left;
        f.hands[1].buttons.pad = right;
        f.hands[1].buttons.mark = right_click || right.is_some();
        f
    };
    // A run with a puff, so that there is a roadmap; then the roadmap on.
    let mut k = run(&mut p, 0, 0.3, input(1.0, 0.0, false));
    k = run(&mut p, k, 0.6, input(1.0, 1.0, false));
    k = run(&mut p, k, 0.1, input(0.0, 0.0, true));
    k = run(&mut p, k, 0.1, input(0.0, 0.0, false));
    assert!(p.imaging.scope.roadmap_on && p.imaging.scope.has_roadmap());
    // One second of the right edge: 15 degrees LAO (to the step's rounding); the roadmap is
    // lost but still on, and the edge click did not toggle it.
    k = run(
        &mut p,
        k,
        1.0,
        press(Some(PadDirection::Right), None, false),
    );
    let c = p.imaging.console;
    let steps = (1.0 / dt).round();
    assert!(
        (c.lao_deg - ARM_DEG_PER_S * steps * dt).abs() < 1e-9,
        "{c:?}"
    );
    assert_eq!(c.cranial_deg, 0.0);
    assert!(p.imaging.scope.roadmap_on && !p.imaging.scope.has_roadmap());
    // Half a second up: 7.5 degrees cranial.
    k = run(&mut p, k, 0.5, press(Some(PadDirection::Up), None, false));
    assert!((p.imaging.console.cranial_deg - 7.5).abs() < 0.05);
    // The right pad's top edge for 0.4 s: the table 2 cm towards the head; its left edge
    // 0.2 s: 1 cm towards the patient's right.
    k = run(&mut p, k, 0.4, press(None, Some(PadDirection::Up), false));
    k = run(&mut p, k, 0.2, press(None, Some(PadDirection::Left), false));
    let t = p.imaging.console.table_cm;
    assert!(
        (t[0] - 2.0).abs() < 0.02 && (t[1] + 1.0).abs() < 0.02,
        "{t:?}"
    );
    // A centre click on the right steps the zoom once however long it is held.
    let field = p.imaging.console.field_cm;
    k = run(&mut p, k, 0.3, press(None, None, true));
    assert!((p.imaging.console.field_cm - 0.75 * field).abs() < 1e-9);
    run(&mut p, k, 0.1, press(None, None, false));
    assert!(
        p.imaging.scope.roadmap_on,
        "no edge click toggled the roadmap"
    );
    // The turned arm shows the vessel from the new angle: the beam has left the frontal.
    let beam = p.imaging.scope.beam();
    assert!(beam.dot(DVec3::Z).abs() < 0.99, "{beam}");
    // The panel's line for the arm: 15 degrees LAO, the 20 cm field at 75 %.
    let figures = p.imaging.console.figures();
    let arm = figures.iter().find(|(k, _)| k == "C-arm").expect("the arm");
    assert!(
        arm.1.starts_with("LAO 15, cran ") && arm.1.ends_with(" deg, 15 cm field"),
        "{arm:?}"
    );
}
