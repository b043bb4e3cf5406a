//! The catheter (and the guidewire, when there is one) against the vessel's wall, as the
//! couplings of their world: before each of the instruments' substeps, the collision (by
//! sections, the paper's contact law) against the wall where they are sets their contact
//! forces, the lumen holds the wire in the catheter ([`super::guidewire::lumen`]), and the
//! wall's reaction is gathered over them; before the vessel's one step, that mean reaction is
//! handed to it. A wall ball pushed harder than an instrument's puncture force gives way: it
//! and the wall balls within that instrument's radius of it stop colliding (a hole it can
//! pass), and the puncture is reported.

use super::Balls;
use super::collision::{Hit, contact_forces, detect_within, narrow};
use super::contact::{ContactForce, ContactLaw};
use super::guidewire::{lumen, shielded};
use super::model::Skeleton;
use super::surface::{SurfaceHit, WallSurface};
use super::vessel::Vessel;
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
    /// The guidewire made it (else the catheter).
    pub by_wire: bool,
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

/// What a step did to the guidewire.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WireOutcome {
    /// The wall's force on the whole wire and on its tip ball, N (means over the substeps).
    pub reaction: DVec3,
    pub tip: DVec3,
    /// The tip's largest normal force over the substeps, N.
    pub tip_normal_n: f64,
    /// Wire-wall contacts at the last substep.
    pub contacts: usize,
    /// Wire balls the catheter's lumen held at the last substep.
    pub held: usize,
}

/// The catheter's, the vessel's and the guidewire's places in their world (the catheter
/// and the wire in stage 0, the vessel in stage 1).
pub const CATHETER: ModelId = ModelId(0);
pub const VESSEL: ModelId = ModelId(1);
pub const GUIDEWIRE: ModelId = ModelId(2);

/// One instrument's collision with the wall: its candidate pairs for the step, this
/// substep's hits, the wall's force on each of its balls, its contact law and the push
/// that punctures the wall under it.
struct Probe {
    law: ContactLaw,
    puncture_n: f64,
    candidates: Vec<Hit>,
    hits: Vec<Hit>,
    on_balls: Vec<DVec3>,
}

impl Probe {
    fn new(law: ContactLaw, puncture_n: f64, balls: usize) -> Probe {
        Probe {
            law,
            puncture_n,
            candidates: Vec::new(),
            hits: Vec::new(),
            on_balls: vec![DVec3::ZERO; balls],
        }
    }
}

/// The guidewire's collision with the wall's surface: as [`Probe`], by triangles.
struct WireProbe {
    law: ContactLaw,
    puncture_n: f64,
    surface: WallSurface,
    candidates: Vec<(u32, u32)>,
    hits: Vec<SurfaceHit>,
    on_balls: Vec<DVec3>,
}

/// The wall contact between the instruments (the catheter, and the guidewire when there is
/// one) and the vessel, the lumen between the two instruments, and what it keeps between
/// steps.
pub struct WallContact {
    pub law: ContactLaw,
    pub puncture_n: f64,
    /// Wall balls that no longer collide (punctured).
    pub holes: Vec<bool>,
    /// What the last step did.
    pub out: StepOutcome,
    /// What the last step did to the wire.
    pub wire_out: WireOutcome,
    catheter: Probe,
    wire: Option<WireProbe>,
    /// Per wall ball scratch: this sub-step's push and reaction, the step's mean reaction,
    /// and the balls it was gathered on.
    pushed: Vec<f64>,
    on_wall: Vec<DVec3>,
    wall_mean: Vec<DVec3>,
    touched: Vec<u32>,
    /// The wall balls the vessel's force buffer holds forces on (from the last hand-over).
    handed: Vec<u32>,
}

impl WallContact {
    /// For a vessel of `wall_balls` balls and a catheter of `catheter_balls`.
    pub fn new(law: ContactLaw, puncture_n: f64, wall_balls: usize, catheter_balls: usize) -> Self {
        WallContact {
            law,
            puncture_n,
            holes: vec![false; wall_balls],
            out: StepOutcome::default(),
            wire_out: WireOutcome::default(),
            catheter: Probe::new(law, puncture_n, catheter_balls),
            wire: None,
            pushed: vec![0.0; wall_balls],
            on_wall: vec![DVec3::ZERO; wall_balls],
            wall_mean: vec![DVec3::ZERO; wall_balls],
            touched: Vec::new(),
            handed: Vec::new(),
        }
    }

