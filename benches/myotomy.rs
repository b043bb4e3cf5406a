//! Criterion benchmarks of the myotomy's boundary-element esophagus at the paper's size
//! (3,720 elements, N = 11,160): a contact update with 64 held elements on a steady set and
//! on a set that changes every update, and the whole surface's displacement. The
//! precomputation comes from the cache (`vesalius precompute myotomy` makes it; built here
//! otherwise, about 30 s).

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use vesalius::models::bem::cache;
use vesalius::models::bem::contact::{Contacts, MOST_CONTACTS, Prony};
use vesalius::procedures::myotomy::anatomy::{Esophagus, EsophagusParams};

fn myotomy(c: &mut Criterion) {
    let e = Esophagus::new(&EsophagusParams::default());
    let path = cache::default_dir().join("myotomy.bem");
    let par = faer::Par::rayon(rayon::current_num_threads());
    let (pre, _) = e
        .problem
        .precompute_cached(&e.field, &path, par, &|_, _| {})
        .expect("precomputes");
    let base = pre.solution(&e.problem).displacement;
    let field = e.field.clone();
    let prony = Prony {
        g1: 0.363,
        tau_s: 6.372,
    };
    let mut contacts = Contacts::new(pre, &e.problem.elements, Some(prony));
    let set: Vec<usize> = field[..MOST_CONTACTS].to_vec();
    let targets: Vec<DVec3> = set
        .iter()
        .map(|&k| base[k] + DVec3::new(0.0, -0.002, 0.0))
        .collect();
    let mut g = c.benchmark_group("myotomy");
    g.sample_size(20);
    contacts.set_contacts(&set).expect("in field");
    g.bench_function("contact_update_64_steady_set", |b| {
        b.iter(|| contacts.update(&targets, 0.001).expect("targets"))
    });
    let mut k = 0usize;
    g.bench_function("contact_update_64_set_changing_every_update", |b| {
        b.iter(|| {
            let mut s = set.clone();
            s[0] = field[MOST_CONTACTS + k % (field.len() - MOST_CONTACTS)];
            k += 1;
            contacts.set_contacts(&s).expect("in field");
            contacts.update(&targets, 0.001).expect("targets")
        })
    });
    let mut u = Vec::new();
    g.bench_function("surface_displacements_3720_elements", |b| {
        b.iter(|| contacts.displacements(&e.problem.conditions, &mut u))
    });
    g.finish();
}

criterion_group!(benches, myotomy);
criterion_main!(benches);
