use super::*;
use crate::procedures::rectum::{Anatomy, INFO, Scenario};
use crate::sim::{Buttons, EventKind, HandInput, Pose};
use glam::Quat;

/// The shipped scenario on a coarse grid (60 x 48 per layer), with `edit` applied to its text.
fn coarse(edit: impl Fn(String) -> String) -> Scenario {
    let text = INFO
        .scenario
        .replace("rows = 600", "rows = 60")
        .replace("cols = 400", "cols = 48");
    Scenario::parse("coarse.toml", &edit(text)).expect("scenario")
}

fn rectum(s: Scenario) -> Rectum {
    let a = Anatomy::generate(s.anatomy_params()).expect("anatomy");
    Rectum::new(s, &a).expect("rectum")
}

/// Forward (-Z) pointing down (-Y), the hook (+Y) pointing along -Z.
fn from_above() -> Quat {
    Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
}

/// The hook's corner for its end to sit between the fasciae at row `i`, column `j`.
fn in_plane(r: &Rectum, i: usize, j: usize) -> Vec3 {
    let m = &r.scene.membrane();
    0.5 * (m.position(m.node(1, i, j)) + m.position(m.node(2, i, j))) + Vec3::new(0.0, 0.0, 0.006)
}

/// Input with the hook at `corner` (current on or off) and the grasper parked far away.
fn hook_at(corner: Vec3, current: bool) -> InputFrame {
    let mut f = InputFrame::default();
    f.hands[1] = HandInput {
        pose: Pose {
            position: corner,
            orientation: from_above(),
        },
        buttons: Buttons {
            trigger: if current { 1.0 } else { 0.0 },
            ..Buttons::default()
        },
    };
    f.hands[0].pose = Pose::looking_at(Vec3::new(0.0, 0.2, 0.0), Vec3::ZERO);
    f
}

#[test]
fn the_shipped_scenario_is_the_papers_grid_and_bad_values_name_their_key() {
    let s = Scenario::parse("rectum.toml", INFO.scenario).expect("shipped");
    assert_eq!(s.nodes(), 960_000);
    let bad = |from: &str, to: &str| {
        let text = INFO.scenario.replace(from, to);
        Scenario::parse("bad.toml", &text).expect_err("refused")
    };
    let e = bad("target_to = 0.525", "target_to = 0.4");
    assert_eq!(
        (e.file.as_str(), e.key.as_str()),
        ("bad.toml", "task.target_to")
    );
    let e = bad("integrator = \"symplectic\"", "integrator = \"euler\"");
    assert_eq!(e.key, "membrane.integrator");
    assert!(e.message.contains("runge_kutta_4"), "{e}");
    let e = bad("pelvis_radius_m = 0.034", "pelvis_radius_m = 0.03");
    assert_eq!(e.key, "anatomy.pelvis_radius_m");
    let e = bad("rows = 600", "rows = 1000");
    assert_eq!(e.key, "anatomy.rows");
    for (from, to, key) in [
        (
            "cut_radius_m = 0.002",
            "cut_radius_m = -1.0",
            "tools.cut_radius_m",
        ),
        ("tile_rows = 8 ", "tile_rows = 1 ", "membrane.tile_rows"),
        ("tile_cols = 16", "tile_cols = 100", "membrane.tile_cols"),
        (
            "link_damping_ratio = 0.5",
            "link_damping_ratio = -0.1",
            "membrane.link_damping_ratio",
        ),
    ] {
        assert_eq!(bad(from, to).key, key);
    }
    // Files from before the optional keys: the links' damping 0.5, tiles of 8 x 16.
    let old = INFO
        .scenario
        .lines()
        .filter(|l| !l.starts_with("tile_") && !l.starts_with("link_damping_ratio"))
        .collect::<Vec<_>>()
        .join("\n");
    let p = Scenario::parse("old.toml", &old)
        .expect("an older file")
        .scene_params();
    assert_eq!(p.membrane.link_damping_ratio, 0.5);
    assert_eq!((p.activity.tile_rows, p.activity.tile_cols), (8, 16));
    // The CPU preset's tiles reach the scene.
    let (file, text) = INFO
        .cpu_preset_scenario()
        .expect("a preset")
        .expect("valid");
    let p = Scenario::parse(&file, &text)
        .expect("preset")
        .scene_params();
    assert_eq!((p.activity.tile_rows, p.activity.tile_cols), (2, 4));
    assert_eq!(p.membrane.spring_damping_ratio, 0.075);
    assert_eq!(p.membrane.link_damping_ratio, 0.1);
}

