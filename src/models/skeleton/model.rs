//! The catheter, the guidewire and the vessel wall as models of a world. The catheter and
//! the wire take the substeps of their stage under their drives and the forces their
//! coupling sets before each ([`super::wall::WallContact`]: the wall's contact, and the
//! lumen's hold between the two); the vessel takes one step with the reaction gathered over
//! them. Each checkpoint keeps the model's whole moving state (balls, and the catheter's
//! twist, frames and bend, the wire's tip curve).

use super::Balls;
use super::catheter::{Catheter, Drive};
use super::guidewire::{Guidewire, WireDrive};
use super::vessel::Vessel;
use crate::sim::{
    Collider, Contact, Fnv, MassSpring, ModelOutput, ModelSizes, ModelSnapshot, SurfaceRole,
    TissueModel,
};
use glam::{DVec3, Vec3};

crate::tissue_models! {
    /// The skeleton-spring models: the catheter, the vessel wall and the guidewire.
    pub enum Skeleton {
        Catheter(CatheterModel),
        Vessel(VesselModel),
        Guidewire(GuidewireModel),
    }
}

/// The catheter, its drive and the contact forces for its next substep.
pub struct CatheterModel {
    pub catheter: Catheter,
    pub drive: Drive,
    /// The wall's force on each ball for the next substep, N.
    pub contact: Vec<DVec3>,
    /// The substep, s, set by the coupling from the world's step in f64 (the step's
    /// `f32` over the substeps would round differently).
    pub substep_s: f64,
    saved: Option<Box<Catheter>>,
}

impl CatheterModel {
    pub fn new(catheter: Catheter) -> CatheterModel {
        let n = catheter.balls.len();
        CatheterModel {
            catheter,
            drive: Drive::default(),
            contact: vec![DVec3::ZERO; n],
            substep_s: 0.0,
            saved: None,
        }
    }
}

/// The guidewire, its drive and the forces for its next substep.
pub struct GuidewireModel {
    pub wire: Guidewire,
    pub drive: WireDrive,
    /// The wall's and the lumen's force on each ball for the next substep, N.
    pub contact: Vec<DVec3>,
    /// The substep, s, set by the coupling (as the catheter's).
    pub substep_s: f64,
    saved: Option<Box<Guidewire>>,
}

impl GuidewireModel {
    pub fn new(wire: Guidewire) -> GuidewireModel {
        let n = wire.balls.len();
        GuidewireModel {
            wire,
            drive: WireDrive::default(),
            contact: vec![DVec3::ZERO; n],
            substep_s: 0.0,
            saved: None,
        }
    }
}

/// The vessel wall and the catheter's mean reaction on it over the last stage.
pub struct VesselModel {
    pub vessel: Vessel,
    /// The force on each wall ball for the next step, N.
    pub external: Vec<DVec3>,
    /// The balls' places and speeds at the last checkpoint (the rest of the wall never
    /// changes).
    saved: (Vec<DVec3>, Vec<DVec3>),
}

impl VesselModel {
    pub fn new(vessel: Vessel) -> VesselModel {
        let n = vessel.balls.len();
        VesselModel {
            external: vec![DVec3::ZERO; n],
            saved: (vessel.balls.x.clone(), vessel.balls.v.clone()),
            vessel,
        }
    }
}

fn hash_balls(h: &mut Fnv, b: &Balls) {
    for (x, v) in b.x.iter().zip(&b.v) {
        for c in x.to_array().into_iter().chain(v.to_array()) {
            let bits = c.to_bits();
            h.write(bits as u32);
            h.write((bits >> 32) as u32);
        }
    }
}

/// Whether every ball's place is finite: a step moves each ball by its speed (semi-implicit
/// Euler, speeds first), so a non-finite speed makes its place non-finite in the same step.
fn finite(b: &Balls) -> bool {
    b.x.iter().all(|p| p.is_finite())
}

/// The balls as points (what a generic view of the world shows; the procedure draws the
/// tubes).
fn points(name: &str, b: &Balls) -> ModelSnapshot {
    let positions: Vec<Vec3> = b.x.iter().map(|p| p.as_vec3()).collect();
    ModelSnapshot {
        name: name.to_string(),
        normals: vec![Vec3::Y; positions.len()],
        cut_edge: vec![false; positions.len()],
        positions,
        roles: vec![SurfaceRole::Tissue],
        ..ModelSnapshot::default()
    }
}

impl TissueModel for CatheterModel {
    fn name(&self) -> &str {
        "catheter"
    }

