//! Palpation of a boundary-element surface (the esophagus's wall) with a round instrument tip: which field
//! elements it holds, where it holds them, and the force, at haptic rate.
//!
//! The tip is a sphere (a shaft, a capsule). The elements whose resting centroids (under the
//! pressure alone) lie inside it are the candidates, the deepest 64 kept; each is pushed in along its normal to
//! the sphere's surface and held there (the tissue sticks to the tip sideways: James and
//! Pai's displacement constraints). A held element that the solution
//! would pull towards the tip (its contact traction along its outward normal is positive: the
//! tissue does not stick) is let go and the rest solved again. The force the tissue takes is
//! the sum of the held elements' contact tractions times their areas; the instrument feels
//! minus it.

use crate::models::bem::contact::{ContactError, ContactState, Contacts, MOST_CONTACTS};
use crate::models::bem::{Element, Solution};
use glam::DVec3;

/// Solves after letting go of pulling elements, at most.
const MOST_RELEASES: usize = 4;

/// A spherical instrument tip, or a capsule (a shaft: the sphere swept from `centre_m` to
/// `back_m`), in the esophagus's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tip {
    pub centre_m: DVec3,
    pub radius_m: f64,
    /// The capsule's other end (`centre_m` for a sphere).
    pub back_m: DVec3,
}

impl Tip {
    pub fn sphere(centre_m: DVec3, radius_m: f64) -> Tip {
        Tip {
            centre_m,
            radius_m,
            back_m: centre_m,
        }
    }

    /// The centre of the sphere that pushes the resting point `p` along its normal `n`: the
    /// point of the axis nearest the line through `p` along `n` (a sphere's own centre).
    fn centre_for(&self, p: DVec3, n: DVec3) -> DVec3 {
        let d = self.back_m - self.centre_m;
        let w = self.centre_m - p;
        let (dd, dn) = (d.length_squared(), d.dot(n));
        let denom = dd - dn * dn;
        if dd <= 0.0 || denom <= 1e-12 * dd {
            return self.centre_m;
        }
        let t = ((dn * w.dot(n) - w.dot(d)) / denom).clamp(0.0, 1.0);
        self.centre_m + d * t
    }
}

/// What one palpation update found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Touch {
    /// The held elements.
    pub held: Vec<usize>,
    /// The force the tissue takes from the tip, N.
    pub force_n: DVec3,
    /// How far the tip pushes the wall in, m (the furthest pushed resting centroid).
    pub depth_m: f64,
}

/// What a rollback returns palpation to: the contacts' state and the grasps.
#[derive(Clone, Default)]
pub struct PalpationState {
    contacts: ContactState,
    grasped: Vec<Vec<(usize, DVec3)>>,
    held_at: Vec<(usize, usize, DVec3)>,
}

