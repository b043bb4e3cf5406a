//! The sandbox's reference tests: its scenario, its block, the probe's push-back, the demo,
//! tuning and what renderers get.

use super::*;
use crate::procedures::Procedure;
use crate::sim::{Buttons, HandInput, Pose};
use crate::trace::KeyTrace;

fn scenario() -> Scenario {
    Scenario::parse("sandbox.toml", INFO.scenario).expect("the builtin scenario parses")
}

fn sandbox() -> Sandbox {
    Sandbox::new(scenario()).expect("the block builds")
}

/// Both instruments pointing straight down, at `probe` and `grasper`, the jaws at `grip`.
fn frame(probe: Vec3, grasper: Vec3, grip: f32) -> InputFrame {
    let down = |p: Vec3| Pose::looking_at(p, p - Vec3::Y * 0.05);
    InputFrame {
        hands: [
            HandInput {
                pose: down(grasper),
                buttons: Buttons {
                    grip,
                    ..Buttons::default()
                },
            },
            HandInput {
                pose: down(probe),
                buttons: Buttons::default(),
            },
        ],
    }
}

/// Well away from the block.
const AWAY_L: Vec3 = Vec3::new(-0.05, 0.08, 0.05);
const AWAY_R: Vec3 = Vec3::new(0.05, 0.08, 0.05);

/// Steps `s` through `n` copies of `f`, from step `from`; returns the events.
fn hold(s: &mut Sandbox, f: InputFrame, from: u64, n: u64) -> Vec<SimEvent> {
    let mut ev = Vec::new();
    for k in from..from + n {
        s.step(&f, k, &mut ev);
    }
    ev
}

/// The demo trace, read with the trace format's own parser (the registry test below checks
/// that `KeyTrace::parse` reads it the same).
fn demo_keys() -> KeyTrace {
    let file = xr_bindings::keyframes::KeyframeFile::parse(INFO.demo_trace)
        .map_err(|e| format!("{}: {}", e.key, e.message))
        .expect("the demo trace parses");
    KeyTrace {
        procedure: file.procedure,
        keys: [file.left, file.right],
        head: file.head,
        interpolation: file.interpolation,
        tremor: file.tremor,
    }
}

struct DemoRun {
    sandbox: Sandbox,
    events: Vec<SimEvent>,
    /// Largest distance of a bottom point from its rest over the run, m.
    bottom_moved_m: f32,
}

/// Plays the demo trace, plus half a second to settle.
fn run_demo() -> DemoRun {
    let keys = demo_keys();
    assert_eq!(keys.procedure, NAME);
    let mut s = sandbox();
    let dt = f64::from(s.scenario.dt_s);
    let steps = ((keys.duration_s() + 0.5) / dt).ceil() as u64;
    let mut events = Vec::new();
    let mut bottom_moved_m = 0.0f32;
    for k in 0..steps {
        s.step(&keys.sample(k as f64 * dt), k, &mut events);
        let b = s.body();
        for (i, x) in b.positions().iter().enumerate() {
            if b.regions()[i] == REGION_BOTTOM {
                bottom_moved_m = bottom_moved_m.max(x.distance(b.mesh().rest[i]));
            }
        }
    }
    DemoRun {
        sandbox: s,
        events,
        bottom_moved_m,
    }
}

/// Every key of every table names its own field.
#[test]
fn every_table_key_reads_and_writes_its_own_field() {
    let s = scenario();
    crate::params::assert_round_trip(&s.timing());
    crate::params::assert_round_trip(&s.geometry);
    crate::params::assert_round_trip(&s.tools);
    crate::params::assert_round_trip(&s.task);
}