    /// A guidewire of `balls` balls touches the wall's `surface` too, under its own law and
    /// puncture force.
    pub fn add_wire(
        &mut self,
        law: ContactLaw,
        puncture_n: f64,
        balls: usize,
        surface: WallSurface,
    ) {
        self.wire = Some(WireProbe {
            law,
            puncture_n,
            surface,
            candidates: Vec::new(),
            hits: Vec::new(),
            on_balls: vec![DVec3::ZERO; balls],
        });
    }

    /// The wire's contact law and puncture force, if there is a wire.
    pub fn wire_law(&self) -> Option<(ContactLaw, f64)> {
        self.wire.as_ref().map(|p| (p.law, p.puncture_n))
    }

    /// Once a step, before the first substep: the candidate pairs (those within
    /// [`CANDIDATE_MARGIN_M`] of touching; each substep tests only those), then the
    /// catheter's drive for the step (the wire turns its tip's curve at each substep) and
    /// the substep.
    fn begin(&mut self, phase: Phase, dt_s: f32, models: &mut Models<'_, Skeleton>) {
        self.out = StepOutcome::default();
        self.wire_out = WireOutcome::default();
        let Some(Skeleton::Vessel(v)) = models.get(VESSEL) else {
            return;
        };
        if let Some(Skeleton::Catheter(c)) = models.get(CATHETER) {
            let inside = c.catheter.first_inside();
            self.out.pair_tests = detect_within(
                &c.catheter.balls,
                inside,
                &v.vessel,
                &self.holes,
                CANDIDATE_MARGIN_M,
                &mut self.catheter.candidates,
            );
        }
        if let (Some(Skeleton::Guidewire(w)), Some(Skeleton::Catheter(c)), Some(probe)) =
            (models.get(GUIDEWIRE), models.get(CATHETER), &mut self.wire)
        {
            // The wire's balls inside the catheter are out of the wall's reach.
            let inside = shielded(&c.catheter, &w.wire);
            self.out.pair_tests += probe.surface.candidates_of(
                &w.wire.balls,
                (w.wire.first_inside(), &inside),
                &v.vessel,
                &self.holes,
                CANDIDATE_MARGIN_M,
                &mut probe.candidates,
            );
        }
        let substep_s = f64::from(dt_s) / f64::from(phase.substeps);
        if let Some(Skeleton::Catheter(c)) = models.get_mut(CATHETER) {
            let drive = c.drive;
            c.catheter.orient(&drive);
            c.substep_s = substep_s;
        }
        if let Some(Skeleton::Guidewire(w)) = models.get_mut(GUIDEWIRE) {
            w.substep_s = substep_s;
        }
    }

