use crate::procedures::catheter::{INFO, Scenario, build_procedure, build_scene};
use glam::DVec3;

/// The shipped `[tree]` is the paper's bifurcation: the same tubes as `[vessel]`'s lengths
/// and angle give (within the points' 1e-7 m), the same number of wall balls, the target
/// named `left` where `task.branch` says 2; its wall is weaker only where the vessels meet.
#[test]
fn the_shipped_tree_is_the_papers_bifurcation_with_weaker_ostia() {
    let s = Scenario::parse("builtin", INFO.scenario).expect("the builtin scenario");
    let tree = s.tree.as_ref().expect("the builtin has a tree");
    let (tubes, branches) = s.vessel_shape();
    let (paper, paper_branches) = s.vessel_params().bifurcation();
    assert_eq!(tubes.len(), paper.len());
    for (a, b) in tubes.iter().zip(&paper) {
        assert!(a.start.distance(b.start) < 1e-7, "{a:?} {b:?}");
        assert!(a.dir.distance(b.dir) < 1e-6, "{a:?} {b:?}");
        assert!((a.length_m - b.length_m).abs() < 1e-7, "{a:?} {b:?}");
        assert_eq!((a.parent, a.vessel), (b.parent, b.vessel));
    }
    let names: Vec<&str> = branches.iter().map(|b| b.name.as_str()).collect();
    let paper_names: Vec<&str> = paper_branches.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(names, paper_names);
    assert_eq!(tree.target, "left");
    assert_eq!(s.target_branch(), s.task.branch as usize);
    let scene = build_scene(&s);
    let v = scene.vessel();
    let paper_vessel = crate::models::skeleton::vessel::Vessel::new(&s.vessel_params());
    assert_eq!(v.balls.len(), paper_vessel.balls.len());
    // Weaker within 4 mm of where the vessels' walls meet: around the junction at 60 mm,
    // not along the trunk's first 40 mm nor the branches' last 30 mm.
    let weak: Vec<DVec3> = v
        .strength
        .iter()
        .zip(&v.rest)
        .filter(|(s, _)| **s < 1.0)
        .map(|(_, x)| *x)
        .collect();
    assert!(
        weak.len() > 16 && weak.len() < v.balls.len() / 4,
        "{}",
        weak.len()
    );
    assert!(
        v.strength
            .iter()
            .all(|&s| s == 1.0 || s == tree.ostium_strength)
    );
    for x in &weak {
        let from_junction = x.distance(DVec3::new(0.06, 0.0, 0.0));
        assert!(x.x > 0.04 && from_junction < 0.03, "{x}");
    }
    // The carina (between the branches, on the x axis past the junction) is weak.
    assert!(
        weak.iter().any(|x| x.y.abs() < 0.003 && x.x > 0.065),
        "{weak:?}"
    );
}

/// A bad tree is refused with the file and the key: a target that is not there, a parent
/// that is not listed before, a branch too narrow for the catheter on its way to the
/// target, a start outside the parent's lumen, a sharp turn, a root off the entry, a reach
/// past the target's end.
#[test]
fn a_bad_tree_is_named() {
    let left = "points_m = [[0.060, 0.0, 0.0], [0.1119615, -0.030, 0.0]]";
    let cases = [
        ("target = \"left\"", "target = \"aorta\"", "tree.target"),
        (
            "parent = \"trunk\"",
            "parent = \"left\"",
            "tree.vessel[1].parent",
        ),
        (
            "name = \"left\"\nparent = \"trunk\"\ndiameter_m = 0.020",
            "name = \"left\"\nparent = \"trunk\"\ndiameter_m = 0.012",
            "tree.vessel[2].diameter_m",
        ),
        (
            left,
            "points_m = [[0.060, -0.012, 0.0], [0.1119615, -0.030, 0.0]]",
            "tree.vessel[2].points_m[0]",
        ),
        (
            left,
            "points_m = [[0.060, 0.0, 0.0], [0.1, -0.02, 0.0], [0.1, 0.02, 0.0]]",
            "tree.vessel[2].points_m[1]",
        ),
        (
            "points_m = [[0.0, 0.0, 0.0], [0.060, 0.0, 0.0]]",
            "points_m = [[0.0, 0.0, 0.0], [0.060, 0.01, 0.0]]",
            "tree.vessel[0].points_m",
        ),
        ("reach_m = 0.030", "reach_m = 0.070", "task.reach_m"),
        (
            "head = [1.0, 0.0, 0.0]",
            "head = [0.0, 0.0, 1.0]",
            "tree.head",
        ),
    ];
    for (from, to, key) in cases {
        assert!(INFO.scenario.contains(from), "{from}");
        let text = INFO.scenario.replacen(from, to, 1);
        let e = Scenario::parse("tree.toml", &text).expect_err(key);
        let said = e.to_string();
        assert!(
            said.contains("tree.toml") && said.contains(key),
            "{key}: {said}"
        );
    }
}