#[test]
fn the_scenario_parses_and_a_bad_value_names_its_key() {
    let s = scenario();
    assert_eq!(s.procedure, "sandbox");
    assert_eq!(s.geometry.size_m, [0.06, 0.03, 0.04]);
    assert_eq!(s.cells(), [24, 14, 18]);
    assert_eq!(s.points(), 4172);
    let plan = (INFO.plan)("sandbox.toml", INFO.scenario).expect("plans");
    assert_eq!(
        (plan.dt_s, plan.publish_hz, plan.nodes),
        (0.002, 90.0, 4172)
    );
    for (from, to, key) in [
        (
            "procedure = \"sandbox\"",
            "procedure = \"nephrectomy\"",
            "procedure",
        ),
        ("dt_s = 0.002", "dt_s = 0.5", "dt_s"),
        (
            "[0.06, 0.03, 0.04]",
            "[0.06, nan, 0.04]",
            "geometry.size_m[1]",
        ),
        ("resolution = 24", "resolution = 1", "geometry.resolution"),
        ("resolution = 24", "resolution = 256", "geometry.resolution"),
        (
            "foundation_pa_per_m = 1.6e6",
            "foundation_pa_per_m = -1.0",
            "block.foundation_pa_per_m",
        ),
        (
            "solver_iterations = 1",
            "solver_iterations = 0",
            "block.solver_iterations",
        ),
        (
            "probe_tip_radius_m = 0.004",
            "probe_tip_radius_m = inf",
            "tools.probe_tip_radius_m",
        ),
        (
            "grip_threshold = 0.5",
            "grip_threshold = 1.5",
            "grasper.grip_threshold",
        ),
        // Deeper than half the block's 3 cm.
        (
            "probe_depth_m = 0.005",
            "probe_depth_m = 0.02",
            "task.probe_depth_m",
        ),
        (
            "lift_height_m = 0.01",
            "lift_height_m = 0.0",
            "task.lift_height_m",
        ),
    ] {
        assert!(INFO.scenario.contains(from), "{from}");
        let bad = INFO.scenario.replacen(from, to, 1);
        let e = Scenario::parse("bad.toml", &bad).expect_err(to);
        assert_eq!((e.file.as_str(), e.key.as_str()), ("bad.toml", key), "{e}");
    }
    // A range error says the range; a typo is refused, not ignored.
    let e = Scenario::parse(
        "bad.toml",
        &INFO.scenario.replacen("dt_s = 0.002", "dt_s = 0.5", 1),
    )
    .expect_err("dt");
    assert!(e.message.contains("0.0001 and 0.01"), "{e}");
    // The probe's depth: the table's range, then half the block's own height.
    let e = Scenario::parse(
        "bad.toml",
        &INFO
            .scenario
            .replacen("probe_depth_m = 0.005", "probe_depth_m = 0.02", 1),
    )
    .expect_err("deep");
    assert_eq!(e.message, "must be between 0.0005 and 0.015 m, got 0.02");
    let typo = INFO.scenario.replacen("grip_threshold", "grip_treshold", 1);
    let e = Scenario::parse("bad.toml", &typo).expect_err("typo");
    assert!(e.message.contains("grip_treshold"), "{e}");
}

#[test]
fn the_block_is_closed_outward_and_evenly_divided() {
    let s = scenario();
    let shape = BlockShape {
        size_m: Vec3::from(s.geometry.size_m),
    };
    let (mesh, regions) = block(&shape, s.cells());
    assert_eq!(mesh.triangle_count() as u64, s.points());
    assert_eq!(regions.len(), mesh.triangle_count());
    // Every edge is shared by exactly two triangles (this fails otherwise), and the dual
    // builds.
    mesh.edge_adjacency().expect("closed 2-manifold");
    let dual = SimplexMesh::dual(&mesh).expect("dual");
    assert_eq!(dual.len(), mesh.triangle_count());
    // Outward: the enclosed volume is the box's, and every face turns away from the centre.
    let volume = 0.06 * 0.03 * 0.04;
    assert!(
        (mesh.volume() - volume).abs() < 1e-3 * volume,
        "{}",
        mesh.volume()
    );
    let area = (0..mesh.triangle_count())
        .map(|f| mesh.triangle_area(f))
        .fold(0.0, f32::max);
    for (f, t) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let normal = (b - a).cross(c - a).normalize();
        let centroid = (a + b + c) / 3.0;
        assert!(
            normal.dot(centroid - shape.centre()) > 0.0,
            "face {f} faces in"
        );
        // Whole triangles (the sides' a little smaller than the top's), or the half ones
        // that end the shifted rows.
        let a = mesh.triangle_area(f);
        assert!(a > 0.4 * area, "face {f}: {a} vs {area}");
        // Regions: the top faces up, the bottom down, the sides sideways.
        let want = match (normal.y > 0.9, normal.y < -0.9) {
            (true, _) => REGION_TOP,
            (_, true) => REGION_BOTTOM,
            _ => REGION_SIDES,
        };
        assert_eq!(regions[f], want, "face {f}");
    }
    let top = regions.iter().filter(|&&r| r == REGION_TOP).count();
    // Rows of 2 x 24 + 1 triangles, 18 rows.
    assert_eq!(top, 18 * 49);
}