/// Palpation against a precomputed surface.
pub struct Palpation {
    pub contacts: Contacts,
    /// The resting centroids (under the pressure), m.
    rest: Vec<DVec3>,
    normals: Vec<DVec3>,
    /// Each tip's grasp: the elements its closed jaws took and where each sits from the
    /// tip's centre, m.
    grasped: Vec<Vec<(usize, DVec3)>>,
    /// Every element held after the last update: its owner tip and target position, m.
    held_at: Vec<(usize, usize, DVec3)>,
    /// Last update's pressing candidates (element, tip) and those it let go.
    last_candidates: Vec<(usize, usize)>,
    last_released: Vec<usize>,
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
            grasped: Vec::new(),
            held_at: Vec::new(),
            last_candidates: Vec::new(),
            last_released: Vec::new(),
        }
    }

    /// Saves what updates change into `to`.
    pub fn save(&self, to: &mut PalpationState) {
        self.contacts.save(&mut to.contacts);
        to.grasped.clone_from(&self.grasped);
        to.held_at.clone_from(&self.held_at);
    }

    /// Returns to a saved state.
    pub fn load(&mut self, from: &PalpationState) {
        self.contacts.load(&from.contacts);
        self.grasped.clone_from(&from.grasped);
        self.held_at.clone_from(&from.held_at);
    }

    /// Elements.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Element `e`'s centroid at rest (under the pressure alone), m.
    pub fn rest(&self, e: usize) -> DVec3 {
        self.rest[e]
    }

    /// One update with one tip that presses (never grasps).
    pub fn update(&mut self, tip: &Tip, dt_s: f64) -> Result<Touch, ContactError> {
        let mut touches = self.update_tips(&[*tip], &[false], dt_s)?;
        Ok(touches.pop().unwrap_or_default())
    }

    /// One update with every tip where it is now, a step of `dt_s`. A tip whose `grasp` is
    /// set holds what it touched when it closed (those elements follow it and are never let
    /// go until it opens); the others press. An element inside two tips belongs to the one
    /// it lies deeper in; at most [`MOST_CONTACTS`] are held in all, grasped ones first, then
    /// the deepest.
    pub fn update_tips(
        &mut self,
        tips: &[Tip],
        grasp: &[bool],
        dt_s: f64,
    ) -> Result<Vec<Touch>, ContactError> {
        self.grasped.resize(tips.len(), Vec::new());
        for (k, g) in self.grasped.iter_mut().enumerate() {
            if !grasp.get(k).copied().unwrap_or(false) {
                g.clear();
            } else if g.is_empty() {
                // Closing: it takes what it holds now.
                let centre = tips[k].centre_m;
                *g = self
                    .held_at
                    .iter()
                    .filter(|&&(_, owner, _)| owner == k)
                    .map(|&(e, _, at)| (e, at - centre))
                    .collect();
            }
        }
        // (owner, element, target position) of the grasped elements.
        let mut fixed: Vec<(usize, usize, DVec3)> = Vec::new();
        for (k, g) in self.grasped.iter().enumerate() {
            for &(e, off) in g {
                if fixed.len() < MOST_CONTACTS {
                    fixed.push((k, e, tips[k].centre_m + off));
                }
            }
        }
        let mut candidates: Vec<(f64, usize, usize)> = Vec::new();
        for e in 0..self.rest.len() {
            if !self.contacts.in_field(e) || fixed.iter().any(|f| f.1 == e) {
                continue;
            }
            let (k, depth) = deepest_push(tips, self.rest[e], self.normals[e]);
            if depth > 0.0 && !grasp.get(k).copied().unwrap_or(false) {
                candidates.push((depth, e, k));
            }
        }
        // Deepest first; ties by element number (the same set on every machine).
        candidates.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        candidates.truncate(MOST_CONTACTS - fixed.len());
        let mut depth_m = vec![0.0f64; tips.len()];
        for &(d, _, k) in &candidates {
            depth_m[k] = depth_m[k].max(d);
        }
        let mut pressed: Vec<(usize, usize)> = candidates.iter().map(|c| (c.1, c.2)).collect();
        // The same candidates as last step start without the ones let go then (a contact set
        // that settled is not factorised again every step).
        let all_pressed = pressed.clone();
        if all_pressed == self.last_candidates {
            pressed.retain(|(e, _)| !self.last_released.contains(e));
        }
        for round in 0..=MOST_RELEASES {
            // The held set in element order, each with its owner and target position.
            let mut held: Vec<(usize, usize, DVec3)> = fixed
                .iter()
                .map(|&(k, e, at)| (e, k, at))
                .chain(
                    pressed
                        .iter()
                        .map(|&(e, k)| (e, k, self.on_sphere(e, &tips[k]))),
                )
                .collect();
            held.sort_unstable_by_key(|h| h.0);
            let elements: Vec<usize> = held.iter().map(|h| h.0).collect();
            let targets: Vec<DVec3> = held
                .iter()
                .map(|&(e, _, at)| self.contacts_target(e, at))
                .collect();
            self.contacts.set_contacts(&elements)?;
            // A trial: only the set finally held advances the relaxation's memory.
            let pending = self.contacts.preview(&targets, dt_s)?;
            let pulling: Vec<usize> = held
                .iter()
                .enumerate()
                .filter(|&(i, &(e, k, _))| {
                    !grasp.get(k).copied().unwrap_or(false)
                        && pending.traction(i).dot(self.normals[e]) > 0.0
                })
                .map(|(_, h)| h.0)
                .collect();
            if pulling.is_empty() || round == MOST_RELEASES {
                self.contacts.commit(pending);
                self.held_at = held;
                break;
            }
            pressed.retain(|(e, _)| !pulling.contains(e));
        }
        self.last_released = all_pressed
            .iter()
            .map(|p| p.0)
            .filter(|e| !pressed.iter().any(|p| p.0 == *e))
            .collect();
        self.last_candidates = all_pressed;
        let mut touches = vec![Touch::default(); tips.len()];
        for (i, &(e, k, _)) in self.held_at.iter().enumerate() {
            let t = &mut touches[k];
            t.held.push(e);
            t.force_n += self.contacts.traction(i) * self.contacts.area(e);
        }
        for (t, d) in touches.iter_mut().zip(depth_m) {
            t.depth_m = d;
        }
        Ok(touches)
    }

    /// Element `e`'s resting centroid pushed in along its normal onto the sphere of `tip`:
    /// `s` solves `|w - n s| = r`, `w` the centroid from the centre (the positive root).
    fn on_sphere(&self, e: usize, tip: &Tip) -> DVec3 {
        let n = self.normals[e];
        let w = self.rest[e] - tip.centre_for(self.rest[e], n);
        let wn = w.dot(n);
        let s = wn
            + (wn * wn + tip.radius_m * tip.radius_m - w.length_squared())
                .max(0.0)
                .sqrt();
        self.rest[e] - n * s
    }

    /// The displacement that puts element `e`'s centroid at `at`.
    fn contacts_target(&self, e: usize, at: DVec3) -> DVec3 {
        let pre = self.contacts.precomputed();
        let rest_u = DVec3::new(pre.y0[3 * e], pre.y0[3 * e + 1], pre.y0[3 * e + 2]);
        at - (self.rest[e] - rest_u)
    }
}

/// The most an instrument travels into the wall, m (the 20 mm of palpation).
pub const MOST_TRAVEL_M: f64 = 0.020;

/// Of the tips, the one that pushes a resting point `p` of outward normal `n` in furthest,
/// and how far (negative: none touches it). A tip touches the point when the line through
/// it along `n` crosses the sphere, the sphere reaching past the point into the tissue but
/// starting no more than [`MOST_TRAVEL_M`] inside it: the point is pushed to the sphere's
/// far side (a tip sunk below the resting surface has pushed the tissue ahead of it).
fn deepest_push(tips: &[Tip], p: DVec3, n: DVec3) -> (usize, f64) {
    tips.iter()
        .enumerate()
        .map(|(k, t)| {
            let w = p - t.centre_for(p, n);
            let wn = w.dot(n);
            let lateral2 = w.length_squared() - wn * wn;
            let r2 = t.radius_m * t.radius_m;
            if lateral2 >= r2 {
                return (k, -1.0);
            }
            let h = (r2 - lateral2).sqrt();
            let push = wn + h;
            if push <= 0.0 || wn - h > MOST_TRAVEL_M {
                (k, -1.0)
            } else {
                (k, push)
            }
        })
        .fold(
            (0, f64::NEG_INFINITY),
            |best, x| {
                if x.1 > best.1 { x } else { best }
            },
        )
}
