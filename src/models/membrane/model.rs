//! The membrane as one model of a world: a step is [`Membrane::advance`] at the substep
//! safety set for it; the quarantine checks the awake tiles' nodes (the only ones a step
//! changes) and rolls back the nodes, the springs (cuts) and the released marks.

use super::{LAYERS, Membrane};
use crate::sim::{
    Collider, Contact, EventKind, MassSpring, ModelOutput, ModelSizes, ModelSnapshot, SurfaceRole,
    TissueModel,
};
use glam::Vec3;

/// The share of the explicit stability limit a substep takes unless set.
pub(super) const SUBSTEP_SAFETY: f32 = 0.9;

impl Membrane {
    /// The share of the explicit limit each substep of a world's step takes, in (0, 1].
    pub fn set_substep_safety(&mut self, safety: f32) {
        self.substep_safety = safety;
    }

    /// Explicit substeps the last step of a world took.
    pub fn last_substeps(&self) -> usize {
        self.last_substeps
    }

    /// Whether the positions of layer `l`, row `i`, columns `c[0]..c[1]` are finite (the
    /// state's row blocks: x, y, z, then the velocities).
    fn positions_finite(&self, l: usize, i: usize, c: [usize; 2]) -> bool {
        let b = l * self.rows + i;
        (0..3).all(|f| {
            let at = (b * 6 + f) * self.cols;
            // Branch-free (an OR over exponent tests), so it runs as vector code: this
            // is checked over every awake node each step.
            let bad = self.state.data[at + c[0]..at + c[1]]
                .iter()
                .fold(0u32, |acc, v| {
                    acc | u32::from(v.to_bits() & 0x7f80_0000 == 0x7f80_0000)
                });
            bad == 0
        })
    }

    /// The membrane's sheets as triangles over each layer's grid (the procedure draws the
    /// membrane in its own way; this is what a generic view of the world shows).
    fn sheets(&self) -> ModelSnapshot {
        let positions: Vec<Vec3> = (0..self.len()).map(|n| self.carried_position(n)).collect();
        let (rows, cols) = (self.rows, self.cols);
        let wrap = if self.periodic { cols } else { cols - 1 };
        let mut indices = Vec::with_capacity(LAYERS * (rows - 1) * wrap * 6);
        for l in 0..LAYERS {
            for i in 0..rows - 1 {
                for j in 0..wrap {
                    let j1 = (j + 1) % cols;
                    let n = |i: usize, j: usize| self.node(l, i, j) as u32;
                    indices.extend([n(i, j), n(i + 1, j), n(i, j1)]);
                    indices.extend([n(i, j1), n(i + 1, j), n(i + 1, j1)]);
                }
            }
        }
        let mut normals = vec![Vec3::ZERO; positions.len()];
        for t in indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|k| positions[k as usize]);
            let f = (b - a).cross(c - a);
            for k in t {
                normals[*k as usize] += f;
            }
        }
        normals
            .iter_mut()
            .for_each(|n| *n = n.normalize_or(Vec3::Y));
        let triangles = indices.len() / 3;
        ModelSnapshot {
            name: "membrane".to_string(),
            cut_edge: vec![false; positions.len()],
            positions,
            normals,
            indices,
            regions: vec![0; triangles],
            roles: vec![SurfaceRole::Tissue],
            seared: Vec::new(),
        }
    }
}

impl TissueModel for Membrane {
    fn name(&self) -> &str {
        "membrane"
    }

