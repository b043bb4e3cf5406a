//! The particle solver stepped on a GPU inside a world ([`ParticlesGpu`]): the CPU keeps the
//! model (the particles as of the last step, the outcome, checkpoints, the hash) and the
//! device runs the step's substeps and sweeps; after each step the particles and the
//! clusters' frames come back in one round trip, so the CPU always holds the newest state.
//!
//! The device's kernels step shape matching, the ties, the cloth (its edges and hinges colour
//! by colour, as the CPU takes them), gravity, point damping and the floor; a solver with
//! other constraint sets is refused with an error naming them ([`ParticleSolver::use_gpu`]).
//! A cut sends the constraints left up before the next device step.
//! A step with an instrument set runs on the CPU (the kernels hold no instruments yet) from
//! the clusters' state read back with it, and the next device step sends everything up
//! again, as after a rollback.
//!
//! Should the device fail (lost, out of memory, a command refused), the step runs on the
//! CPU from the state the CPU holds, which the failed step has not touched, the device is
//! dropped and the failure is reported once: the session goes on.

use super::gpu::{Constraints, ParticlesGpu, Set, Stepping};
use super::solver::{HandTool, ParticleSolver};
use crate::gpu::{Gpu, RenderError};

/// The solver's place on a device, or none. A clone runs on the CPU (two models must not
/// share one device's buffers).
#[derive(Default)]
pub(super) struct Slot {
    on: Option<Box<ParticlesGpu>>,
    /// The CPU changed the model since the device last stepped it: everything goes up first.
    stale: bool,
    /// A cut removed constraints: they go up before the next device step.
    constraints_changed: bool,
    /// Why the device was given up, until the model reports it.
    note: Option<String>,
}

impl Clone for Slot {
    fn clone(&self) -> Self {
        Slot::default()
    }
}

impl std::fmt::Debug for Slot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.on {
            Some(d) => write!(f, "on {}", d.gpu().describe()),
            None => f.write_str("on the CPU"),
        }
    }
}

impl Slot {
    /// The CPU rewrote the particles or the clusters: they go up with the next device step.
    pub fn stale(&mut self) {
        self.stale = true;
    }

    /// A cut changed the constraints: they go up with the next device step.
    pub fn constraints_changed(&mut self) {
        self.constraints_changed = true;
    }
}

impl ParticleSolver {
    /// The ties and the cloth as the device takes them.
    fn constraints(&self) -> Constraints<'_> {
        let (ties, tie_colours) = self.ties();
        let (edge_colours, hinge_colours) = self.cloth.colours();
        let (edge_compliance, hinge_compliance) = self.cloth.compliances();
        Constraints {
            ties: Set {
                items: ties,
                colours: tie_colours,
                compliance: 1.0 / self.params.tie_stiffness_n_per_m.max(1e-9),
            },
            edges: Set {
                items: self.cloth.stretch_constraints(),
                colours: edge_colours,
                compliance: edge_compliance,
            },
            hinges: Set {
                items: self.cloth.bend_constraints(),
                colours: hinge_colours,
                compliance: hinge_compliance,
            },
        }
    }

    /// What this solver holds that the GPU's kernels do not step, one phrase each (empty:
    /// the device can take it).
    pub fn gpu_unsupported(&self) -> Vec<String> {
        let mut out = Vec::new();
        let chain_segments: usize = (0..self.chains.chains())
            .map(|c| self.chains.segments(c))
            .sum();
        let mut add = |n: usize, what: &str| {
            if n > 0 {
                out.push(format!("{n} {what}"));
            }
        };
        add(chain_segments, "chain segments");
        add(
            self.adhesion.segments() + self.bonds.segments(),
            "strand segments",
        );
        add(self.contacts.members(), "particles in body contacts");
        out
    }

    /// Steps this solver on `gpu` from now on (see `device.rs`). An error names what the
    /// device refused or what the kernels do not step; the solver stays on the CPU.
    pub fn use_gpu(&mut self, gpu: &Gpu) -> Result<(), RenderError> {
        let missing = self.gpu_unsupported();
        if !missing.is_empty() {
            return Err(RenderError::Unsupported(format!(
                "the particle solver's kernels step shape matching, ties, cloth, gravity, \
                 damping and the floor; this world also has {}",
                missing.join(", ")
            )));
        }
        let k = ParticlesGpu::new(gpu, &self.particles, &self.shape, &self.constraints())?;
        self.device = Slot {
            on: Some(Box::new(k)),
            stale: false,
            constraints_changed: false,
            note: None,
        };
        Ok(())
    }

    /// The adapter the solver steps on; none on the CPU.
    pub fn gpu_adapter(&self) -> Option<String> {
        self.device.on.as_ref().map(|d| d.gpu().describe())
    }

    /// Destroys the device under the solver, as a driver reset would (fault injection: the
    /// next step must fall back to the CPU). False when on the CPU.
    pub fn inject_device_loss(&mut self) -> bool {
        match &self.device.on {
            Some(d) => {
                d.gpu().device.destroy();
                true
            }
            None => false,
        }
    }

    /// Why the device was given up, once (the owner reports it as an event).
    pub fn take_device_note(&mut self) -> Option<String> {
        self.device.note.take()
    }
}

/// Whether the next step can run on the device (it has one, and no instrument is set).
pub(super) fn can_step(s: &ParticleSolver, tools: &[Option<HandTool>; 2]) -> bool {
    s.device.on.is_some() && tools.iter().all(Option::is_none)
}

/// One step of `dt_s` on the device; false where it has none or it failed (noted, the device
/// dropped, the external forces left for the CPU, whose particles the failed step did not
/// touch). Before a CPU step, call [`before_cpu_step`].
pub(super) fn step(s: &mut ParticleSolver, dt_s: f32) -> bool {
    let Some(mut d) = s.device.on.take() else {
        return false;
    };
    let external = s.particles.ext.clone();
    let how = Stepping {
        dt_s,
        substeps: s.params.substeps.max(1),
        iterations: s.params.iterations.max(1),
        gravity_m_per_s2: s.params.gravity_m_per_s2,
        damping_per_s: s.params.damping_per_s,
        floor_y_m: Some(s.params.floor_y_m),
    };
    if s.device.stale {
        d.upload(&s.particles);
        d.upload_shape(&s.shape);
    }
    if s.device.constraints_changed
        && let Err(e) = d.set_constraints(&s.constraints())
    {
        s.device.note = Some(e.to_string());
        return false;
    }
    let run = d
        .advance(&mut s.particles, &how, 1)
        .and_then(|()| d.download_all(&mut s.particles, &mut s.shape));
    match run {
        Ok(()) => {
            s.device.on = Some(d);
            s.device.stale = false;
            s.device.constraints_changed = false;
            true
        }
        Err(e) => {
            s.particles.ext = external;
            s.device.note = Some(e.to_string());
            false
        }
    }
}

/// Before a step the CPU runs while the solver has a device: the CPU holds the newest state
/// (each device step reads the particles and the clusters back), and after the CPU's step the
/// device's is old.
pub(super) fn before_cpu_step(s: &mut ParticleSolver) {
    s.device.stale();
}
