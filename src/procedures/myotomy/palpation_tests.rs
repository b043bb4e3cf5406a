//! Palpation of the boundary-element esophagus (the model in `models/bem/palpation.rs`)
//! at a coarse level.

use crate::models::bem::contact::Contacts;
use crate::models::bem::palpation::{Palpation, Tip};
use crate::procedures::myotomy::anatomy::{Esophagus, EsophagusParams};
use faer::Par;
use glam::DVec3;

/// The esophagus at a coarse level (12 around, 12 along), precomputed.
fn coarse() -> (Esophagus, Palpation) {
    let e = Esophagus::new(&EsophagusParams {
        around: 12,
        along: 12,
        field_arc_deg: 120.0,
        ..EsophagusParams::default()
    });
    let pre = e
        .problem
        .precompute(&e.field, Par::Seq, &|_, _| {})
        .expect("solves");
    let base = pre.solution(&e.problem);
    let contacts = Contacts::new(pre, &e.problem.elements, None);
    let palpation = Palpation::new(contacts, &e.problem.elements, &base);
    (e, palpation)
}

/// An 8 mm tip (the coarse level's elements are 5 mm across) pressed into the anterior wall at mid-length (travel past the highest
/// resting centroid; the ones under the tip sit a little lower): nothing before it
/// reaches the wall, then a force into the wall (-y) that grows with the travel, every
/// held element pushed (none pulled).
#[test]
fn pressing_the_anterior_wall_pushes_back_more_the_deeper_the_tip() {
    let (e, mut palp) = coarse();
    let r = 0.008;
    // The resting wall's height above the axis at mid-length (pressure inflates it).
    let wall = e
        .problem
        .elements
        .iter()
        .enumerate()
        .filter(|(_, el)| el.normal.y > 0.95 && (el.centroid.z - 0.03).abs() < 0.006)
        .map(|(i, _)| palp.rest(i).y)
        .fold(0.0f64, f64::max);
    assert!(wall > 0.0095, "resting wall at {wall} m");
    let mut last = 0.0;
    for depth_mm in [-1.0, 2.0, 4.0, 6.0, 8.0] {
        let tip = Tip::sphere(DVec3::new(0.0, wall + r - depth_mm * 1e-3, 0.03), r);
        let touch = palp.update(&tip, 0.001).expect("within the field");
        if depth_mm < 0.0 {
            assert!(touch.held.is_empty() && touch.force_n == DVec3::ZERO);
            continue;
        }
        assert!(!touch.held.is_empty(), "{depth_mm} mm");
        let f = touch.force_n;
        assert!(
            f.y < 0.0 && f.y.abs() > 3.0 * f.x.abs().max(f.z.abs()),
            "{f}"
        );
        assert!(-f.y > last, "{depth_mm} mm: {} N after {last} N", -f.y);
        last = -f.y;
        for k in 0..touch.held.len() {
            let el = &e.problem.elements[touch.held[k]];
            assert!(palp.contacts.traction(k).dot(el.normal) <= 0.0);
        }
    }
    eprintln!("palpation: {last} N at 8 mm");
    // Millinewtons to a few newtons: the paper's 5.2 kPa tissue under an 8 mm tip.
    assert!(last > 1e-3 && last < 5.0, "{last} N at 8 mm");
}
