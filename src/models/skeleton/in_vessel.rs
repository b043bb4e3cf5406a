//! The catheter in the vessel: the two models in one world, the catheter (stage 0, in
//! substeps) before the vessel (stage 1), joined by the wall contact.

use super::catheter::{Catheter, Drive};
use super::contact::ContactLaw;
use super::model::{CatheterModel, Skeleton, VesselModel};
use super::vessel::Vessel;
use super::wall::{CATHETER, StepOutcome, VESSEL, WallContact};
use crate::sim::{EventKind, World};

/// The catheter and the vessel in their world, with their contact.
pub struct CatheterInVessel {
    world: World<Skeleton>,
    wall: WallContact,
}

impl CatheterInVessel {
    /// The catheter takes `substeps` substeps a step.
    pub fn new(
        catheter: Catheter,
        vessel: Vessel,
        law: ContactLaw,
        puncture_n: f64,
        substeps: u32,
    ) -> CatheterInVessel {
        let wall = WallContact::new(law, puncture_n, vessel.balls.len(), catheter.balls.len());
        let mut world = World::new();
        let c = world.add_to(0, Skeleton::Catheter(CatheterModel::new(catheter)));
        let v = world.add_to(1, Skeleton::Vessel(VesselModel::new(vessel)));
        debug_assert_eq!((c, v), (CATHETER, VESSEL));
        world.set_substeps(0, substeps.max(1));
        CatheterInVessel { world, wall }
    }

    /// One step of `dt_s` (step number `step`) under the device's drive; the world's events
    /// (a quarantined model) go to `events`.
    pub fn step(
        &mut self,
        drive: &Drive,
        dt_s: f32,
        step: u64,
        events: &mut Vec<EventKind>,
    ) -> StepOutcome {
        if let Skeleton::Catheter(c) = self.world.model_mut(CATHETER) {
            c.drive = *drive;
        }
        self.world.step_coupled(dt_s, step, events, &mut self.wall);
        self.wall.out.clone()
    }

    pub fn catheter(&self) -> &Catheter {
        match self.world.model(CATHETER) {
            Skeleton::Catheter(c) => &c.catheter,
            Skeleton::Vessel(_) => unreachable!("model 0 is the catheter"),
        }
    }

    pub fn vessel(&self) -> &Vessel {
        match self.world.model(VESSEL) {
            Skeleton::Vessel(v) => &v.vessel,
            Skeleton::Catheter(_) => unreachable!("model 1 is the vessel"),
        }
    }

    /// Wall balls that no longer collide (punctured).
    pub fn holes(&self) -> &[bool] {
        &self.wall.holes
    }

    pub fn law(&self) -> &ContactLaw {
        &self.wall.law
    }

    pub fn world(&self) -> &World<Skeleton> {
        &self.world
    }

    pub fn world_mut(&mut self) -> &mut World<Skeleton> {
        &mut self.world
    }

    /// Wall-clock seconds stepping the catheter, the vessel and the collision (with the
    /// contact forces), benchmarks only.
    pub fn times(&self) -> [f64; 3] {
        let t = self.world.model_times();
        [t[0], t[1], self.world.coupling_time()]
    }

    /// A digest of the balls' places and speeds and the holes, for replay checks.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        let balls = [&self.catheter().balls, &self.vessel().balls];
        for b in balls {
            for (x, v) in b.x.iter().zip(&b.v) {
                for c in x.to_array().into_iter().chain(v.to_array()) {
                    let bits = c.to_bits();
                    h.write(bits as u32);
                    h.write((bits >> 32) as u32);
                }
            }
        }
        for t in &self.catheter().twist {
            let bits = t.to_bits();
            h.write(bits as u32);
            h.write((bits >> 32) as u32);
        }
        h.write(self.wall.holes.iter().filter(|&&x| x).count() as u32);
        h.0
    }
}
