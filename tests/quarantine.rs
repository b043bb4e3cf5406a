//! The world's quarantine in every procedure (each steps its models through one): a NaN put
//! into each of its models mid-session is caught, the model rolled back to its last good
//! state and frozen, one `quarantined` event names it, and the session goes on with the
//! other models stepping and every figure finite.

use vesalius::registry::REGISTRY;
use vesalius::sim::{Clock, EventKind, Pacing, SimEvent};
use vesalius::trace::KeyTrace;

/// Simulated seconds before the NaN (at least a few checkpoints), and after it. A model that
/// holds no state the next step would meet (a contact model touching nothing) is tried
/// again every `RETRY_S` until `LATEST_S`.
const BEFORE_S: f64 = 0.05;
const AFTER_S: f64 = 0.1;
const RETRY_S: f64 = 0.05;
const LATEST_S: f64 = 6.0;

#[test]
fn a_nan_in_any_model_of_a_world_is_caught_rolled_back_and_the_session_goes_on() {
    let mut covered = Vec::new();
    for info in REGISTRY {
        let file = format!("builtin {} scenario", info.name);
        let probe = (info.build)(&file, info.scenario).expect("builds");
        let models = probe
            .models()
            .unwrap_or_else(|| panic!("{}: its models are in no world", info.name));
        let names: Vec<String> = models.model_reports().into_iter().map(|m| m.name).collect();
        drop(probe);
        let trace = KeyTrace::parse("demo", info.demo_trace).expect("the demo trace");
        for (k, name) in names.iter().enumerate() {
            let mut p = (info.build)(&file, info.scenario).expect("builds");
            let mut clock = Clock::new(p.dt_s(), Pacing::AsFastAsPossible);
            let mut events: Vec<SimEvent> = Vec::new();
            let run_until = |p: &mut Box<dyn vesalius::procedures::Procedure>,
                             clock: &mut Clock,
                             events: &mut Vec<SimEvent>,
                             t_s: f64| {
                while clock.time_s() < t_s {
                    p.step(&trace.sample(clock.time_s()), clock.step(), events);
                    clock.tick();
                }
            };
            run_until(&mut p, &mut clock, &mut events, BEFORE_S);
            assert!(
                !events
                    .iter()
                    .any(|e| matches!(e.kind, EventKind::Quarantined { .. })),
                "{}: quarantined before the NaN",
                info.name
            );
            let mut times_before = p.models().expect("a world").model_times();
            while !p.models_mut().expect("a world").inject_nan(k) {
                assert!(
                    clock.time_s() < LATEST_S,
                    "{}/{name}: never held a state to spoil",
                    info.name
                );
                let t = clock.time_s() + RETRY_S;
                run_until(&mut p, &mut clock, &mut events, t);
                times_before = p.models().expect("a world").model_times();
            }
            let t = clock.time_s() + AFTER_S;
            run_until(&mut p, &mut clock, &mut events, t);
            let quarantined: Vec<&EventKind> = events
                .iter()
                .map(|e| &e.kind)
                .filter(|e| matches!(e, EventKind::Quarantined { .. }))
                .collect();
            assert_eq!(
                quarantined.len(),
                1,
                "{}/{name}: {quarantined:?}",
                info.name
            );
            assert!(
                matches!(quarantined[0], EventKind::Quarantined { model, .. } if model == name),
                "{}/{name}: {quarantined:?}",
                info.name
            );
            // The session went on: every figure finite, the other models still stepping.
            let times_after = p.models().expect("a world").model_times();
            for (j, (a, b)) in times_before.iter().zip(&times_after).enumerate() {
                if j != k {
                    assert!(b > a, "{}: model {j} stopped stepping", info.name);
                }
            }
            let r = p.report();
            assert!(r.score.is_finite(), "{}/{name}", info.name);
            assert!(
                p.reactions().iter().all(|f| f.is_finite()),
                "{}/{name}",
                info.name
            );
            let snapshot = p.snapshot(clock.step());
            for m in &snapshot.models {
                assert!(
                    m.positions.iter().all(|x| x.is_finite()),
                    "{}/{name}: {} drawn with a NaN",
                    info.name,
                    m.name
                );
            }
        }
        covered.push(info.name);
    }
    assert_eq!(covered.len(), REGISTRY.len(), "{covered:?}");
}