    fn kind(&self) -> &'static str {
        "mass_spring_4_layer"
    }

    fn sizes(&self) -> ModelSizes {
        ModelSizes {
            vertices: self.len(),
            triangles: 0,
            constraints: self.springs(),
        }
    }

    /// Tools reach the membrane through their procedure's coupling (it presses and cuts
    /// nodes in its own terms), so contacts are not read here.
    fn step(&mut self, dt_s: f32, _contacts: &[Contact], out: &mut ModelOutput) {
        let before = self.activity.as_ref().map(|a| a.awake_share);
        self.last_substeps = self.advance(dt_s, self.substep_safety);
        if let Some(reason) = self.take_device_note() {
            out.events.push(EventKind::ComputeFallback {
                model: self.name().to_string(),
                reason,
            });
        }
        self.last_share = match (before, &self.activity) {
            (Some(b), Some(a)) => (a.awake_share - b) as f32,
            _ => 1.0,
        };
    }

    /// None that rays or tools meet: the nodes are points in a grid, pressed by the
    /// procedure's coupling.
    fn collider(&self) -> Collider<'_> {
        Collider::none()
    }

    fn render_mesh(&mut self) -> ModelSnapshot {
        self.catch_up();
        self.sheets()
    }

    /// The tiles that changed since the last checkpoint (`checkpoint.rs`), brought up to date
    /// from the device first unless the step before brought those lagging on the CPU into
    /// the checkpoint's copy.
    fn checkpoint(&mut self) {
        if !self.saved_holds_lagging() {
            self.catch_up();
        }
        self.save();
    }

    /// A frame follows the next step: every awake tile comes back with it, to the readback,
    /// where the frame reads the drawn nodes of the tiles the CPU lags, with no round trip
    /// (see `device_lazy.rs`).
    fn read_whole_after_step(&mut self) {
        self.device.read_whole_next();
    }

    /// A checkpoint follows the next step: the tiles it would leave lagging on the CPU come
    /// back with it into the checkpoint's copy, not the CPU's, so the checkpoint neither
    /// waits for them nor copies them twice.
    fn checkpoint_follows(&mut self) {
        self.device.checkpoint_next();
    }

    fn restore(&mut self) {
        if let Some(a) = &mut self.activity {
            a.measured_finite = None;
        }
        self.load();
        self.external.clear();
        self.device.stale();
    }

    /// The positions of the awake tiles' nodes (a sleeping tile's nodes do not change), all
    /// of them without an active set or with every tile kept awake. Positions alone suffice:
    /// every substep moves each node by its velocity, so a non-finite velocity makes its
    /// position non-finite in the same step. The last sleep check measured them (on the
    /// device where it stepped them: no pass over the nodes here) unless the model changed
    /// since.
    fn state_is_finite(&self) -> bool {
        let Some(a) = self.activity.as_ref().filter(|a| !a.all_awake) else {
            return (0..LAYERS)
                .all(|l| (0..self.rows).all(|i| self.positions_finite(l, i, [0, self.cols])));
        };
        if let Some(finite) = a.measured_finite {
            return finite;
        }
        (0..a.awake.len()).filter(|&t| a.awake[t]).all(|t| {
            let ([r0, r1], cols) = a.span(t, self.rows, self.cols);
            (0..LAYERS).all(|l| (r0..r1).all(|i| self.positions_finite(l, i, cols)))
        })
    }

    fn state_hash(&self) -> u64 {
        Membrane::state_hash(self)
    }

    /// A NaN velocity on a node of layer 1 in the first awake tile (the first tile, woken,
    /// if none is), where the next step meets it.
    fn inject_nan(&mut self) -> bool {
        let awake = self
            .activity
            .as_ref()
            .map(|a| a.awake.iter().position(|&w| w));
        let t = match awake {
            Some(Some(t)) => t,
            Some(None) => {
                self.wake(0);
                0
            }
            None => 0,
        };
        let ([r0, _], [c0, _]) = self.tile_span(t);
        let b = self.rows + r0;
        self.catch_up();
        // Written here, not on a device: it goes up whole; the last check no longer holds.
        self.device.stale();
        self.all_changed();
        if let Some(a) = &mut self.activity {
            a.measured_finite = None;
        }
        match self.state.data.get_mut((b * 6 + 3) * self.cols + c0) {
            Some(v) => {
                *v = f32::NAN;
                true
            }
            None => false,
        }
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![("membrane", self.heap_bytes())]
    }

    fn mass_spring(&self) -> MassSpring {
        MassSpring {
            nodes: Some(self.len()),
            springs: Some(self.springs()),
            integrator: Some(self.params.integrator.name()),
            substeps: Some(self.last_substeps),
            step_limit_s: Some(self.step_limit),
        }
    }

    fn awake_fraction(&self) -> f32 {
        self.last_share
    }

    fn gpu_adapter(&self) -> Option<String> {
        Membrane::gpu_adapter(self)
    }

    fn stay_awake(&mut self) {
        Membrane::stay_awake(self);
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        ((i as usize) < self.len()).then(|| self.position(i as usize))
    }
}
