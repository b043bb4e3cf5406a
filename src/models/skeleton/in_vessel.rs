//! The catheter in the vessel: the models in one world, the catheter (stage 0, in substeps)
//! and the guidewire in it when there is one (stage 0 too) before the vessel (stage 1),
//! joined by the wall contact and the lumen.

use super::catheter::{Catheter, Drive};
use super::contact::ContactLaw;
use super::guidewire::{Guidewire, WireDrive};
use super::model::{CatheterModel, GuidewireModel, Skeleton, VesselModel};
use super::surface::WallSurface;
use super::vessel::Vessel;
use super::wall::{CATHETER, GUIDEWIRE, StepOutcome, VESSEL, WallContact, WireOutcome};
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

    /// With a guidewire in the catheter's lumen, touching the wall under `law` and
    /// puncturing it at `puncture_n`; it takes the catheter's substeps.
    pub fn with_wire(mut self, wire: Guidewire, law: ContactLaw, puncture_n: f64) -> Self {
        let n = wire.balls.len();
        let id = self
            .world
            .add_to(0, Skeleton::Guidewire(GuidewireModel::new(wire)));
        debug_assert_eq!(id, GUIDEWIRE);
        let surface = WallSurface::new(self.vessel());
        self.wall.add_wire(law, puncture_n, n, surface);
        self
    }

    /// One step of `dt_s` (step number `step`) under the devices' drives (the wire's, when
    /// there is a wire); the world's events (a quarantined model) go to `events`.
    pub fn step(
        &mut self,
        (drive, wire_drive): (&Drive, &WireDrive),
        dt_s: f32,
        step: u64,
        events: &mut Vec<EventKind>,
    ) -> StepOutcome {
        if let Skeleton::Catheter(c) = self.world.model_mut(CATHETER) {
            c.drive = *drive;
        }
        if self.has_wire()
            && let Skeleton::Guidewire(w) = self.world.model_mut(GUIDEWIRE)
        {
            w.drive = *wire_drive;
        }
        self.world.step_coupled(dt_s, step, events, &mut self.wall);
        self.wall.out.clone()
    }

    /// What the last step did to the wire (all zero without one).
    pub fn wire_outcome(&self) -> &WireOutcome {
        &self.wall.wire_out
    }

    pub fn catheter(&self) -> &Catheter {
        match self.world.model(CATHETER) {
            Skeleton::Catheter(c) => &c.catheter,
            _ => unreachable!("model 0 is the catheter"),
        }
    }

    pub fn vessel(&self) -> &Vessel {
        match self.world.model(VESSEL) {
            Skeleton::Vessel(v) => &v.vessel,
            _ => unreachable!("model 1 is the vessel"),
        }
    }

    fn has_wire(&self) -> bool {
        self.world.len() > GUIDEWIRE.index()
    }

    /// The guidewire, when the scene has one.
    pub fn guidewire(&self) -> Option<&Guidewire> {
        if !self.has_wire() {
            return None;
        }
        match self.world.model(GUIDEWIRE) {
            Skeleton::Guidewire(w) => Some(&w.wire),
            _ => None,
        }
    }

    /// The wire's contact law and puncture force, when there is a wire.
    pub fn wire_law(&self) -> Option<(ContactLaw, f64)> {
        self.wall.wire_law()
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

    /// Wall-clock seconds stepping the catheter, the vessel, the collision (with the contact
    /// forces and the lumen) and the guidewire when there is one, benchmarks only.
    pub fn times(&self) -> Vec<f64> {
        let t = self.world.model_times();
        let mut out = vec![t[0], t[1], self.world.coupling_time()];
        out.extend(t.get(GUIDEWIRE.index()));
        out
    }

    /// A digest of the balls' places and speeds and the holes, for replay checks.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        let balls = [&self.catheter().balls, &self.vessel().balls]
            .into_iter()
            .chain(self.guidewire().map(|w| &w.balls));
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