/// Steps a probe whose ball reaches `depth_m` into the top centre: it comes down over 0.1 s,
/// is held 0.5 s, then 1 s more while `each` sees every step.
fn hold_probe(depth_m: f32, mut each: impl FnMut(&Sandbox)) -> Sandbox {
    let mut s = sandbox();
    let r = s.scenario.tools.probe_tip_radius_m;
    let tip = Vec3::new(0.0, s.shape().top_y() + r - depth_m, 0.0);
    let mut ev = Vec::new();
    for k in 0..50u64 {
        let above = tip + Vec3::Y * (0.005 * (1.0 - k as f32 / 50.0));
        s.step(&frame(above, AWAY_L, 0.0), k, &mut ev);
    }
    hold(&mut s, frame(tip, AWAY_L, 0.0), 50, 250);
    for k in 300..800u64 {
        s.step(&frame(tip, AWAY_L, 0.0), k, &mut ev);
        each(&s);
    }
    s
}

/// The reference the sandbox is for: a ball held at a depth in a flat top. What the probe
/// feels is the sum of what the tissue does to the points it holds, so at rest it equals the
/// load the whole block bears (its foundation and gas pressure, summed over every point from
/// the positions alone): Newton's third law and statics.
#[test]
fn a_held_probe_pushes_back_up_harder_deeper_and_not_at_all_above() {
    hold_probe(-0.0005, |s| {
        assert_eq!(s.reactions()[1], Vec3::ZERO);
        assert_eq!(s.probe_depth_m(), 0.0);
    });
    let mut last = 0.0;
    for depth in [0.001, 0.003, 0.006] {
        let mut reaction = Vec3::ZERO;
        let s = hold_probe(depth, |s| reaction = s.reactions()[1]);
        assert!(
            (s.probe_depth_m() - depth).abs() < 1e-6,
            "{}",
            s.probe_depth_m()
        );
        // Up, nearly straight up on a flat top, and more the deeper.
        assert!(reaction.y > last, "{depth} m: {reaction} after {last} N");
        assert!(
            reaction.x.hypot(reaction.z) < 0.05 * reaction.y,
            "{reaction}"
        );
        // Within 3%: the gas pressure's share on the sleeping part of the block is borne
        // there (the verify case `tip_reaction_balance` holds 1% on a body kept awake).
        let load = crate::verify::softbody_contact_cases::body_load_n(s.body());
        assert!(
            (reaction.as_dvec3() - load).length() < 0.03 * load.length(),
            "{depth} m: reaction {reaction} vs the block's load {load}"
        );
        eprintln!("probe {:.0} mm deep: mean {reaction} N", depth * 1e3);
        last = reaction.y;
    }
}