#[test]
fn cutting_in_the_target_counts_correct_cuts_and_raises_spring_cut_events() {
    let mut r = rectum(coarse(|t| t));
    let (rows, cols) = (r.scene.membrane().rows(), r.scene.membrane().cols());
    let (cut0, total) = r.scene.target_progress();
    assert_eq!(cut0, 0);
    // The target: rows 0.475-0.525 of 60 (rows 28-31), 80 degrees of 48 columns round the
    // front.
    assert!(total > 0 && total < (rows * cols) as u32, "{total}");
    let mut events = Vec::new();
    let corner = in_plane(&r, rows / 2, 0);
    r.step(&hook_at(corner, false), 0, &mut events);
    assert!(
        r.reactions()[1].length() > 0.0,
        "the hook presses the fasciae"
    );
    r.step(&hook_at(corner, true), 1, &mut events);
    let m = &r.metrics;
    assert!(m.correct_cuts > 0, "{m:?}");
    assert_eq!(m.correct_cuts, r.scene.target_progress().0);
    let cut_events: u32 = events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::Procedure(p) if p.name == "spring_cut" => p.fields["springs"].as_u64(),
            _ => None,
        })
        .map(|n| n as u32)
        .sum();
    assert_eq!(cut_events, m.correct_cuts + m.incorrect_cuts);
    assert!(m.correct_cut_ratio > 0.0 && m.correct_cut_ratio <= 1.0);
    // The checklist waits for the exposure: no step before it, however much is cut.
    assert!(m.steps_done.is_empty(), "{:?}", m.steps_done);
    // A cut outside the target (the back of the section) is counted as incorrect.
    let before = r.metrics.incorrect_cuts;
    let back = in_plane(&r, rows / 2, cols / 2);
    r.step(&hook_at(back, true), 2, &mut events);
    assert!(r.metrics.incorrect_cuts > before, "{:?}", r.metrics);
}

#[test]
fn the_hook_on_a_ureter_raises_an_alarm_event_in_that_step() {
    let mut r = rectum(coarse(|t| t));
    let (rows, cols) = (r.scene.membrane().rows(), r.scene.membrane().cols());
    let m = &r.scene.membrane();
    let ureter = m.position(m.node(3, rows / 5, cols / 4)) + Vec3::new(0.0, 0.0, 0.006);
    let mut events = Vec::new();
    r.step(&hook_at(ureter, false), 0, &mut events);
    let alarms: Vec<&str> = events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::Alarm { message, .. } => Some(message.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(alarms, ["the hook touches the left ureter"], "{events:?}");
    assert_eq!(r.metrics.vulnerable_contacts, 1);
    assert!(r.touching_now());
}

#[test]
fn the_drawn_layers_show_the_dissection_and_the_vulnerable_structures() {
    let mut r = rectum(coarse(|t| t));
    let rows = r.scene.membrane().rows();
    let corner = in_plane(&r, rows / 2, 0);
    let mut events = Vec::new();
    r.step(&hook_at(corner, true), 0, &mut events);
    let s = r.snapshot(1);
    let names: Vec<&str> = s.models.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["rectum", "fascia", "pelvis"]);
    let fascia = &s.models[1];
    // Two layers of the 60 x 48 grid, closed round the ring.
    assert_eq!(fascia.positions.len(), 2 * 60 * 48);
    assert_eq!(fascia.indices.len(), 2 * 59 * 48 * 6);
    assert!(fascia.cut_edge.iter().any(|&c| c), "the cut shows");
    assert!(fascia.regions.contains(&1), "the target is drawn as such");
    let pelvis = &s.models[2];
    assert!(
        pelvis.regions.contains(&1),
        "the ureters and plexus are drawn"
    );
    assert!(
        s.models
            .iter()
            .all(|m| m.normals.len() == m.positions.len()
                && m.positions.iter().all(|p| p.is_finite()))
    );
}

/// Springs cut in the events of `step`.
fn springs_cut(events: &[SimEvent], step: u64) -> u64 {
    events
        .iter()
        .filter(|e| e.step == step)
        .filter_map(|e| match &e.kind {
            EventKind::Procedure(p) if p.name == "spring_cut" => p.fields["springs"].as_u64(),
            _ => None,
        })
        .sum()
}

