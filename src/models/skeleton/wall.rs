//! The catheter against the vessel's wall, as the couplings of their world: before each of
//! the catheter's substeps, the collision (by sections, the paper's contact law) against the
//! wall where it is sets the catheter's contact forces, and the wall's reaction is gathered
//! over them; before the vessel's one step, that mean reaction is handed to it. A wall ball
//! pushed harder than the puncture force gives way: it and the wall balls within the
//! catheter's radius of it stop colliding (a hole the catheter can pass), and the puncture is
//! reported.

use super::collision::{Hit, contact_forces, detect_within, narrow};
use super::contact::ContactLaw;
use super::model::Skeleton;
use crate::sim::{Couplings, EventKind, ModelId, Models, Phase};
use glam::DVec3;

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

/// The catheter's and the vessel's places in their world (stages 0 and 1).
pub const CATHETER: ModelId = ModelId(0);
pub const VESSEL: ModelId = ModelId(1);

/// The wall contact between the catheter and the vessel, and what it keeps between steps.
pub struct WallContact {
    pub law: ContactLaw,
    pub puncture_n: f64,
    /// Wall balls that no longer collide (punctured).
    pub holes: Vec<bool>,
    /// What the last step did.
    pub out: StepOutcome,
    candidates: Vec<Hit>,
    hits: Vec<Hit>,
    /// Per wall ball scratch: this sub-step's push and reaction, the step's mean reaction,
    /// and the balls it was gathered on.
    pushed: Vec<f64>,
    on_wall: Vec<DVec3>,
    wall_mean: Vec<DVec3>,
    touched: Vec<u32>,
    /// The wall balls the vessel's force buffer holds forces on (from the last hand-over).
    handed: Vec<u32>,
    on_catheter: Vec<DVec3>,
}

impl WallContact {
    /// For a vessel of `wall_balls` balls and a catheter of `catheter_balls`.
    pub fn new(law: ContactLaw, puncture_n: f64, wall_balls: usize, catheter_balls: usize) -> Self {
        WallContact {
            law,
            puncture_n,
            holes: vec![false; wall_balls],
            out: StepOutcome::default(),
            candidates: Vec::new(),
            hits: Vec::new(),
            pushed: vec![0.0; wall_balls],
            on_wall: vec![DVec3::ZERO; wall_balls],
            wall_mean: vec![DVec3::ZERO; wall_balls],
            touched: Vec::new(),
            handed: Vec::new(),
            on_catheter: vec![DVec3::ZERO; catheter_balls],
        }
    }

    /// Once a step, before the first substep: the candidate pairs (those within
    /// [`CANDIDATE_MARGIN_M`] of touching; each substep tests only those), then the
    /// catheter's drive for the step.
    fn begin(&mut self, phase: Phase, dt_s: f32, models: &mut Models<'_, Skeleton>) {
        self.out = StepOutcome::default();
        if let (Some(Skeleton::Catheter(c)), Some(Skeleton::Vessel(v))) =
            (models.get(CATHETER), models.get(VESSEL))
        {
            let inside = c.catheter.first_inside();
            self.out.pair_tests = detect_within(
                &c.catheter.balls,
                inside,
                &v.vessel,
                &self.holes,
                CANDIDATE_MARGIN_M,
                &mut self.candidates,
            );
        }
        if let Some(Skeleton::Catheter(c)) = models.get_mut(CATHETER) {
            let drive = c.drive;
            c.catheter.orient(&drive);
            c.substep_s = f64::from(dt_s) / f64::from(phase.substeps);
        }
    }

    /// Before each substep: the hits, the forces on the catheter's balls (set for its
    /// substep) and on the wall's (into the step's mean), and punctures.
    fn substep(&mut self, phase: Phase, models: &mut Models<'_, Skeleton>) {
        let (Some(Skeleton::Catheter(c)), Some(Skeleton::Vessel(v))) =
            (models.get(CATHETER), models.get(VESSEL))
        else {
            return;
        };
        let (catheter, vessel) = (&c.catheter, &v.vessel);
        let head = catheter.balls.len() - 1;
        let share = 1.0 / f64::from(phase.substeps);
        narrow(&self.candidates, &catheter.balls, vessel, &mut self.hits);
        self.on_catheter.iter_mut().for_each(|f| *f = DVec3::ZERO);
        let forces = contact_forces(
            &self.hits,
            &self.law,
            &catheter.balls,
            vessel,
            &mut self.on_catheter,
            &mut self.on_wall,
        );
        for (hit, f) in self.hits.iter().zip(&forces) {
            let w = hit.wall as usize;
            self.pushed[w] += f.normal.length();
            if hit.catheter as usize == head {
                self.out.head_normal_n = self.out.head_normal_n.max(f.normal.length());
            }
        }
        let radius = 0.5 * catheter.params.diameter_m;
        // The wall's reaction this sub-step into the step's mean; the scratch cleared
        // where it was used.
        for k in 0..self.hits.len() {
            let hit = self.hits[k];
            let w = hit.wall as usize;
            if self.pushed[w] > 0.0 {
                self.out.largest_push_n = self.out.largest_push_n.max(self.pushed[w]);
                if self.pushed[w] > self.puncture_n && !self.holes[w] {
                    self.puncture(w, self.pushed[w], radius, &vessel.balls.x);
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
        self.out.reaction += self.on_catheter.iter().sum::<DVec3>() * share;
        self.out.head += self.on_catheter[head] * share;
        self.out.contacts = self.hits.len();
        if let Some(Skeleton::Catheter(c)) = models.get_mut(CATHETER) {
            c.contact.copy_from_slice(&self.on_catheter);
        }
    }

    /// Before the vessel's step: the mean reaction over the catheter's substeps. The buffers
    /// are swapped, not copied: the vessel's last one comes back, cleared where it was used.
    fn hand_to_vessel(&mut self, models: &mut Models<'_, Skeleton>) {
        let handed = match models.get_mut(VESSEL) {
            Some(Skeleton::Vessel(v)) => {
                std::mem::swap(&mut v.external, &mut self.wall_mean);
                true
            }
            _ => false,
        };
        let stale = if handed {
            std::mem::replace(&mut self.handed, std::mem::take(&mut self.touched))
        } else {
            std::mem::take(&mut self.touched)
        };
        for &w in &stale {
            self.wall_mean[w as usize] = DVec3::ZERO;
        }
        self.touched = stale;
        self.touched.clear();
    }

    /// Wall ball `b`, pushed with `force_n`, gives way, with those within the catheter's
    /// radius `radius_m` of it.
    fn puncture(&mut self, b: usize, force_n: f64, radius_m: f64, wall: &[DVec3]) {
        let at = wall[b];
        self.out.punctures.push(Puncture {
            wall: b as u32,
            position: at,
            force_n,
        });
        for (k, x) in wall.iter().enumerate() {
            if x.distance(at) <= radius_m {
                self.holes[k] = true;
            }
        }
        // The candidates through the hole go.
        let holes = &self.holes;
        self.candidates.retain(|c| !holes[c.wall as usize]);
    }
}

impl Couplings<Skeleton> for WallContact {
    fn couple(
        &mut self,
        phase: Phase,
        dt_s: f32,
        models: &mut Models<'_, Skeleton>,
        _events: &mut Vec<EventKind>,
    ) {
        match phase.stage {
            0 => {
                if phase.first() {
                    self.begin(phase, dt_s, models);
                }
                self.substep(phase, models);
            }
            1 => self.hand_to_vessel(models),
            _ => {}
        }
    }
}