#[test]
fn the_demo_completes_its_steps_in_order_and_replays_bit_for_bit() {
    let run = run_demo();
    let s = &run.sandbox;
    let names: Vec<&str> = STEPS.iter().map(|t| t.id).collect();
    assert!(s.is_completed(), "{:?}", s.metrics);
    assert_eq!(s.metrics.steps_done, names);
    let raised: Vec<(u64, &str)> = run
        .events
        .iter()
        .filter_map(|e| match &e.kind {
            EventKind::TaskStep { name } => Some((e.step, name.as_str())),
            _ => None,
        })
        .collect();
    assert_eq!(raised.iter().map(|r| r.1).collect::<Vec<_>>(), names);
    for (step, name) in &raised {
        eprintln!("{name} at {:.3} s", *step as f64 * 0.002);
    }
    // Contact, grasp and release are raised where they happen, and nothing went wrong.
    let kinds: Vec<&str> = run.events.iter().map(|e| e.kind.name()).collect();
    for want in ["contact", "grasp", "release"] {
        assert!(kinds.contains(&want), "{kinds:?}");
    }
    assert!(!kinds.contains(&"quarantined"), "{kinds:?}");
    let m = &s.metrics;
    assert!(
        m.max_probe_depth_m >= s.scenario.task.probe_depth_m,
        "{m:?}"
    );
    assert!(m.lift_height_m >= s.scenario.task.lift_height_m, "{m:?}");
    assert!(
        m.max_probe_force_n > 0.0 && m.max_grasper_force_n > 0.0,
        "{m:?}"
    );
    assert_eq!(m.grasper_overloads, 0, "{m:?}");
    // The bottom stays on the table: its rest springs hold it to well under a millimetre.
    assert!(run.bottom_moved_m < 5e-4, "{} m", run.bottom_moved_m);
    eprintln!("bottom moved at most {:e} m", run.bottom_moved_m);
    // The score: 70 for the steps, 30 x target time / time taken.
    let t = m.completion_time_s.expect("completed");
    let want = 70.0 + 30.0 * (10.0 / t).min(1.0) as f32;
    let report = Procedure::report(s);
    assert!(
        (report.score - want).abs() < 1e-3,
        "{} vs {want}",
        report.score
    );
    assert_eq!(
        report.metrics["steps_done"].as_array().map(Vec::len),
        Some(4)
    );
    eprintln!("demo: {m:?}, score {}", report.score);
    // Determinism: the same trace gives the same state.
    assert_eq!(s.state_hash(), run_demo().sandbox.state_hash());
}

#[test]
fn steps_done_out_of_order_wait_for_the_ones_before() {
    let mut s = sandbox();
    let top = s.shape().top_y();
    let at = Vec3::new(-0.0175, top + 0.002, 0.01);
    // Grasp and lift first: neither counts, nothing has been touched.
    let mut ev = hold(&mut s, frame(AWAY_R, at, 1.0), 0, 20);
    ev.extend(hold(
        &mut s,
        frame(AWAY_R, at + Vec3::Y * 0.012, 1.0),
        20,
        100,
    ));
    ev.extend(hold(&mut s, frame(AWAY_R, AWAY_L, 0.0), 120, 100));
    assert!(s.metrics.steps_done.is_empty(), "{:?}", s.metrics);
    assert!(s.metrics.lift_height_m > 0.01, "{:?}", s.metrics);
    // Probing does touch and press, in order, in one step if it must.
    let deep = Vec3::new(0.0, top + 0.004 - 0.006, 0.0);
    hold(&mut s, frame(deep, AWAY_L, 0.0), 220, 1);
    assert_eq!(s.metrics.steps_done, ["touch", "press"]);
    // Now the grasp counts, and the lift once let go.
    hold(&mut s, frame(AWAY_R, at, 1.0), 221, 20);
    assert_eq!(s.metrics.steps_done, ["touch", "press", "grasp"]);
    hold(&mut s, frame(AWAY_R, at + Vec3::Y * 0.012, 1.0), 241, 100);
    assert!(!s.is_completed());
    hold(&mut s, frame(AWAY_R, AWAY_L, 0.0), 341, 1);
    assert!(s.is_completed());
    let t = s.metrics.completion_time_s.expect("completed");
    assert!((t - 342.0 * 0.002).abs() < 1e-6, "{t}");
}

#[test]
fn tune_refuses_a_bad_value_and_changes_nothing() {
    let mut s = sandbox();
    let before = s.tunables();
    assert_eq!(before.len(), 3);
    assert!(before.iter().all(|t| t.model == "block"));
    let params = s.body().params;
    for (model, values, says) in [
        (
            "block",
            vec![
                ("foundation_pa_per_m".to_string(), 2e6),
                ("damping_per_s".to_string(), 1e6),
            ],
            "block.damping_per_s",
        ),
        (
            "block",
            vec![("offset_m".to_string(), f32::NAN)],
            "block.offset_m",
        ),
        (
            "block",
            vec![("falloff_m".to_string(), 0.01)],
            "block.falloff_m",
        ),
        (
            "kidney",
            vec![("foundation_pa_per_m".to_string(), 50.0)],
            "kidney",
        ),
    ] {
        let e = s.tune(model, &values).expect_err(says).to_string();
        assert!(e.contains(says), "{e}");
        assert_eq!(s.tunables(), before);
        assert_eq!(s.body().params, params);
    }
    s.tune("block", &[("foundation_pa_per_m".to_string(), 2e6)])
        .expect("in range");
    assert_eq!(s.body().params.foundation_pa_per_m, 2e6);
    assert_eq!(s.scenario.block.foundation_pa_per_m, 2e6);
    assert_eq!(s.tunables()[0].value, 2e6);
}

