use super::*;
use crate::procedures::catheter::{INFO, Scenario, build_procedure};
use crate::trace::KeyTrace;

/// The builtin scenario's wire holds the table's defaults; without the table the catheter
/// goes in alone; a bad value and a tip longer than the wire are named with the file and
/// the key; the wire's contact law is the wall's scaled by its width.
#[test]
fn the_guidewire_table_is_optional_checked_and_scaled() {
    let s = Scenario::parse("builtin", INFO.scenario).expect("the builtin scenario");
    let w = s.guidewire.expect("the builtin has a wire");
    for spec in GuidewireTable::SPECS {
        assert_eq!(w.get(spec.key), Some(spec.default), "{}", spec.key);
    }
    let cut = INFO.scenario.find("[guidewire]").expect("the table");
    let alone = Scenario::parse("alone.toml", &INFO.scenario[..cut]).expect("parses");
    assert_eq!(alone.guidewire, None);
    let mut p = build_procedure(alone);
    assert!(p.scene.guidewire().is_none());
    assert_eq!(
        p.wire_drive(&crate::sim::InputFrame::default()),
        Default::default()
    );
    for (from, to, key) in [
        (
            "diameter_m = 0.0009",
            "diameter_m = 0.004",
            "guidewire.diameter_m",
        ),
        (
            "tip_length_m = 0.020",
            "tip_length_m = 0.2",
            "guidewire.tip_length_m",
        ),
    ] {
        let e =
            Scenario::parse("wire.toml", &INFO.scenario.replace(from, to)).expect_err("refused");
        let said = e.to_string();
        assert!(said.contains("wire.toml") && said.contains(key), "{said}");
    }
    // 0.9 mm over the catheter's 10 mm: 9 % of the stiffness, damping and puncture force;
    // no preload; the wire's own friction.
    let (law, puncture) = w.law(&s.law(), s.contact.puncture_n, s.catheter.diameter_m);
    assert!((law.stiffness_n_per_m - 45.0).abs() < 1e-9, "{law:?}");
    assert!((law.damping_n_s_per_m - 0.027).abs() < 1e-12, "{law:?}");
    assert_eq!(law.preload_n, 0.0);
    assert!((puncture - 0.27).abs() < 1e-12, "{puncture}");
    assert_eq!(law.friction, w.friction);
}

/// The demo to 4.6 s: the left hand's travel feeds the wire out of the catheter and its
/// wrist's half turn points the angled tip at the -y branch, which the wire enters 30 mm and
/// more, ahead of the catheter, without a wrong branch or a puncture. The same hand unrolled
/// points the tip at +y: the wire goes into the other branch.
#[test]
fn the_wrist_roll_turns_the_wire_into_its_branch() {
    let run = |trace: &str| {
        let s = Scenario::parse("builtin", INFO.scenario).expect("the builtin scenario");
        let t = KeyTrace::parse("demo", trace).expect("the demo trace");
        let mut p = build_procedure(s);
        let mut events = Vec::new();
        for k in 0..4600u64 {
            p.step(&t.sample(k as f64 * 0.001), k, &mut events);
        }
        p.metrics.guidewire.expect("a wire")
    };
    let w = run(INFO.demo_trace);
    assert!(w.reach_m >= 0.03, "{w:?}");
    assert!(w.lead_m >= 0.05, "{w:?}");
    assert_eq!((w.wrong_branch, w.punctures), (0, 0), "{w:?}");
    assert!(w.peak_force_n > 0.0, "{w:?}");
    let unrolled: String = INFO
        .demo_trace
        .lines()
        .filter(|l| !l.starts_with("roll_deg"))
        .map(|l| format!("{l}\n"))
        .collect();
    let w = run(&unrolled);
    assert!(w.wrong_branch >= 1, "{w:?}");
    assert_eq!(w.reach_m, 0.0, "{w:?}");
}