    fn kind(&self) -> &'static str {
        "skeleton_springs"
    }

    fn sizes(&self) -> ModelSizes {
        let c = &self.catheter;
        ModelSizes {
            vertices: c.balls.len(),
            triangles: 0,
            constraints: c.springs.len() + c.angles.len(),
        }
    }

    fn mass_spring(&self) -> MassSpring {
        MassSpring {
            nodes: Some(self.catheter.balls.len()),
            springs: Some(self.catheter.springs.len() + self.catheter.angles.len()),
            integrator: Some("semi_implicit_euler"),
            ..MassSpring::default()
        }
    }

    /// One substep under the drive and the contact forces the coupling set.
    fn step(&mut self, _dt_s: f32, _contacts: &[Contact], _out: &mut ModelOutput) {
        self.catheter
            .step(&self.drive, &self.contact, self.substep_s);
    }

    fn collider(&self) -> Collider<'_> {
        Collider::none()
    }

    fn render_mesh(&mut self) -> ModelSnapshot {
        points("catheter", &self.catheter.balls)
    }

    fn checkpoint(&mut self) {
        match &mut self.saved {
            Some(s) => (**s).clone_from(&self.catheter),
            None => self.saved = Some(Box::new(self.catheter.clone())),
        }
    }

    fn restore(&mut self) {
        if let Some(s) = &self.saved {
            self.catheter.clone_from(s);
        }
        self.contact.iter_mut().for_each(|f| *f = DVec3::ZERO);
    }

    fn state_is_finite(&self) -> bool {
        finite(&self.catheter.balls) && self.catheter.twist.iter().all(|t| t.is_finite())
    }

    /// The balls' places and speeds, then the twist.
    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        hash_balls(&mut h, &self.catheter.balls);
        for t in &self.catheter.twist {
            let bits = t.to_bits();
            h.write(bits as u32);
            h.write((bits >> 32) as u32);
        }
        h.0
    }

    /// A NaN speed on the head ball.
    fn inject_nan(&mut self) -> bool {
        match self.catheter.balls.v.last_mut() {
            Some(v) => {
                v.x = f64::NAN;
                true
            }
            None => false,
        }
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![("catheter", 80 * self.catheter.balls.len())]
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        self.catheter.balls.x.get(i as usize).map(|p| p.as_vec3())
    }
}

impl TissueModel for GuidewireModel {
    fn name(&self) -> &str {
        "guidewire"
    }

    fn kind(&self) -> &'static str {
        "skeleton_springs"
    }

    fn sizes(&self) -> ModelSizes {
        let w = &self.wire;
        ModelSizes {
            vertices: w.balls.len(),
            triangles: 0,
            constraints: w.springs.len() + w.angles.len(),
        }
    }

    fn mass_spring(&self) -> MassSpring {
        MassSpring {
            nodes: Some(self.wire.balls.len()),
            springs: Some(self.wire.springs.len() + self.wire.angles.len()),
            integrator: Some("semi_implicit_euler"),
            ..MassSpring::default()
        }
    }

    /// One substep under the drive and the forces the coupling set.
    fn step(&mut self, _dt_s: f32, _contacts: &[Contact], _out: &mut ModelOutput) {
        self.wire.step(&self.drive, &self.contact, self.substep_s);
    }

    fn collider(&self) -> Collider<'_> {
        Collider::none()
    }

    fn render_mesh(&mut self) -> ModelSnapshot {
        points("guidewire", &self.wire.balls)
    }

    fn checkpoint(&mut self) {
        match &mut self.saved {
            Some(s) => (**s).clone_from(&self.wire),
            None => self.saved = Some(Box::new(self.wire.clone())),
        }
    }

    fn restore(&mut self) {
        if let Some(s) = &self.saved {
            self.wire.clone_from(s);
        }
        self.contact.iter_mut().for_each(|f| *f = DVec3::ZERO);
    }

    fn state_is_finite(&self) -> bool {
        finite(&self.wire.balls)
    }

    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        hash_balls(&mut h, &self.wire.balls);
        h.0
    }

    /// A NaN speed on the tip ball.
    fn inject_nan(&mut self) -> bool {
        match self.wire.balls.v.last_mut() {
            Some(v) => {
                v.x = f64::NAN;
                true
            }
            None => false,
        }
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![("guidewire", 80 * self.wire.balls.len())]
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        self.wire.balls.x.get(i as usize).map(|p| p.as_vec3())
    }
}

impl TissueModel for VesselModel {
    fn name(&self) -> &str {
        "vessel"
    }

    fn kind(&self) -> &'static str {
        "skeleton_springs"
    }

    fn sizes(&self) -> ModelSizes {
        ModelSizes {
            vertices: self.vessel.balls.len(),
            triangles: 0,
            constraints: self.vessel.springs.len(),
        }
    }

    fn mass_spring(&self) -> MassSpring {
        MassSpring {
            nodes: Some(self.vessel.balls.len()),
            springs: Some(self.vessel.springs.len()),
            integrator: Some("semi_implicit_euler"),
            ..MassSpring::default()
        }
    }

    /// One step under the catheter's mean reaction over its substeps.
    fn step(&mut self, dt_s: f32, _contacts: &[Contact], _out: &mut ModelOutput) {
        self.vessel.step(&self.external, f64::from(dt_s));
    }

    fn collider(&self) -> Collider<'_> {
        Collider::none()
    }

    fn render_mesh(&mut self) -> ModelSnapshot {
        points("vessel", &self.vessel.balls)
    }

    fn checkpoint(&mut self) {
        self.saved.0.clone_from(&self.vessel.balls.x);
        self.saved.1.clone_from(&self.vessel.balls.v);
    }

    fn restore(&mut self) {
        self.vessel.balls.x.clone_from(&self.saved.0);
        self.vessel.balls.v.clone_from(&self.saved.1);
    }

    fn state_is_finite(&self) -> bool {
        finite(&self.vessel.balls)
    }

    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        hash_balls(&mut h, &self.vessel.balls);
        h.0
    }

    /// A NaN speed on the first free wall ball.
    fn inject_nan(&mut self) -> bool {
        let b = &mut self.vessel.balls;
        match b.fixed.iter().position(|f| !f) {
            Some(k) => {
                b.v[k].x = f64::NAN;
                true
            }
            None => false,
        }
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![("vessel", 96 * self.vessel.balls.len())]
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        self.vessel.balls.x.get(i as usize).map(|p| p.as_vec3())
    }
}