#[test]
fn the_snapshot_gives_each_region_its_role() {
    let mut s = sandbox();
    let snap = s.snapshot(0);
    assert_eq!(snap.models.len(), 1);
    let m = &snap.models[0];
    assert_eq!(m.name, "block");
    assert_eq!(
        m.roles,
        [
            SurfaceRole::Tissue,
            SurfaceRole::Target,
            SurfaceRole::Tissue
        ]
    );
    assert_eq!(m.regions.len() * 3, m.indices.len());
    let top = s.shape().top_y();
    for (t, &region) in m.regions.iter().enumerate() {
        assert!((region as usize) < m.roles.len());
        let on_top = m.indices[3 * t..3 * t + 3]
            .iter()
            .all(|&v| (m.positions[v as usize].y - top).abs() < 1e-6);
        assert_eq!(
            m.roles[region as usize] == SurfaceRole::Target,
            on_top,
            "{t}"
        );
    }
    let report = Procedure::model_reports(&s);
    assert_eq!(report.len(), 1);
    assert_eq!(report[0].triangles as u64, s.scenario.points());
}

/// The registry plans, builds and plays the sandbox, and the window's save-back writes its
/// table.
#[test]
fn a_catalog_builds_plans_and_plays_the_sandbox() {
    let keys = KeyTrace::parse("sandbox-demo.toml", INFO.demo_trace).expect("trace");
    assert_eq!(keys, demo_keys());
    let own = crate::sim::Catalog(&[&INFO]);
    let (info, plan) = own.plan("sandbox.toml", INFO.scenario).expect("plan");
    assert_eq!((info.name, plan.nodes), (NAME, 4172));
    let mut p = own.build("sandbox.toml", INFO.scenario).expect("build");
    let mut ev = Vec::new();
    p.step(&keys.sample(0.0), 0, &mut ev);
    let tuned = crate::scenario::with_tunables(
        &|text| own.plan("sandbox.toml", text).map(|_| ()),
        "sandbox.toml",
        INFO.scenario,
        p.tunables()
            .iter()
            .map(|t| (t.model.as_str(), t.key, t.value)),
    )
    .expect("the window's save-back writes [block]");
    assert_eq!(
        Scenario::parse("tuned.toml", &tuned).expect("parses"),
        scenario()
    );
}

#[test]
fn a_scenario_from_before_the_grasper_table_reads_the_same() {
    // Files (and recordings, which embed them) from before `[grasper]` held its keys in
    // `[tools]`, the tip's radius as `grasper_tip_radius_m`.
    let new = "\n\n[grasper]\ntip_radius_m";
    assert!(INFO.scenario.contains(new));
    let old = INFO.scenario.replacen(new, "\ngrasper_tip_radius_m", 1);
    let now = Scenario::parse("new.toml", INFO.scenario).expect("valid");
    assert_eq!(Scenario::parse("old.toml", &old).expect("still read"), now);
    // Moved keys are still checked, and named where they are now.
    let bad = old.replacen("grip_threshold = 0.5", "grip_threshold = 1.5", 1);
    let e = Scenario::parse("old.toml", &bad).expect_err("out of range");
    assert_eq!(e.key, "grasper.grip_threshold", "{e}");
    // Both at once: the old place's key is not moved over the new one, and is refused.
    let both = INFO
        .scenario
        .replacen("[tools]\n", "[tools]\ngrasp_radius_m = 0.003\n", 1);
    let e = Scenario::parse("both.toml", &both).expect_err("a key twice");
    assert!(e.message.contains("grasp_radius_m"), "{e}");
}
