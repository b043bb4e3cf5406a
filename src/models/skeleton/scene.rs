//! The catheter in the vessel: every step the catheter takes its sub-steps against the
//! vessel's wall where it is (collision by sections, the paper's contact law), the wall's
//! reaction is gathered over them, and the vessel takes one step with it. A wall ball pushed
//! harder than the puncture force gives way: it and the wall balls within the catheter's
//! radius of it stop colliding (a hole the catheter can pass), and the puncture is reported.

use super::catheter::{Catheter, Drive};
use super::collision::{Hit, contact_forces, detect_within, narrow};
use super::contact::ContactLaw;
use super::vessel::Vessel;
use glam::DVec3;
use std::time::Instant;

/// Pairs within this of touching at the start of a step are tested at each of its sub-steps,
/// m (the handle moves at most 0.5 mm a step; the wall far less).
pub const CANDIDATE_MARGIN_M: f64 = 0.002;

/// One puncture of the wall.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Puncture {
    /// The wall ball that gave way, where it was and the force on it, N.
    pub wall: u32,
    pub position: DVec3,
    pub force_n: f64,
}

/// What a step did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepOutcome {
    /// The force the wall puts on the whole catheter (its reaction, for the haptic device),
    /// and on its head ball, N: means over the sub-steps.
    pub reaction: DVec3,
    pub head: DVec3,
    /// The head's normal force alone, N (the largest over the sub-steps).
    pub head_normal_n: f64,
    /// The hardest any wall ball was pushed (the sum of the normal forces on it), N: what
    /// the puncture force is compared with.
    pub largest_push_n: f64,
    /// Catheter-wall contacts at the last sub-step.
    pub contacts: usize,
    pub punctures: Vec<Puncture>,
    /// Ball pairs the collision tested over the step.
    pub pair_tests: u64,
}

/// The catheter, the vessel and their contact.
pub struct CatheterScene {
    pub catheter: Catheter,
    pub vessel: Vessel,
    pub law: ContactLaw,
    pub puncture_n: f64,
    pub substeps: u32,
    /// Wall balls that no longer collide (punctured).
    pub holes: Vec<bool>,
    /// Wall-clock seconds stepping the catheter, the vessel and the collision (with the
    /// contact forces).
    pub times: [f64; 3],
    candidates: Vec<Hit>,
    hits: Vec<Hit>,
    /// Per wall ball scratch: this sub-step's push and reaction, the step's mean reaction,
    /// and the balls it was gathered on.
    pushed: Vec<f64>,
    on_wall: Vec<DVec3>,
    wall_mean: Vec<DVec3>,
    touched: Vec<u32>,
}

impl CatheterScene {
    pub fn new(
        catheter: Catheter,
        vessel: Vessel,
        law: ContactLaw,
        puncture_n: f64,
        substeps: u32,
    ) -> CatheterScene {
        let n = vessel.balls.len();
        let holes = vec![false; n];
        CatheterScene {
            catheter,
            vessel,
            law,
            puncture_n,
            substeps: substeps.max(1),
            holes,
            times: [0.0; 3],
            candidates: Vec::new(),
            hits: Vec::new(),
            pushed: vec![0.0; n],
            on_wall: vec![DVec3::ZERO; n],
            wall_mean: vec![DVec3::ZERO; n],
            touched: Vec::new(),
        }
    }

