//! Times the esophagus's boundary-element precomputation at the paper's size: assembly, LU
//! factorisation (with its GFLOP/s) and the field's responses. `--field-arc DEG` changes the
//! precomputed arc (0: none).
use std::io::Write;
use vesalius::models::bem::contact::{Contacts, MOST_CONTACTS, Prony};
use vesalius::models::bem::system::lu_flops;
use vesalius::procedures::myotomy::anatomy::{Esophagus, EsophagusParams};

fn main() {
    let mut p = EsophagusParams::default();
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--field-arc") {
        p.field_arc_deg = args.get(i + 1).and_then(|s| s.parse().ok()).unwrap_or(90.0);
    }
    let e = Esophagus::new(&p);
    let n = e.problem.unknowns();
    let field = if p.field_arc_deg > 0.0 {
        e.field.clone()
    } else {
        Vec::new()
    };
    println!(
        "elements {} N {n} field elements {}",
        e.problem.elements.len(),
        field.len()
    );
    let progress = |stage: &str, f: f64| {
        eprint!("\r{stage:>14} {:5.1} %", 100.0 * f);
        let _ = std::io::stderr().flush();
    };
    let par = faer::Par::rayon(rayon::current_num_threads());
    let pre = e
        .problem
        .precompute(&field, par, &progress)
        .expect("precompute");
    eprintln!();
    let t = pre.timings;
    println!(
        "assembly {:.2} s, LU {:.2} s ({:.1} GFLOP/s), solves {:.2} s, total {:.2} s",
        t.assembly_s,
        t.factor_s,
        lu_flops(n) / t.factor_s / 1e9,
        t.solve_s,
        t.assembly_s + t.factor_s + t.solve_s
    );
    if field.len() < MOST_CONTACTS + 1 {
        return;
    }
    // Contact updates with 64 held elements: the same set each update, and a set that
    // changes (one element swapped) every update.
    let prony = Prony {
        g1: 0.363,
        tau_s: 6.372,
    };
    let base = pre.solution(&e.problem).displacement;
    let mut contacts = Contacts::new(pre, &e.problem.elements, Some(prony));
    let set: Vec<usize> = field[..MOST_CONTACTS].to_vec();
    let targets: Vec<_> = set
        .iter()
        .map(|&k| base[k] + glam::DVec3::new(0.0, -0.002, 0.0))
        .collect();
    contacts.set_contacts(&set).expect("in field");
    let updates = 20_000;
    let t = std::time::Instant::now();
    let mut f = glam::DVec3::ZERO;
    for _ in 0..updates {
        f = contacts.update(&targets, 0.001).expect("targets");
    }
    let same = updates as f64 / t.elapsed().as_secs_f64();
    let changing_updates = 500;
    let t = std::time::Instant::now();
    for k in 0..changing_updates {
        let mut s = set.clone();
        s[0] = field[MOST_CONTACTS + (k % (field.len() - MOST_CONTACTS))];
        contacts.set_contacts(&s).expect("in field");
        contacts.update(&targets, 0.001).expect("targets");
    }
    let changing = changing_updates as f64 / t.elapsed().as_secs_f64();
    let t = std::time::Instant::now();
    let mut u = Vec::new();
    for _ in 0..50 {
        contacts.displacements(&e.problem.conditions, &mut u);
    }
    let surface = 50.0 / t.elapsed().as_secs_f64();
    println!(
        "contact updates (64 elements): {same:.0}/s same set, {changing:.0}/s set changing every update; whole-surface displacements {surface:.0}/s; force {:.3} N",
        f.length()
    );
}