/// Without a `[tree]` the vessel is the paper's bifurcation from `[vessel]`, the target
/// `task.branch`; the demo still completes into that branch.
#[test]
fn without_a_tree_the_bifurcation_comes_from_the_vessel_table() {
    let start = INFO.scenario.find("\n[tree]\n").expect("the tree");
    let end = INFO.scenario.find("# The fluoroscope").expect("after it");
    let text = format!("{}{}", &INFO.scenario[..start], &INFO.scenario[end..]);
    let s = Scenario::parse("paper.toml", &text).expect("parses");
    assert!(s.tree.is_none());
    assert_eq!(s.target_branch(), 2);
    let p = build_procedure(s.clone());
    assert!(p.scene.vessel().strength.iter().all(|&x| x == 1.0));
    let long = text.replace("branch_m = 0.060", "branch_m = 0.020");
    let e = Scenario::parse("paper.toml", &long).expect_err("reach past the branch");
    assert!(e.to_string().contains("task.reach_m"), "{e}");
}

const AORTA: &str = include_str!("../../../assets/examples/catheter-abdominal-aorta.toml");
const AORTA_TRACE: &str =
    include_str!("../../../assets/examples/catheter-abdominal-aorta-trace.toml");

/// The abdominal aorta example: the aorta cut where each renal leaves it; blood shared at
/// each branching by the lumens' cubes (Murray's law), none made or lost; the task's
/// target named `left_renal`.
#[test]
fn the_aorta_example_shares_its_flow_by_murrays_law() {
    let s = Scenario::parse("aorta.toml", AORTA).expect("the example");
    assert_eq!(s.target_branch(), 1);
    let p = build_procedure(s);
    let v = p.scene.vessel();
    let names: Vec<&str> = v.branches.iter().map(|b| b.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "aorta",
            "left_renal",
            "right_renal",
            "left_iliac",
            "right_iliac"
        ]
    );
    // The aorta in three (0-35, 35-40, 40-110 mm), each renal in two, each iliac in one.
    assert_eq!(v.tubes.len(), 9);
    let q = 10e-6;
    let flows = super::super::fluoroscopy::tube_flows(v, q);
    assert!((flows[0] - q).abs() < 1e-18);
    for (k, t) in v.tubes.iter().enumerate() {
        let children: Vec<usize> = (0..v.tubes.len())
            .filter(|&c| v.tubes[c].parent == Some(k))
            .collect();
        if children.is_empty() {
            continue;
        }
        let sum: f64 = children.iter().map(|&c| flows[c]).sum();
        assert!(
            (sum - flows[k]).abs() < 1e-12 * q,
            "tube {k}: {sum} vs {}",
            flows[k]
        );
        for pair in children.windows(2) {
            let (a, b) = (&v.tubes[pair[0]], &v.tubes[pair[1]]);
            let want = (a.lumen_m / b.lumen_m).powi(3);
            let got = flows[pair[0]] / flows[pair[1]];
            assert!((got / want - 1.0).abs() < 1e-12, "{t:?}: {got} vs {want}");
        }
    }
    // A renal takes (3.5 / 8.5)^3 of the aorta's flow against the aorta's own.
    let renal = v.tubes.iter().position(|t| t.vessel == 1).unwrap_or(0);
    let ratio = flows[renal] / flows[v.tubes[renal].parent.unwrap_or(0)];
    let (r, a) = (0.0035f64, 0.0085f64);
    assert!(
        (ratio - r.powi(3) / (r.powi(3) + a.powi(3))).abs() < 1e-12,
        "{ratio}"
    );
}

/// The example's trace: the catheter's curve, untwisted, points the wire into the left
/// renal (its target, 10 mm and more in, no wrong branch, no puncture) and the catheter
/// pushed over it follows and completes the task; twisted half a turn with the wire rolled
/// the same, they go into the right renal, and the wrong branch is named.
#[test]
fn the_aorta_examples_wire_goes_where_the_curve_points() {
    let run = |trace: &str| {
        let s = Scenario::parse("aorta.toml", AORTA).expect("the example");
        let t = crate::trace::KeyTrace::parse("aorta-trace.toml", trace).expect("the trace");
        let mut p = build_procedure(s);
        let mut events = Vec::new();
        for k in 0..9500u64 {
            p.step(&t.sample(k as f64 * 0.001), k, &mut events);
        }
        let wrong: Vec<String> = events
            .iter()
            .filter_map(|e| match &e.kind {
                crate::sim::EventKind::Procedure(p) if p.name == "wrong_branch" => {
                    Some(p.fields.get("vessel")?.as_str()?.to_string())
                }
                _ => None,
            })
            .collect();
        (p.metrics, wrong)
    };
    let (m, wrong) = run(AORTA_TRACE);
    let w = m.guidewire.expect("a wire");
    assert!(w.reach_m >= 0.010, "{w:?}");
    assert_eq!(
        (w.wrong_branch, m.wrong_branch, m.punctures),
        (0, 0, 0),
        "{wrong:?}"
    );
    assert!(m.reach_m >= 0.020 && m.completion_time_s.is_some(), "{m:?}");
    let cut = AORTA_TRACE.find("[[left]]").unwrap_or(0);
    let (right, left) = AORTA_TRACE.split_at(cut);
    let twisted = format!(
        "{}{}",
        right.replace("grip = 0.0", "grip = 1.0"),
        left.replace("roll_deg = 0.0", "roll_deg = 180.0")
    );
    let (m, wrong) = run(&twisted);
    let w = m.guidewire.expect("a wire");
    assert!(
        w.wrong_branch >= 1 && w.reach_m == 0.0 && m.reach_m == 0.0,
        "{m:?}"
    );
    assert!(
        !wrong.is_empty() && wrong.iter().all(|v| v == "right_renal"),
        "{wrong:?}"
    );
}