    /// Before each substep: each instrument's hits, the wall's forces on its balls and the
    /// opposite on the wall's (into the step's mean), punctures; then the lumen's hold
    /// between catheter and wire; the sums are set for the instruments' substep.
    fn substep(&mut self, phase: Phase, models: &mut Models<'_, Skeleton>) {
        let (Some(Skeleton::Catheter(c)), Some(Skeleton::Vessel(v))) =
            (models.get(CATHETER), models.get(VESSEL))
        else {
            return;
        };
        let (catheter, vessel) = (&c.catheter, &v.vessel);
        let share = 1.0 / f64::from(phase.substeps);
        let radius = 0.5 * catheter.params.diameter_m;
        let head = catheter.balls.len() - 1;
        let mut wall = WallScratch {
            holes: &mut self.holes,
            pushed: &mut self.pushed,
            on_wall: &mut self.on_wall,
            wall_mean: &mut self.wall_mean,
            touched: &mut self.touched,
            out: &mut self.out,
        };
        let how = (&catheter.balls, radius, false, self.catheter.puncture_n);
        let head_normal = wall.touch(&mut self.catheter, how, vessel, share);
        let out = &mut *wall.out;
        out.head_normal_n = out.head_normal_n.max(head_normal);
        let on = &self.catheter.on_balls;
        out.reaction += on.iter().sum::<DVec3>() * share;
        out.head += on[head] * share;
        out.contacts = self.catheter.hits.len();
        let mut on_catheter = self.catheter.on_balls.clone();
        let wire_forces = match (models.get(GUIDEWIRE), &mut self.wire) {
            (Some(Skeleton::Guidewire(w)), Some(probe)) => {
                let wire = &w.wire;
                let tip = wire.balls.len() - 1;
                let r = 0.5 * wire.params.diameter_m;
                let how = (&wire.balls, r, true, probe.puncture_n);
                let normal = wall.touch(probe, how, vessel, share);
                let o = &mut self.wire_out;
                o.tip_normal_n = o.tip_normal_n.max(normal);
                o.reaction += probe.on_balls.iter().sum::<DVec3>() * share;
                o.tip += probe.on_balls[tip] * share;
                o.contacts = probe.hits.len();
                let mut on_wire = probe.on_balls.clone();
                o.held = lumen(catheter, wire, &mut on_wire, &mut on_catheter);
                Some(on_wire)
            }
            _ => None,
        };
        if let Some(Skeleton::Catheter(c)) = models.get_mut(CATHETER) {
            c.contact.copy_from_slice(&on_catheter);
        }
        if let (Some(f), Some(Skeleton::Guidewire(w))) = (wire_forces, models.get_mut(GUIDEWIRE)) {
            w.contact.copy_from_slice(&f);
        }
    }

    /// Before the vessel's step: the mean reaction over the instruments' substeps. The
    /// buffers are swapped, not copied: the vessel's last one comes back, cleared where it
    /// was used.
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
}

/// The wall's per-ball scratch, borrowed for one instrument's contact.
struct WallScratch<'a> {
    holes: &'a mut Vec<bool>,
    pushed: &'a mut Vec<f64>,
    on_wall: &'a mut Vec<DVec3>,
    wall_mean: &'a mut Vec<DVec3>,
    touched: &'a mut Vec<u32>,
    out: &'a mut StepOutcome,
}

/// What [`WallScratch::touch`] needs of an instrument's probe, by balls ([`Probe`]) or by
/// the wall's surface ([`WireProbe`]).
trait Touching {
    /// Drops the candidates through the wall balls marked in `holes`.
    fn drop_holes(&mut self, holes: &[bool]);
    /// This substep's hits among the candidates and their forces (in hit order): the wall's
    /// on the instrument's balls (cleared first), the opposite into `on_wall`.
    fn contact(&mut self, at: (&Balls, &Vessel), on_wall: &mut [DVec3]) -> Vec<ContactForce>;
    /// Hit `k`'s instrument ball, and the wall balls its push lands on with their shares
    /// (the first `n` of three).
    fn hit(&self, k: usize) -> (u32, [(u32, f64); 3], usize);
}

impl Touching for Probe {
    fn drop_holes(&mut self, holes: &[bool]) {
        self.candidates.retain(|c| !holes[c.wall as usize]);
    }

    fn contact(
        &mut self,
        (balls, vessel): (&Balls, &Vessel),
        on: &mut [DVec3],
    ) -> Vec<ContactForce> {
        narrow(&self.candidates, balls, vessel, &mut self.hits);
        self.on_balls.iter_mut().for_each(|f| *f = DVec3::ZERO);
        let hits = &self.hits;
        contact_forces(hits, &self.law, balls, vessel, &mut self.on_balls, on)
    }

    fn hit(&self, k: usize) -> (u32, [(u32, f64); 3], usize) {
        let h = &self.hits[k];
        (h.catheter, [(h.wall, 1.0); 3], 1)
    }
}

impl Touching for WireProbe {
    fn drop_holes(&mut self, holes: &[bool]) {
        let triangles = &self.surface.triangles;
        self.candidates
            .retain(|&(_, t)| triangles[t as usize].iter().all(|&c| !holes[c as usize]));
    }

