//! Palpation of the boundary-element esophagus with a round instrument tip: which field
//! elements it holds, where it holds them, and the force, at haptic rate.
//!
//! The tip is a sphere. The elements whose resting centroids (under the pressure alone) lie
//! inside it are the candidates, the deepest 64 kept; each is pushed in along its normal to
//! the sphere's surface and held there (the tissue sticks to the tip sideways: James and
//! Pai's displacement constraints). A held element that the solution
//! would pull towards the tip (its contact traction along its outward normal is positive: the
//! tissue does not stick) is let go and the rest solved again. The force the tissue takes is
//! the sum of the held elements' contact tractions times their areas; the instrument feels
//! minus it.

use crate::models::bem::contact::{ContactError, Contacts, MOST_CONTACTS};
use crate::models::bem::{Element, Solution};
use glam::DVec3;

/// Solves after letting go of pulling elements, at most.
const MOST_RELEASES: usize = 4;

/// A spherical instrument tip, in the esophagus's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tip {
    pub centre_m: DVec3,
    pub radius_m: f64,
}

/// What one palpation update found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Touch {
    /// The held elements.
    pub held: Vec<usize>,
    /// The force the tissue takes from the tip, N.
    pub force_n: DVec3,
    /// How far the tip reaches past the resting surface, m (the deepest candidate's).
    pub depth_m: f64,
}

/// Palpation against a precomputed esophagus.
pub struct Palpation {
    pub contacts: Contacts,
    /// The resting centroids (under the pressure), m.
    rest: Vec<DVec3>,
    normals: Vec<DVec3>,
}

impl Palpation {
    pub fn new(contacts: Contacts, elements: &[Element], base: &Solution) -> Palpation {
        let rest = elements
            .iter()
            .zip(&base.displacement)
            .map(|(e, u)| e.centroid + *u)
            .collect();
        Palpation {
            contacts,
            rest,
            normals: elements.iter().map(|e| e.normal).collect(),
        }
    }

    /// One update: the tip where it is now, a step of `dt_s`.
    pub fn update(&mut self, tip: &Tip, dt_s: f64) -> Result<Touch, ContactError> {
        let mut candidates: Vec<(f64, usize)> = Vec::new();
        for e in 0..self.rest.len() {
            if !self.contacts.in_field(e) {
                continue;
            }
            let depth = tip.radius_m - (self.rest[e] - tip.centre_m).length();
            if depth > 0.0 {
                candidates.push((depth, e));
            }
        }
        // Deepest first; ties by element number (the same set on every machine).
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        candidates.truncate(MOST_CONTACTS);
        let depth_m = candidates.first().map_or(0.0, |c| c.0);
        let mut held: Vec<usize> = candidates.iter().map(|c| c.1).collect();
        held.sort_unstable();
        let base_u = |e: usize| self.rest[e];
        for _ in 0..=MOST_RELEASES {
            let targets: Vec<DVec3> = held
                .iter()
                .map(|&e| {
                    // Pushed in along its normal until it is on the sphere: `s` solves
                    // `|w - n s| = r`, `w` the centroid from the centre (the positive root).
                    let (w, n) = (base_u(e) - tip.centre_m, self.normals[e]);
                    let wn = w.dot(n);
                    let s = wn
                        + (wn * wn + tip.radius_m * tip.radius_m - w.length_squared())
                            .max(0.0)
                            .sqrt();
                    // The target displacement from the element's undeformed centroid.
                    self.contacts_target(e, base_u(e) - n * s)
                })
                .collect();
            self.contacts.set_contacts(&held)?;
            self.contacts.update(&targets, dt_s)?;
            let pulling: Vec<usize> = held
                .iter()
                .enumerate()
                .filter(|&(k, &e)| self.contacts.traction(k).dot(self.normals[e]) > 0.0)
                .map(|(_, &e)| e)
                .collect();
            if pulling.is_empty() {
                break;
            }
            held.retain(|e| !pulling.contains(e));
        }
        Ok(Touch {
            held,
            force_n: self.contacts.force_n(),
            depth_m,
        })
    }

    /// The displacement that puts element `e`'s centroid at `at`.
    fn contacts_target(&self, e: usize, at: DVec3) -> DVec3 {
        let pre = self.contacts.precomputed();
        let rest_u = DVec3::new(pre.y0[3 * e], pre.y0[3 * e + 1], pre.y0[3 * e + 2]);
        at - (self.rest[e] - rest_u)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procedures::myotomy::anatomy::{Esophagus, EsophagusParams};
    use faer::Par;

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
            .zip(&palp.rest)
            .filter(|(el, _)| el.normal.y > 0.95 && (el.centroid.z - 0.03).abs() < 0.006)
            .map(|(_, p)| p.y)
            .fold(0.0f64, f64::max);
        assert!(wall > 0.0095, "resting wall at {wall} m");
        let mut last = 0.0;
        for depth_mm in [-1.0, 2.0, 4.0, 6.0, 8.0] {
            let tip = Tip {
                centre_m: DVec3::new(0.0, wall + r - depth_mm * 1e-3, 0.03),
                radius_m: r,
            };
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
}