    /// One step of `dt_s` under the device's drive. The collision finds the candidate pairs
    /// once a step (those within [`CANDIDATE_MARGIN_M`] of touching) and each sub-step tests
    /// only those; the wall's reaction is gathered only where it touches, so no part of the
    /// step grows with the vessel's length but the vessel's own step.
    pub fn step(&mut self, drive: &Drive, dt_s: f64) -> StepOutcome {
        let n_sub = self.substeps as usize;
        let h = dt_s / n_sub as f64;
        let nc = self.catheter.balls.len();
        let head = nc - 1;
        let mut out = StepOutcome::default();
        let t0 = Instant::now();
        let inside = self.catheter.first_inside();
        out.pair_tests = detect_within(
            &self.catheter.balls,
            inside,
            &self.vessel,
            &self.holes,
            CANDIDATE_MARGIN_M,
            &mut self.candidates,
        );
        self.times[2] += t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        self.catheter.orient(drive);
        self.times[0] += t1.elapsed().as_secs_f64();
        let mut on_catheter = vec![DVec3::ZERO; nc];
        let share = 1.0 / n_sub as f64;
        for _ in 0..n_sub {
            let t0 = Instant::now();
            narrow(
                &self.candidates,
                &self.catheter.balls,
                &self.vessel,
                &mut self.hits,
            );
            on_catheter.iter_mut().for_each(|f| *f = DVec3::ZERO);
            let forces = contact_forces(
                &self.hits,
                &self.law,
                &self.catheter.balls,
                &self.vessel,
                &mut on_catheter,
                &mut self.on_wall,
            );
            for (hit, f) in self.hits.iter().zip(&forces) {
                let w = hit.wall as usize;
                self.pushed[w] += f.normal.length();
                if hit.catheter as usize == head {
                    out.head_normal_n = out.head_normal_n.max(f.normal.length());
                }
            }
            // The wall's reaction this sub-step into the step's mean; the scratch cleared
            // where it was used.
            for k in 0..self.hits.len() {
                let hit = self.hits[k];
                let w = hit.wall as usize;
                if self.pushed[w] > 0.0 {
                    out.largest_push_n = out.largest_push_n.max(self.pushed[w]);
                    if self.pushed[w] > self.puncture_n && !self.holes[w] {
                        self.puncture(w, self.pushed[w], &mut out.punctures);
                    }
                    self.pushed[w] = 0.0;
                }
                if self.on_wall[w] != DVec3::ZERO {
                    if self.wall_mean[w] == DVec3::ZERO {
                        self.touched.push(hit.wall);
                    }
                    self.wall_mean[w] += self.on_wall[w] * share;
                    self.on_wall[w] = DVec3::ZERO;
                }
            }
            let t1 = Instant::now();
            self.catheter.step(drive, &on_catheter, h);
            let t2 = Instant::now();
            self.times[2] += (t1 - t0).as_secs_f64();
            self.times[0] += (t2 - t1).as_secs_f64();
            out.reaction += on_catheter.iter().sum::<DVec3>() * share;
            out.head += on_catheter[head] * share;
            out.contacts = self.hits.len();
        }
        let t0 = Instant::now();
        self.vessel.step(&self.wall_mean, dt_s);
        for &w in &self.touched {
            self.wall_mean[w as usize] = DVec3::ZERO;
        }
        self.touched.clear();
        self.times[1] += t0.elapsed().as_secs_f64();
        out
    }

    /// Wall ball `b`, pushed with `force_n`, gives way, with those within the catheter's
    /// radius of it.
    fn puncture(&mut self, b: usize, force_n: f64, out: &mut Vec<Puncture>) {
        let r = 0.5 * self.catheter.params.diameter_m;
        let at = self.vessel.balls.x[b];
        out.push(Puncture {
            wall: b as u32,
            position: at,
            force_n,
        });
        for (k, x) in self.vessel.balls.x.iter().enumerate() {
            if x.distance(at) <= r {
                self.holes[k] = true;
            }
        }
        // The candidates through the hole go.
        let holes = &self.holes;
        self.candidates.retain(|c| !holes[c.wall as usize]);
    }

    /// A digest of the balls' places and speeds and the holes, for replay checks.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        let balls = [&self.catheter.balls, &self.vessel.balls];
        for b in balls {
            for (x, v) in b.x.iter().zip(&b.v) {
                for c in x.to_array().into_iter().chain(v.to_array()) {
                    let bits = c.to_bits();
                    h.write(bits as u32);
                    h.write((bits >> 32) as u32);
                }
            }
        }
        for t in &self.catheter.twist {
            let bits = t.to_bits();
            h.write(bits as u32);
            h.write((bits >> 32) as u32);
        }
        h.write(self.holes.iter().filter(|&&x| x).count() as u32);
        h.0
    }
}
