//! Criterion benchmark of the full-size nephrectomy step (53k triangles, dt 2 ms) while the
//! laser cuts around the tumour, the phase of the demo that keeps the most points awake.

use criterion::{Criterion, criterion_group, criterion_main};
use vesalius::procedures::Nephrectomy;
use vesalius::procedures::nephrectomy::Scenario;
use vesalius::registry::builtin;
use vesalius::trace::KeyTrace;

fn nephrectomy_step(c: &mut Criterion) {
    let text = builtin("nephrectomy").expect("builtin scenario");
    let scenario = Scenario::parse("nephrectomy.toml", text).expect("scenario");
    let trace =
        KeyTrace::parse("demo", vesalius::procedures::nephrectomy::INFO.demo_trace).expect("trace");
    let dt = scenario.dt_s as f64;
    let mut p = Nephrectomy::new(scenario).expect("anatomy");
    let mut events = Vec::new();
    // Advance to the middle of the cut (about 9 s into the demo).
    let mut step = 0u64;
    while (step as f64) * dt < 9.0 {
        p.step(&trace.sample(step as f64 * dt), step, &mut events);
        step += 1;
    }
    c.bench_function("nephrectomy_step_full_size_cutting", |b| {
        b.iter(|| {
            events.clear();
            p.step(&trace.sample(step as f64 * dt), step, &mut events);
            step += 1;
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = nephrectomy_step
}
criterion_main!(benches);