    fn contact(&mut self, at: (&Balls, &Vessel), on_wall: &mut [DVec3]) -> Vec<ContactForce> {
        let (surface, hits) = (&self.surface, &mut self.hits);
        surface.narrow(&self.candidates, at.0, at.1, hits);
        self.on_balls.fill(DVec3::ZERO);
        surface.forces(hits, &self.law, at.0, at.1, &mut self.on_balls, on_wall)
    }

    fn hit(&self, k: usize) -> (u32, [(u32, f64); 3], usize) {
        let h = &self.hits[k];
        let tri = self.surface.triangles[h.triangle as usize];
        let w = h.weights;
        (h.ball, [(tri[0], w[0]), (tri[1], w[1]), (tri[2], w[2])], 3)
    }
}

impl WallScratch<'_> {
    /// One instrument's contact this substep: its hits among its candidates, the wall's
    /// forces on its balls (into the probe's, cleared first) and the opposite on the wall's
    /// (into the step's mean, `share` of it), each hit's normal force pushing the wall balls
    /// under it by their shares; punctures where a wall ball is pushed harder than the
    /// `puncture_n` (the hole as wide as the instrument's `radius_m`; `by_wire`
    /// says which instrument made it). Returns the largest normal force on the
    /// instrument's last ball (its tip).
    fn touch<P: Touching>(
        &mut self,
        probe: &mut P,
        (balls, radius_m, by_wire, puncture_n): (&Balls, f64, bool, f64),
        vessel: &Vessel,
        share: f64,
    ) -> f64 {
        if !self.out.punctures.is_empty() {
            // Holes the other instrument made this step.
            probe.drop_holes(self.holes);
        }
        let forces = probe.contact((balls, vessel), self.on_wall);
        let last = balls.len().saturating_sub(1) as u32;
        let mut tip_normal: f64 = 0.0;
        for (k, f) in forces.iter().enumerate() {
            let n = f.normal.length();
            let (ball, corners, count) = probe.hit(k);
            for &(c, w) in &corners[..count] {
                self.pushed[c as usize] += n * w;
            }
            if ball == last {
                tip_normal = tip_normal.max(n);
            }
        }
        // The wall's reaction this substep into the step's mean; the scratch cleared
        // where it was used.
        let how = (puncture_n, radius_m, by_wire);
        let mut punctured = false;
        for k in 0..forces.len() {
            let (_, corners, count) = probe.hit(k);
            for &(c, _) in &corners[..count] {
                punctured |= self.settle(c as usize, how, vessel, share);
            }
        }
        if punctured {
            // The candidates through the hole go.
            probe.drop_holes(self.holes);
        }
        tip_normal
    }

    /// Wall ball `w` after a contact's forces: a push past `puncture_n` (times the ball's
    /// strength: less at the ostia) punctures it (a hole
    /// of `radius_m`, made by the wire if `by_wire`), and its reaction goes into the step's
    /// mean (`share` of it); its scratch is cleared. Returns whether it was punctured.
    fn settle(
        &mut self,
        w: usize,
        (puncture_n, radius_m, by_wire): (f64, f64, bool),
        vessel: &Vessel,
        share: f64,
    ) -> bool {
        let mut punctured = false;
        if self.pushed[w] > 0.0 {
            self.out.largest_push_n = self.out.largest_push_n.max(self.pushed[w]);
            if self.pushed[w] > puncture_n * vessel.strength[w] && !self.holes[w] {
                let at = vessel.balls.x[w];
                self.out.punctures.push(Puncture {
                    wall: w as u32,
                    position: at,
                    force_n: self.pushed[w],
                    by_wire,
                });
                for (k, x) in vessel.balls.x.iter().enumerate() {
                    if x.distance(at) <= radius_m {
                        self.holes[k] = true;
                    }
                }
                punctured = true;
            }
            self.pushed[w] = 0.0;
        }
        if self.on_wall[w] != DVec3::ZERO {
            if self.wall_mean[w] == DVec3::ZERO {
                self.touched.push(w as u32);
            }
            self.wall_mean[w] += self.on_wall[w] * share;
            self.on_wall[w] = DVec3::ZERO;
        }
        punctured
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
