use super::*;
use crate::models::bem::Problem;
use faer::Par;

fn quiet(_: &str, _: f64) {}

fn setup() -> (Problem, Vec<usize>) {
    crate::models::bem::reference::pressurised_tube(0.45)
}

/// Two elements held where the instrument puts them: the capacitance solution is the one a
/// full solve gives with those elements' displacements prescribed.
#[test]
fn held_elements_match_a_full_solve_with_their_displacements_prescribed() {
    let (p, field) = setup();
    let pre = p.precompute(&field, Par::Seq, &quiet).expect("solves");
    let mut contacts = Contacts::new(pre.clone(), &p.elements, None);
    let held = [field[3], field[10]];
    contacts.set_contacts(&held).expect("in field");
    let base = pre.solution(&p);
    let targets = [
        base.displacement[held[0]] + DVec3::new(0.0, -0.002, 0.0005),
        base.displacement[held[1]] + DVec3::new(0.001, 0.0, 0.0),
    ];
    let force = contacts.update(&targets, 0.001).expect("two targets");
    let mut u = Vec::new();
    contacts.displacements(&p.conditions, &mut u);

    let mut direct = p.clone();
    for (&e, t) in held.iter().zip(&targets) {
        direct.conditions[e] = Condition {
            known: [Known::Displacement; 3],
            value: *t,
        };
    }
    let (sol, _) = direct.solve(Par::Seq, &quiet).expect("solves");
    let scale = sol
        .displacement
        .iter()
        .map(|d| d.length())
        .fold(0.0, f64::max);
    for (a, b) in u.iter().zip(&sol.displacement) {
        assert!((*a - *b).length() < 1e-8 * scale, "{a} vs {b}");
    }
    let want: DVec3 = held
        .iter()
        .map(|&e| sol.traction[e] * p.elements[e].area_m2)
        .sum();
    assert!(
        (force - want).length() < 1e-8 * want.length(),
        "{force} N vs {want} N"
    );
    assert!(force.length() > 0.0);
}

/// A step indentation held still: the force relaxes as the Prony series, within 2 %.
#[test]
fn a_held_indentation_relaxes_as_the_prony_series() {
    let prony = Prony {
        g1: 0.363,
        tau_s: 6.372,
    };
    for hold in [1.0, 6.372, 20.0] {
        let (got, want) =
            crate::models::bem::reference::prony_relaxation(prony, hold, 0.001).expect("runs");
        assert!((got / want - 1.0).abs() < 0.02, "{hold} s: {got} vs {want}");
        assert!(got < 1.0);
    }
}

#[test]
fn contact_sets_outside_the_field_repeated_or_too_large_are_refused() {
    let (p, field) = setup();
    let pre = p.precompute(&field[..4], Par::Seq, &quiet).expect("solves");
    let mut c = Contacts::new(pre, &p.elements, None);
    assert_eq!(
        c.set_contacts(&[field[5]]),
        Err(ContactError::NotInField { element: field[5] })
    );
    assert_eq!(
        c.set_contacts(&[field[1], field[1]]),
        Err(ContactError::Repeated { element: field[1] })
    );
    let many: Vec<usize> = (0..65).collect();
    assert!(matches!(
        c.set_contacts(&many),
        Err(ContactError::TooMany { .. })
    ));
    c.set_contacts(&[field[0]]).expect("in field");
    assert!(matches!(
        c.update(&[], 0.001),
        Err(ContactError::Targets { .. })
    ));
}

#[test]
fn the_surface_displacements_are_the_same_bytes_on_one_and_two_threads() {
    let (p, field) = setup();
    let pre = p.precompute(&field, Par::Seq, &quiet).expect("solves");
    let base = pre.solution(&p);
    let mut contacts = Contacts::new(pre, &p.elements, None);
    let held = [field[2], field[9], field[20]];
    contacts.set_contacts(&held).expect("in field");
    let targets: Vec<DVec3> = held
        .iter()
        .map(|&e| base.displacement[e] + DVec3::new(0.0, -0.001, 0.0))
        .collect();
    contacts.update(&targets, 0.001).expect("targets");
    let run = |threads| {
        crate::sim::on_threads(threads, || {
            let mut u = Vec::new();
            contacts.displacements(&p.conditions, &mut u);
            u
        })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one, two);
    assert!(one.iter().zip(&base.displacement).any(|(a, b)| a != b));
}