#[test]
fn cutting_gives_off_smoke_at_the_hooks_end_that_is_forgotten_after_two_seconds() {
    let mut r = rectum(coarse(|t| t));
    let rows = r.scene.membrane().rows();
    let mut events = Vec::new();
    let corner = in_plane(&r, rows / 2, 0);
    r.step(&hook_at(corner, false), 0, &mut events);
    assert!(
        r.snapshot(1).emissions.is_empty(),
        "no smoke without current"
    );
    r.step(&hook_at(corner, true), 1, &mut events);
    assert!(springs_cut(&events, 1) > 0, "the hook cut");
    let s = r.snapshot(2);
    assert_eq!(s.emissions.len(), 1, "{:?}", s.emissions);
    let e = s.emissions[0];
    assert_eq!(e.kind, crate::sim::EmissionKind::Smoke);
    // At the end of the step that cut (the snapshot's time), at the hook's working end: the
    // tip of its L, not the corner the hand holds.
    assert_eq!(e.time_s, s.time_s);
    let hook = crate::collision::Instrument::l_hook(corner, from_above()).expect("hook");
    let end = hook.cylinders()[1].p1();
    assert_eq!(e.position, end);
    assert_eq!(s.tools[1].tip, end);
    assert!(
        e.position.distance(corner) > 0.003,
        "the end, not the corner"
    );
    // A millisecond later it cuts again, but smoke is given off at most every 15 ms.
    let next = in_plane(&r, rows / 2, 2);
    r.step(&hook_at(next, true), 2, &mut events);
    assert!(springs_cut(&events, 2) > 0, "the hook cut again");
    assert_eq!(r.snapshot(3).emissions.len(), 1);
    // 20 ms on (the step number is the clock), another cut, another emission.
    let further = in_plane(&r, rows / 2, 46);
    r.step(&hook_at(further, true), 21, &mut events);
    assert!(springs_cut(&events, 21) > 0, "the hook cut a third time");
    let at = |steps: u64| steps as f64 * f64::from(r.scenario.dt_s);
    let (first, second) = (at(2), at(22));
    let times: Vec<f64> = r.snapshot(22).emissions.iter().map(|e| e.time_s).collect();
    assert_eq!(times, [first, second]);
    // With the current off, none; and each is forgotten 2 s after it was given off.
    r.step(&hook_at(further, false), 2010, &mut events);
    let times: Vec<f64> = r
        .snapshot(2011)
        .emissions
        .iter()
        .map(|e| e.time_s)
        .collect();
    assert_eq!(times, [second]);
    r.step(&hook_at(further, false), 2030, &mut events);
    assert!(r.snapshot(2031).emissions.is_empty());
}

#[test]
fn the_left_device_drives_the_laparoscope_while_its_button_is_held() {
    let mut r = rectum(coarse(|t| t));
    let mut events = Vec::new();
    let start = Vec3::new(0.0, 0.2, 0.0);
    let mut input = hook_at(Vec3::new(0.0, 0.3, 0.0), false);
    input.hands[0].pose = Pose::looking_at(start, Vec3::ZERO);
    r.step(&input, 0, &mut events);
    assert_eq!(
        r.snapshot(1).scope,
        None,
        "the procedure's viewpoint to begin with"
    );
    let grasper_at = r.tool_tip(0);
    // Button down, the device moves 3 cm along +x over 30 steps: the camera goes with it,
    // the grasper stays and travels nothing.
    for k in 0..=30 {
        input.hands[0].buttons.mark = true;
        input.hands[0].pose = Pose::looking_at(
            start + Vec3::new(0.001 * k as f32, 0.0, 0.0),
            Vec3::new(0.001 * k as f32, 0.0, 0.0),
        );
        r.step(&input, k + 1, &mut events);
    }
    let scope = r.snapshot(32).scope.expect("a moved laparoscope");
    let home = INFO.view;
    assert!(
        (scope.eye - (home.eye + Vec3::new(0.03, 0.0, 0.0))).length() < 1e-5,
        "{scope:?} from {home:?}"
    );
    assert!((scope.target - (home.target + Vec3::new(0.03, 0.0, 0.0))).length() < 1e-5);
    assert!(r.tool_tip(0).distance(grasper_at) < 1e-6);
    assert!(
        r.metrics.path_length_left_m < 1e-6,
        "{}",
        r.metrics.path_length_left_m
    );
    // Button up: the grasper follows the device's motions from where it waited.
    input.hands[0].buttons.mark = false;
    r.step(&input, 32, &mut events);
    assert!(r.tool_tip(0).distance(grasper_at) < 1e-6);
    input.hands[0].pose.position += Vec3::new(0.0, 0.0, 0.01);
    r.step(&input, 33, &mut events);
    assert!(
        r.tool_tip(0)
            .distance(grasper_at + Vec3::new(0.0, 0.0, 0.01))
            < 1e-5,
        "{} from {grasper_at}",
        r.tool_tip(0)
    );
    assert!((r.metrics.path_length_left_m - 0.01).abs() < 1e-5);
    // The camera stays where it was left.
    assert_eq!(r.snapshot(34).scope, Some(scope));
}

