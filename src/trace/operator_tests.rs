use super::*;
use crate::assess::motion::MotionRecorder;

/// A plan: the right hand reaches 5 cm forward in 0.5 s and closes (trigger) there for
/// 0.3 s, then goes back; the left closes its grip at 0.2 s and opens it at 1.5 s.
const PLAN: &str = "procedure = \"sandbox\"
[[left]]
t_s = 0.0
position = [-0.05, 0.0, 0.0]
target = [-0.05, 0.0, -0.1]
[[left]]
t_s = 0.2
position = [-0.05, 0.0, 0.0]
target = [-0.05, 0.0, -0.1]
grip = 1.0
[[left]]
t_s = 1.5
position = [-0.05, 0.0, 0.0]
target = [-0.05, 0.0, -0.1]
grip = 1.0
[[left]]
t_s = 1.6
position = [-0.05, 0.0, 0.0]
target = [-0.05, 0.0, -0.1]
[[right]]
t_s = 0.0
position = [0.05, 0.0, 0.0]
target = [0.05, 0.0, -0.1]
[[right]]
t_s = 0.5
position = [0.05, 0.0, -0.05]
target = [0.05, 0.0, -0.15]
[[right]]
t_s = 0.55
position = [0.05, 0.0, -0.05]
target = [0.05, 0.0, -0.15]
trigger = 1.0
[[right]]
t_s = 0.85
position = [0.05, 0.0, -0.05]
target = [0.05, 0.0, -0.15]
trigger = 1.0
[[right]]
t_s = 0.9
position = [0.05, 0.0, -0.05]
target = [0.05, 0.0, -0.15]
[[right]]
t_s = 1.4
position = [0.05, 0.0, 0.0]
target = [0.05, 0.0, -0.1]
";

fn plan() -> KeyTrace {
    KeyTrace::parse("plan.toml", PLAN).expect("plan")
}

/// The performance's trace as the players read it.
fn played(p: &Performance) -> KeyTrace {
    KeyTrace::parse("performed.toml", &p.toml("test")).expect("the written trace parses")
}

/// Where the right hand is when its trigger first closes (> 0.5), and when.
fn right_acts(t: &KeyTrace) -> (f64, Vec3) {
    let mut time = 0.0;
    while time < t.duration_s() {
        let f = t.sample(time);
        if f.hands[1].buttons.trigger > 0.5 {
            return (time, f.hands[1].pose.position);
        }
        time += 0.001;
    }
    panic!("the right hand never acted");
}

#[test]
fn a_seed_gives_the_same_session_and_another_seed_another() {
    let (a, b, c) = (
        perform(&plan(), &NOVICE, 7),
        perform(&plan(), &NOVICE, 7),
        perform(&plan(), &NOVICE, 8),
    );
    assert_eq!(a.toml("x"), b.toml("x"));
    assert_ne!(a.toml("x"), c.toml("x"));
}

#[test]
fn an_expert_acts_on_the_target_at_the_plans_pace() {
    let goal = Vec3::new(0.05, 0.0, -0.05);
    for seed in 0..10 {
        let p = perform(&plan(), &EXPERT, seed);
        let t = played(&p);
        let (when, at) = right_acts(&t);
        // Settled within 0.3 mm; its tremor (two sinusoids of at most 0.08 / sqrt 2 mm an
        // axis) adds at most 0.2 mm.
        assert!(
            at.distance(goal) < 0.0003 + 0.0002,
            "seed {seed}: {} mm off",
            at.distance(goal) * 1e3
        );
        // The plan's 0.55 s, at 0.9-1.15 of its pace, plus a pause of at most 0.12 s and the
        // corrections.
        assert!(when > 0.4 && when < 1.4, "seed {seed}: acted at {when} s");
        // Two reaches, each with a pause of at most 0.12 s and corrections of 0.15-0.3 s.
        assert!(
            p.duration_s() < 1.6 * 1.15 + 2.0 * (0.12 + 0.6),
            "{}",
            p.duration_s()
        );
    }
}

#[test]
fn the_hands_keep_the_plans_order_of_actions() {
    // The left's grip closes before the right acts and opens after the right has let go.
    for (who, seed) in [(&EXPERT, 1), (&NOVICE, 2), (&NOVICE, 3)] {
        let t = played(&perform(&plan(), who, seed));
        let first = |f: &dyn Fn(&crate::sim::InputFrame) -> bool| {
            let mut time = 0.0;
            while time <= t.duration_s() {
                if f(&t.sample(time)) {
                    return time;
                }
                time += 0.001;
            }
            f64::INFINITY
        };
        let grip_on = first(&|f| f.hands[0].buttons.grip > 0.5);
        let (right_on, _) = right_acts(&t);
        let right_off = first(&|f: &crate::sim::InputFrame| {
            f.hands[1].buttons.trigger < 0.5
                && f.hands[1].pose.position.z < -0.03
                && f.hands[0].buttons.grip > 0.5
        });
        let grip_off = {
            let mut time = right_on;
            while time <= t.duration_s() && t.sample(time).hands[0].buttons.grip > 0.5 {
                time += 0.001;
            }
            time
        };
        assert!(
            grip_on < right_on,
            "{} {seed}: {grip_on} {right_on}",
            who.name
        );
        assert!(
            right_on < grip_off && right_off < grip_off,
            "{} {seed}",
            who.name
        );
    }
}

/// The motion analysis of a trace played at 1 ms steps.
fn motion_of(t: &KeyTrace) -> crate::assess::motion::Motion {
    let mut r = MotionRecorder::new();
    let steps = (t.duration_s() / 0.001).ceil() as usize;
    for k in 1..=steps {
        let time = k as f64 * 0.001;
        let f = t.sample(time);
        let b = |h: usize| f.hands[h].buttons.trigger > 0.5 || f.hands[h].buttons.grip > 0.5;
        r.record(
            time,
            [f.hands[0].pose.position, f.hands[1].pose.position],
            [b(0), b(1)],
        );
    }
    r.analyse()
}

#[test]
fn a_novice_is_slower_travels_further_and_moves_less_smoothly() {
    let (mut e, mut n) = (Vec::new(), Vec::new());
    for seed in 0..5 {
        e.push(motion_of(&played(&perform(&plan(), &EXPERT, seed))));
        n.push(motion_of(&played(&perform(&plan(), &NOVICE, 100 + seed))));
    }
    let worst_expert = |f: &dyn Fn(&crate::assess::motion::Motion) -> f64| {
        e.iter().map(f).fold(f64::MIN, f64::max)
    };
    let best_novice = |f: &dyn Fn(&crate::assess::motion::Motion) -> f64| {
        n.iter().map(f).fold(f64::MAX, f64::min)
    };
    assert!(best_novice(&|m| m.duration_s) > worst_expert(&|m| m.duration_s));
    assert!(best_novice(&|m| m.path_m) > worst_expert(&|m| m.path_m));
    assert!(
        best_novice(&|m| -m.ldlj.unwrap_or(0.0)) > worst_expert(&|m| -m.ldlj.unwrap_or(0.0)),
        "{:?} {:?}",
        e.iter().map(|m| m.ldlj).collect::<Vec<_>>(),
        n.iter().map(|m| m.ldlj).collect::<Vec<_>>()
    );
}
