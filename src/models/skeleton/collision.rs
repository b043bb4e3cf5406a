//! Sphere collision between the catheter's balls and the vessel's (the paper's Fig. 5: a hit
//! when the centres are nearer than the radii's sum), only against the sections of the vessel
//! near each catheter ball: each tube keeps its balls by section along its axis, and a
//! catheter ball looks only at the sections its axial place reaches, so the cost does not grow
//! with the vessel's length. The hits' forces follow [`super::contact::ContactLaw`].

use super::Balls;
use super::contact::{ContactForce, ContactLaw};
use super::vessel::Vessel;
use glam::DVec3;

/// How far a wall ball may have moved from its resting section and still be found, as a
/// share of a section.
const SECTION_SLACK: f64 = 0.5;

/// One catheter ball touching one wall ball.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    pub catheter: u32,
    pub wall: u32,
    pub depth_m: f64,
    /// From the wall ball towards the catheter ball.
    pub normal: DVec3,
}

/// Every hit between the catheter's balls from `from` on (those before are outside the
/// vessel, in the introducer) and the vessel's, in (catheter ball, tube, section, wall ball)
/// order, skipping wall balls marked in `holes`; returns the pairs it tested.
pub fn detect(
    catheter: &Balls,
    from: usize,
    vessel: &Vessel,
    holes: &[bool],
    out: &mut Vec<Hit>,
) -> u64 {
    detect_within(catheter, from, vessel, holes, 0.0, out)
}

/// [`detect`] for pairs within `margin_m` of touching too (their depth down to `-margin_m`):
/// the candidates a step's sub-steps test again as the balls move.
pub fn detect_within(
    catheter: &Balls,
    from: usize,
    vessel: &Vessel,
    holes: &[bool],
    margin_m: f64,
    out: &mut Vec<Hit>,
) -> u64 {
    detect_skipping(catheter, (from, &[]), vessel, holes, margin_m, out)
}

/// [`detect_within`] leaving out the instrument's balls marked in `skip` (those another body
/// shields from the wall): they are not searched at all.
pub fn detect_skipping(
    catheter: &Balls,
    (from, skip): (usize, &[bool]),
    vessel: &Vessel,
    holes: &[bool],
    margin_m: f64,
    out: &mut Vec<Hit>,
) -> u64 {
    out.clear();
    let mut tests = 0u64;
    let section = vessel.params.section_m;
    let wall_r = 0.5 * vessel.params.wall_m;
    for (i, (&p, &r)) in catheter
        .x
        .iter()
        .zip(&catheter.radius_m)
        .enumerate()
        .skip(from)
    {
        if skip.get(i).copied().unwrap_or(false) {
            continue;
        }
        let reach = r + wall_r + margin_m;
        for tube in &vessel.tubes {
            let t = tube.along(p);
            if t < -reach - section || t > tube.length_m + reach + section {
                continue;
            }
            if tube.from_axis(p) > tube.mid_radius_m + reach + SECTION_SLACK * section {
                continue;
            }
            let n = tube.sections.len() as i64;
            let lo = (((t - reach) / section) - SECTION_SLACK).floor() as i64;
            let hi = (((t + reach) / section) + SECTION_SLACK).floor() as i64;
            for k in lo.max(0)..=hi.min(n - 1) {
                for &b in &tube.sections[k as usize] {
                    if holes.get(b as usize).copied().unwrap_or(false) {
                        continue;
                    }
                    tests += 1;
                    let d = p - vessel.balls.x[b as usize];
                    let dist = d.length();
                    let depth = reach - margin_m - dist;
                    if depth > -margin_m && dist > 0.0 {
                        out.push(Hit {
                            catheter: i as u32,
                            wall: b,
                            depth_m: depth,
                            normal: d / dist,
                        });
                    }
                }
            }
        }
    }
    tests
}

/// The candidates that touch where the balls are now, their depth and normal brought up to
/// date, in the candidates' order.
pub fn narrow(candidates: &[Hit], catheter: &Balls, vessel: &Vessel, out: &mut Vec<Hit>) {
    out.clear();
    for c in candidates {
        let (i, b) = (c.catheter as usize, c.wall as usize);
        let d = catheter.x[i] - vessel.balls.x[b];
        let dist = d.length();
        let depth = catheter.radius_m[i] + vessel.balls.radius_m[b] - dist;
        if depth > 0.0 && dist > 0.0 {
            out.push(Hit {
                depth_m: depth,
                normal: d / dist,
                ..*c
            });
        }
    }
}

/// The hits' forces: added to `on_catheter` (per catheter ball) and, with the opposite sign,
/// to `on_wall` (per wall ball); each hit's force on the catheter is returned in hit order.
pub fn contact_forces(
    hits: &[Hit],
    law: &ContactLaw,
    catheter: &Balls,
    vessel: &Vessel,
    on_catheter: &mut [DVec3],
    on_wall: &mut [DVec3],
) -> Vec<ContactForce> {
    hits.iter()
        .map(|h| {
            let (c, w) = (h.catheter as usize, h.wall as usize);
            let v_rel = catheter.v[c] - vessel.balls.v[w];
            let f = law.force(h.depth_m, h.normal, v_rel);
            on_catheter[c] += f.total();
            on_wall[w] -= f.total();
            f
        })
        .collect()
}