/// Names of the `instrument_change` events' instruments, in order.
fn changes(events: &[SimEvent]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::Procedure(p) if p.name == "instrument_change" => {
                p.fields["to"].as_str().map(str::to_string)
            }
            _ => None,
        })
        .collect()
}

#[test]
fn the_right_hand_changes_hook_for_grasper_and_instrument_selection_follows_the_task() {
    let mut r = rectum(coarse(|t| t));
    let rows = r.scene.membrane().rows();
    let m = &r.scene.membrane();
    let top = m.position(m.node(0, rows / 2, 0));
    let mut events = Vec::new();
    // The primary button pressed and held for three steps: one change, to the grasper.
    let mut input = hook_at(top + Vec3::Y * 0.03, false);
    for k in 0..3 {
        input.hands[1].buttons.mark = true;
        r.step(&input, k, &mut events);
    }
    assert_eq!(changes(&events), ["right grasper"]);
    assert_eq!(r.right_tool(), RightTool::Grasper);
    assert_eq!(r.snapshot(3).tools[1].instrument, 1);
    // The grasper closes (trigger) on the top of the rectum and lifts it 6 mm: the exposure,
    // done with the instrument it calls for.
    input.hands[1].buttons.mark = false;
    input.hands[1].buttons.trigger = 1.0;
    let mut step = 3;
    for k in 0..300u64 {
        input.hands[1].pose.position = top + Vec3::Y * (0.006 * k as f32 / 299.0);
        r.step(&input, step, &mut events);
        step += 1;
        if !r.metrics.steps_done.is_empty() {
            break;
        }
    }
    assert!(r.scene.rod().grip(1).is_some(), "the right grasper holds");
    assert!(r.scene.rod().grip(0).is_none(), "the left one does not");
    assert!(
        events.iter().any(|e| matches!(&e.kind,
            EventKind::Grasp { tool, .. } if tool == "right grasper")),
        "{events:?}"
    );
    assert_eq!(r.metrics.steps_done, ["expose"]);
    assert_eq!(r.metrics.instrument_selection, Some(1.0));
    assert!(
        r.reactions()[1].length() > 0.0,
        "the grasper feels the rectum"
    );
    // Holding on into the next step (enter: the hook's) counts against the selection.
    let (work, apt) = (r.sums.right_work_steps, r.sums.right_apt_steps);
    for k in 0..100u64 {
        r.step(&input, step + k, &mut events);
    }
    step += 100;
    assert_eq!(r.sums.right_work_steps, work + 100);
    assert_eq!(r.sums.right_apt_steps, apt);
    let share = r.metrics.instrument_selection.expect("measured");
    assert!(
        (share - apt as f32 / (work + 100) as f32).abs() < 1e-6,
        "{share}"
    );
    assert!(share < 1.0);
    // The button again: back to the hook, the grasper lets go; the trigger is the hook's
    // current now, and no spring was cut while the grasper held it.
    assert_eq!(r.metrics.correct_cuts + r.metrics.incorrect_cuts, 0);
    input.hands[1].buttons.mark = true;
    input.hands[1].buttons.trigger = 0.0;
    r.step(&input, step, &mut events);
    assert_eq!(changes(&events), ["right grasper", "hook"]);
    assert_eq!(r.metrics.instrument_changes, 2);
    assert!(r.scene.rod().grip(1).is_none());
    assert_eq!(r.snapshot(step + 1).tools[1].instrument, 0);
    assert!(events.iter().any(|e| matches!(&e.kind,
        EventKind::Release { tool } if tool == "right grasper")));
}

