//! Palpation of a boundary-element surface as one model of a world. Its owner sets the
//! instrument tips (spheres and shafts, with their grasps) before each step; the step is one
//! palpation update at those tips. The contacts' state (set, factors, tractions, the
//! relaxation's memory) and the grasps are what a checkpoint keeps.

use super::palpation::{Palpation, PalpationState, Tip, Touch};
use crate::sim::{
    Collider, Contact, Fnv, ModelOutput, ModelSizes, ModelSnapshot, SurfaceRole, TissueModel,
    ToolId,
};
use glam::{DVec3, Vec3};

/// A boundary-element surface pressed and held by instrument tips.
pub struct Palpated {
    name: String,
    palpation: Palpation,
    /// This step's tips, whether each grasps, and the tool each belongs to.
    tips: Vec<Tip>,
    grasp: Vec<bool>,
    owners: Vec<ToolId>,
    /// What the last update found at each tip; whether it failed (the capacitance solve
    /// refused: the instruments felt nothing that step).
    touches: Vec<Touch>,
    failed: bool,
    saved: PalpationState,
    /// The resting centroids, f32, for the generic view of the world.
    centroids: Vec<Vec3>,
}

impl Palpated {
    pub fn new(name: &str, palpation: Palpation) -> Palpated {
        let centroids = (0..palpation.len())
            .map(|e| palpation.rest(e).as_vec3())
            .collect();
        Palpated {
            name: name.to_string(),
            palpation,
            tips: Vec::new(),
            grasp: Vec::new(),
            owners: Vec::new(),
            touches: Vec::new(),
            failed: false,
            saved: PalpationState::default(),
            centroids,
        }
    }

    pub fn palpation(&self) -> &Palpation {
        &self.palpation
    }

    /// The tips for the next step: each with whether it grasps and its tool.
    pub fn set_tips(&mut self, tips: &[(Tip, bool, ToolId)]) {
        self.tips.clear();
        self.grasp.clear();
        self.owners.clear();
        for &(t, g, o) in tips {
            self.tips.push(t);
            self.grasp.push(g);
            self.owners.push(o);
        }
    }

    /// What the last step found at each tip (in [`Palpated::set_tips`]' order), taken out of
    /// the model; none when it failed.
    pub fn take_touches(&mut self) -> Option<Vec<Touch>> {
        let touches = std::mem::take(&mut self.touches);
        (!self.failed).then_some(touches)
    }
}

impl TissueModel for Palpated {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> &'static str {
        "boundary_elements"
    }

    fn sizes(&self) -> ModelSizes {
        ModelSizes {
            vertices: self.palpation.len(),
            triangles: 0,
            constraints: self.palpation.contacts.set().len(),
        }
    }

    /// One palpation update at the tips set for it (the world's contacts are not read: the
    /// tips carry their shafts and grasps). Each tool is pushed back by minus what the
    /// tissue takes from its tips.
    fn step(&mut self, dt_s: f32, _contacts: &[Contact], out: &mut ModelOutput) {
        match self
            .palpation
            .update_tips(&self.tips, &self.grasp, f64::from(dt_s))
        {
            Ok(t) => {
                self.touches = t;
                self.failed = false;
            }
            Err(_) => {
                self.touches.clear();
                self.failed = true;
            }
        }
        for tool in ToolId::BOTH {
            let f = self
                .owners
                .iter()
                .zip(&self.touches)
                .filter(|(o, _)| **o == tool)
                .fold(DVec3::ZERO, |acc, (_, t)| acc + t.force_n);
            if f != DVec3::ZERO {
                out.reactions.push((tool, (-f).as_vec3()));
            }
        }
    }

    /// None that rays meet: instruments reach the wall through their tips.
    fn collider(&self) -> Collider<'_> {
        Collider::none()
    }

    /// The elements' resting centroids (the procedure draws the surface itself).
    fn render_mesh(&mut self) -> ModelSnapshot {
        ModelSnapshot {
            name: self.name.clone(),
            positions: self.centroids.clone(),
            normals: vec![Vec3::Y; self.centroids.len()],
            cut_edge: vec![false; self.centroids.len()],
            roles: vec![SurfaceRole::Tissue],
            ..ModelSnapshot::default()
        }
    }

    fn checkpoint(&mut self) {
        self.palpation.save(&mut self.saved);
    }

    fn restore(&mut self) {
        self.palpation.load(&self.saved);
        self.touches.clear();
    }

    fn state_is_finite(&self) -> bool {
        self.palpation.contacts.is_finite()
            && self
                .touches
                .iter()
                .all(|t| t.force_n.is_finite() && t.depth_m.is_finite())
    }

    /// The contact set and its tractions.
    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        self.palpation.contacts.digest(&mut h);
        h.0
    }

    /// A NaN in the contacts' tractions and memory (nothing when no element is held: there
    /// is no contact state to spoil).
    fn inject_nan(&mut self) -> bool {
        self.palpation.contacts.inject_nan()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![(
            "palpation",
            self.centroids.capacity() * std::mem::size_of::<Vec3>(),
        )]
    }
}