/// The demo trace's first `seconds` on the coarse grid with `compute` (the scenario's key):
/// the procedure, its events, and the hook's reaction at every step.
fn demo_on(
    compute: &str,
    seconds: f64,
    spoil: impl Fn(&mut Rectum, u64),
) -> (Rectum, Vec<SimEvent>, Vec<Vec3>) {
    let key = format!("procedure = \"rectum\"\ncompute = \"{compute}\"");
    let mut r = rectum(coarse(|t| t.replacen("procedure = \"rectum\"", &key, 1)));
    let trace = crate::trace::KeyTrace::parse("demo", INFO.demo_trace).expect("demo trace");
    let mut clock = crate::sim::Clock::new(r.scenario.dt_s, crate::sim::Pacing::AsFastAsPossible);
    let (mut events, mut hook) = (Vec::new(), Vec::new());
    while clock.time_s() < seconds {
        spoil(&mut r, clock.step());
        r.step(&trace.sample(clock.time_s()), clock.step(), &mut events);
        hook.push(r.reactions()[1]);
        clock.tick();
    }
    (r, events, hook)
}

fn of_kind<'a>(events: &'a [SimEvent], name: &str) -> Vec<&'a EventKind> {
    events
        .iter()
        .map(|e| &e.kind)
        .filter(|k| k.name() == name)
        .collect()
}

#[test]
fn the_membrane_on_the_gpu_dissects_as_on_the_cpu() {
    use crate::procedures::Procedure;
    let (cpu, cpu_events, cpu_hook) = demo_on("cpu", 1.5, |_, _| {});
    let (gpu, gpu_events, gpu_hook) = demo_on("gpu", 1.5, |_, _| {});
    let adapter = gpu.scene.membrane().gpu_adapter();
    assert!(adapter.is_some(), "on the adapter there is (CI: lavapipe)");
    let reports = gpu.model_reports();
    assert_eq!(reports[1].gpu, adapter);
    assert_eq!(cpu.model_reports()[1].gpu, None);
    // The same physics in another order of float sums: the same cuts and events, and the
    // hook's force within a thousandth of its largest at every step.
    assert_eq!(gpu.metrics.correct_cuts, cpu.metrics.correct_cuts);
    assert!(
        cpu.metrics.correct_cuts > 0,
        "the demo cuts in its first 1.5 s"
    );
    let names = |e: &[SimEvent]| e.iter().map(|e| e.kind.name()).collect::<Vec<_>>();
    assert_eq!(names(&gpu_events), names(&cpu_events));
    let most = cpu_hook.iter().map(|f| f.length()).fold(0.0f32, f32::max);
    assert!(most > 0.0);
    for (k, (a, b)) in gpu_hook.iter().zip(&cpu_hook).enumerate() {
        assert!(
            (*a - *b).length() <= 1e-3 * most,
            "step {k}: {a} against {b}"
        );
    }
}

#[test]
fn on_the_gpu_a_nan_is_quarantined_and_a_lost_device_hands_over_to_the_cpu() {
    use crate::procedures::Procedure;
    // A NaN put into the membrane mid-session: caught, rolled back, reported; the membrane
    // stays on the device.
    let (r, events, _) = demo_on("gpu", 0.6, |r, step| {
        if step == 300 {
            assert!(r.models_mut().expect("a world").inject_nan(1));
        }
    });
    assert_eq!(of_kind(&events, "quarantined").len(), 1, "{events:?}");
    assert!(r.scene.membrane().gpu_adapter().is_some());
    // The device lost mid-session: the membrane goes on on the CPU from the same state, once
    // reported, and the session goes on.
    let (r, events, hook) = demo_on("gpu", 1.0, |r, step| {
        if step == 300 {
            assert!(r.scene.membrane_mut().inject_device_loss());
        }
    });
    let fell = of_kind(&events, "compute_fallback");
    assert_eq!(fell.len(), 1, "{events:?}");
    assert!(of_kind(&events, "quarantined").is_empty(), "{events:?}");
    assert!(r.scene.membrane().gpu_adapter().is_none());
    assert!(r.model_reports()[1].gpu.is_none());
    assert!(hook.iter().all(|f| f.is_finite()));
    let (cpu, _, cpu_hook) = demo_on("cpu", 1.0, |_, _| {});
    assert_eq!(r.metrics.correct_cuts, cpu.metrics.correct_cuts);
    let most = cpu_hook.iter().map(|f| f.length()).fold(0.0f32, f32::max);
    let last = (*hook.last().expect("steps") - *cpu_hook.last().expect("steps")).length();
    assert!(last <= 1e-3 * most.max(1e-6), "{last} N off");
}

#[test]
fn a_frame_announced_before_its_step_takes_no_round_trip_on_the_gpu() {
    use crate::procedures::Procedure;
    // The demo's first second on lavapipe with a snapshot every 10 steps, the step before
    // each told (as the session tells it) or not; told, the step gathers the drawn nodes of
    // the tiles it leaves lagging, or (`runs`) copies every run to the readback.
    let run = |told: bool, runs: bool| {
        let key = "procedure = \"rectum\"\ncompute = \"gpu\"";
        let mut r = rectum(coarse(|t| t.replacen("procedure = \"rectum\"", key, 1)));
        r.scene.membrane_mut().gpu_frames_copy_runs(runs);
        // The state bytes the frames' steps brought back.
        let mut frame_bytes = 0;
        let trace = crate::trace::KeyTrace::parse("demo", INFO.demo_trace).expect("demo trace");
        let mut clock =
            crate::sim::Clock::new(r.scenario.dt_s, crate::sim::Pacing::AsFastAsPossible);
        let (mut events, mut frames, mut trips, mut left_lagging) = (Vec::new(), Vec::new(), 0, 0);
        // Copies on the device for the frame: catch-ups and the frame's own reads.
        let catch_ups = |r: &Rectum| {
            let m = r.scene.membrane();
            Some(m.gpu_readback_counts()?.1 + m.gpu_frame_copies()?)
        };
        while clock.time_s() < 1.0 {
            let step = clock.step();
            let frame_after = step % 10 == 9;
            if told && frame_after {
                r.models_mut().expect("a world").read_whole_after_step();
            }
            r.step(&trace.sample(clock.time_s()), step, &mut events);
            if frame_after {
                frame_bytes += r.scene.membrane().gpu_last_readback_bytes().unwrap_or(0);
                let before = catch_ups(&r).expect("on the device");
                let s = r.snapshot(step);
                trips += catch_ups(&r).expect("on the device") - before;
                left_lagging += r.scene.membrane().gpu_tiles_behind().unwrap_or(0);
                frames.push(
                    s.models
                        .iter()
                        .map(|m| m.positions.clone())
                        .collect::<Vec<_>>(),
                );
            }
            clock.tick();
        }
        (frames, trips, left_lagging, frame_bytes)
    };
    let (told, told_trips, told_left, gathered_bytes) = run(true, false);
    let (runs, runs_trips, _, runs_bytes) = run(true, true);
    let (untold, untold_trips, untold_left, untold_bytes) = run(false, false);
    // Told, the frames' steps bring back the lagging tiles' drawn nodes beside what every
    // step brings back: fewer bytes than their whole runs, more than nothing.
    eprintln!(
        "frames' steps brought back {untold_bytes} B untold, {gathered_bytes} B told \
         (drawn nodes gathered), {runs_bytes} B told (runs copied)"
    );
    assert!(untold_bytes < gathered_bytes && gathered_bytes < runs_bytes);
    assert_eq!(runs_trips, 0);
    assert!(runs == told, "the frames differ");
    // Untold, a frame copies the runs of the tiles away from the instruments in round trips
    // of its own; told, the step before it left them in the readback. Either way the frame
    // reads only the nodes it draws and the tiles go on lagging. The frames are the same.
    eprintln!("round trips at the frames: {untold_trips} untold, {told_trips} told");
    assert!(untold_trips > 0, "no tile lagged at a frame");
    assert_eq!(told_trips, 0);
    assert!(
        told_left > 0 && untold_left == told_left,
        "{told_left} {untold_left}"
    );
    assert_eq!(told.len(), untold.len());
    for (k, (a, b)) in told.iter().zip(&untold).enumerate() {
        assert!(a == b, "frame {k}");
    }
}

#[test]
fn a_snapshot_built_on_another_thread_is_the_one_built_at_once() {
    // The hook cuts in the plane, so tiles are awake and asleep and links are cut: the job
    // reads the drawn vertices and the rod's pose now and builds the meshes later, on
    // another thread, into the very snapshot `snapshot` builds at once.
    let mut r = rectum(coarse(|s| s));
    let corner = in_plane(&r, 30, 2);
    let mut events = Vec::new();
    for step in 0..60 {
        r.step(&hook_at(corner, step >= 20), step, &mut events);
    }
    let now = r.snapshot(60);
    let job = r.snapshot_job(60);
    assert!(!job.is_ready(), "the meshes are left to the build");
    let later = std::thread::spawn(move || job.build())
        .join()
        .expect("built");
    assert_eq!(now.models.len(), 3);
    for m in &now.models {
        assert!(!m.positions.is_empty() && m.normals.len() == m.positions.len());
    }
    assert!(
        now.models[1].cut_edge.iter().any(|&c| c),
        "the hook cut links of the drawn plane"
    );
    assert_eq!(now, later);
}
