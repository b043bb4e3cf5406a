//! The particle solver stepped on a GPU inside a world ([`ParticlesGpu`]): the CPU keeps the
//! model (the particles as of the last step, the outcome, checkpoints, the hash) and the
//! device runs the step's substeps and sweeps; after each substep the particles' positions
//! and velocities come back (one round trip a submission), so the CPU holds the newest
//! particles. The clusters' centres and rotations stay on the device: they come back only
//! before the CPU steps them itself, and where the device is lost by then, the CPU's step
//! finds every rotation again from a cold start.
//!
//! The device's kernels step shape matching, the vessels' chains, the ties, the cloth (its
//! edges and hinges), the strands (each set colour by colour, as the CPU takes them; in one
//! dispatch a sweep where the levels of `gpu_schedule.rs` fit one workgroup), the contacts
//! between bodies (their candidate pairs searched on the CPU before each
//! substep, from the positions the prediction will give, and coloured), gravity, point
//! damping and the floor. A cut, a tear or a weakened strand sends the constraints up
//! again before the next device substep, a new search its pairs alone. The strands'
//! weakening and tearing run on the CPU after each substep, from the particles read back,
//! as the CPU's own substep runs them. The instruments go up with each step: a grasp taken on
//! the CPU at the step's start (from the particles it holds, as the CPU's first substep takes
//! it) and then held by the device's springs, or an instrument's cylinders pushing; their
//! sums come back with the particles, and the reactions are made from them as the CPU makes
//! them. An instrument the kernels cannot take (more cylinders or radius samples than they
//! hold) runs that step on the CPU, and the next device step sends everything up again, as
//! after a rollback.
//!
//! Should the device fail (lost, out of memory, a command refused), the step runs on the
//! CPU from the state the CPU holds, which the failed step has not touched, the device is
//! dropped and the failure is reported once: the session goes on.

use super::contacts::PUSH_LIST_MARGIN_M;
use super::gpu::{Constraints, Later, ParticlesGpu, Set, Stepping, Sweeps};
use super::gpu_tools::DeviceTool;
use super::solver::{HandTool, ParticleSolver, StepOutcome};
use crate::gpu::{Gpu, RenderError};

/// The solver's place on a device, or none. A clone runs on the CPU (two models must not
/// share one device's buffers).
#[derive(Default)]
pub(super) struct Slot {
    on: Option<Box<ParticlesGpu>>,
    /// The CPU changed the model since the device last stepped it: everything goes up first.
    stale: bool,
    /// What the constraints on the device were made from ([`signature`]): a cut, a tear or a
    /// weakened strand changes it, and the constraints go up again.
    uploaded: Signature,
    /// The contacts' searches when their pairs last went up.
    searched: u64,
    /// Why the device was given up, until the model reports it.
    note: Option<String>,
    /// The device's own time for the substeps so far, seconds (where it has timestamps).
    kernel_s: f64,
    /// Run each substep in a submission of its own, never two ahead (for comparisons).
    one_by_one: bool,
    /// Steps whose second substep ran ahead in the first's submission: kept, and run again
    /// because something fell between the two.
    ahead: [u64; 2],
    /// The second substep of a split submission while the first is checked.
    later: Later,
    /// Submissions so far.
    submissions: u64,
    /// Whether something fell between the last step's substeps (its next runs one by one).
    missed: bool,
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
}

impl ParticleSolver {
    /// The clusters' centres, rotations and goal frames from the device, where it stepped them
    /// on from the CPU's (each substep reads only the particles back). Where the device cannot
    /// give them, the CPU's next step starts every rotation cold.
    pub(crate) fn read_device_clusters(&mut self) {
        if let (Some(d), true) = (&self.device.on, self.shape.is_behind())
            && let Err(e) = d.download_clusters(&mut self.shape)
        {
            tracing::warn!("the particle solver's clusters could not be read back: {e}");
        }
    }

    /// The ties and the cloth as the device takes them.
    fn constraints(&self) -> Constraints<'_> {
        let (ties, tie_colours) = self.ties();
        let (edge_colours, hinge_colours) = self.cloth.colours();
        let (edge_compliance, hinge_compliance) = self.cloth.compliances();
        let (pairs, pair_colours) = self.contacts.pairs_by_colour();
        Constraints {
            pairs,
            pair_colours,
            contact_distance_m: self.contacts.contact_distance_m(),
            vessels: self.chains.device_set(),
            adhesion: self.adhesion.device_set(),
            bonds: self.bonds.device_set(),
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

    /// Steps this solver on `gpu` from now on (see `device.rs`). An error names what the
    /// device refused; the solver stays on the CPU.
    pub fn use_gpu(&mut self, gpu: &Gpu) -> Result<(), RenderError> {
        self.use_gpu_with(gpu, Sweeps::Scheduled)
    }

    /// As [`ParticleSolver::use_gpu`], its sweeps dispatched as `sweeps` says.
    pub fn use_gpu_with(&mut self, gpu: &Gpu, sweeps: Sweeps) -> Result<(), RenderError> {
        let c = self.constraints();
        let k = ParticlesGpu::with_sweeps(gpu, &self.particles, &self.shape, &c, sweeps)?;
        self.device = Slot {
            on: Some(Box::new(k)),
            stale: false,
            uploaded: signature(self),
            searched: self.contacts.searches,
            note: None,
            kernel_s: 0.0,
            one_by_one: false,
            ahead: [0; 2],
            later: Later::default(),
            submissions: 0,
            missed: false,
        };
        Ok(())
    }

    /// The dispatches a device sweep takes for the constraint sets and the contacts, and
    /// their scheduled levels (`ParticlesGpu::sweep_dispatches`); none on the CPU.
    pub fn gpu_sweep_dispatches(&self) -> Option<(usize, [usize; 2])> {
        self.device.on.as_ref().map(|d| d.sweep_dispatches())
    }

    /// The dispatches a device substep takes (`ParticlesGpu::dispatches_per_substep`); none
    /// on the CPU.
    pub fn gpu_dispatches_per_substep(&self) -> Option<usize> {
        let d = self.device.on.as_ref()?;
        Some(d.dispatches_per_substep(self.params.iterations, true))
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

    /// The device's own time for the substeps it ran so far, seconds (0 on the CPU or
    /// without timestamp queries).
    pub fn gpu_kernel_seconds(&self) -> f64 {
        self.device.kernel_s
    }

    /// The fewest bytes a substep moves on the device (none on the CPU).
    pub fn gpu_bytes_per_substep(&self) -> Option<u64> {
        let sweeps = self.params.iterations;
        self.device.on.as_ref().map(|d| d.bytes_per_substep(sweeps))
    }

    /// Whether each device step with strands or contacts runs its first two substeps in one
    /// submission (the default: `device.rs`), or each substep in its own (`false`).
    pub fn gpu_step_ahead(&mut self, on: bool) {
        self.device.one_by_one = !on;
    }

    /// Of the device steps whose second substep ran ahead in the first's submission: how
    /// many kept it, and how many ran it again because a search, a weakened or torn strand
    /// fell between the two.
    pub fn gpu_ahead_counts(&self) -> [u64; 2] {
        self.device.ahead
    }

    /// The device submissions the solver made so far (each waits for its results).
    pub fn gpu_submissions(&self) -> u64 {
        self.device.submissions
    }

    /// Why the device was given up, once (the owner reports it as an event).
    pub fn take_device_note(&mut self) -> Option<String> {
        self.device.note.take()
    }
}

/// Whether the next step can run on the device (it has one, and the kernels can take each
/// instrument set).
pub(super) fn can_step(s: &ParticleSolver, tools: &[Option<HandTool>; 2]) -> bool {
    s.device.on.is_some()
        && tools
            .iter()
            .flatten()
            .all(|t| DeviceTool::fits(&t.instrument))
}

/// Each hand's instrument as the device takes it this step: its grasp where it holds
/// particles, otherwise its cylinders pushing.
fn device_tools<'a>(
    s: &'a ParticleSolver,
    tools: &'a [Option<HandTool>; 2],
) -> [DeviceTool<'a>; 2] {
    std::array::from_fn(|h| {
        let Some(t) = &tools[h] else {
            return DeviceTool::None;
        };
        match s.hand_state(h) {
            (Some(g), _) if !g.is_empty() => DeviceTool::Grasp {
                held: g.held(),
                jaw: t.jaw,
                stiffness_n_per_m: g.stiffness_n_per_m(),
            },
            (_, push) => DeviceTool::Push {
                instrument: &t.instrument,
                radius_m: push.radius_m(),
                margin_m: PUSH_LIST_MARGIN_M,
            },
        }
    })
}

/// What the constraints a sweep projects depend on that cuts, tears and weakening change: the
/// vessels' intact segments and bending springs, each strand set's weakened strands and broken
/// segments, the cloth's edges and hinges. (A contact search sends its pairs up alone.)
type Signature = [usize; 8];

fn signature(s: &ParticleSolver) -> Signature {
    let (segs, bends) = s.chains.intact_counts();
    let (aw, at) = s.adhesion.broken_counts();
    let (bw, bt) = s.bonds.broken_counts();
    [
        segs,
        bends,
        aw,
        at,
        bw,
        bt,
        s.cloth.edges(),
        s.cloth.hinges(),
    ]
}

/// The substeps of a step of `dt_s` on the device, the strands' weakening and tearing after
/// each (on the CPU, from the particles read back, as the CPU's substep does it; a solver
/// without strands or contacts runs all its substeps in one submission), under the step's
/// external forces `ext` (through every substep). Returns how many substeps ran: all of them,
/// or fewer where the device failed (noted, the device dropped): the CPU then runs the rest
/// from the last substep read back. Before a CPU step, call [`before_cpu_step`].
///
/// With strands or contacts, the first two substeps still go in one submission, split after
/// the first ([`ParticlesGpu::advance_split`]): both come back in one round trip, and the CPU
/// does with the first's particles what it does between substeps (the strands' update, the
/// next search's test). Where that changed nothing the device holds, the second substep is
/// the one the device would have run next, and it is kept; otherwise the first's state goes
/// up again and the second runs anew. Either way the bytes are those of a submission a
/// substep (tested).
pub(super) fn step(
    s: &mut ParticleSolver,
    dt_s: f32,
    tools: &[Option<HandTool>; 2],
    ext: Option<&[glam::Vec3]>,
    out: &mut StepOutcome,
) -> u32 {
    let Some(mut d) = s.device.on.take() else {
        return 0;
    };
    let _span = tracing::debug_span!("particles_gpu_step").entered();
    let prep = tracing::debug_span!("particles_gpu_prep").entered();
    let n = s.params.substeps.max(1);
    let strands = s.adhesion.segments() + s.bonds.segments() > 0;
    let contacts = s.contacts.members() > 0;
    let chunk = if strands || contacts { 1 } else { n };
    // The grasps the CPU's first substep would take, from the particles as they are.
    s.take_grasps(tools);
    let sub_dt = dt_s / n as f32;
    let pushing = [tools[0].is_some(), tools[1].is_some()];
    if let Err(e) = d.set_tools(&device_tools(s, tools), sub_dt, s.params.grasp_most) {
        s.device.note = Some(e.to_string());
        return 0;
    }
    let how = Stepping {
        dt_s: sub_dt * chunk as f32,
        substeps: chunk,
        iterations: s.params.iterations.max(1),
        gravity_m_per_s2: s.params.gravity_m_per_s2,
        damping_per_s: s.params.damping_per_s,
        floor_y_m: Some(s.params.floor_y_m),
    };
    let pair = Stepping {
        dt_s: sub_dt * 2.0,
        substeps: 2,
        ..how
    };
    // After a step whose second substep had to run again (an instrument dragging tissue
    // makes a search at nearly every substep), the next runs a submission a substep: the
    // same bytes, without a substep the device runs for nothing and its upload.
    let split = chunk == 1 && !s.device.one_by_one && !s.device.missed;
    let mut missed = false;
    if s.device.stale {
        d.upload(&s.particles);
        // Where the device stepped the clusters on from the CPU's, it holds the newest.
        if !s.shape.is_behind() {
            d.upload_shape(&s.shape);
        }
    }
    drop(prep);
    let mut done = 0;
    // Whether the next substep's forces and search are in place already.
    let mut ready = false;
    while done < n {
        if !ready {
            before_substep(s, ext, sub_dt, contacts);
            // Would a second substep run ahead have had to run again?
            let changed =
                signature(s) != s.device.uploaded || s.contacts.searches != s.device.searched;
            missed |= done > 0 && changed;
        }
        ready = false;
        let ahead = split && n - done >= 2;
        let totals = match run(s, &mut d, if ahead { &pair } else { &how }, ahead) {
            Ok(t) => t,
            Err(e) => {
                s.device.note = Some(e.to_string());
                return done;
            }
        };
        add_reactions(out, totals, pushing, sub_dt, n);
        done += chunk;
        after_substep(s, out, contacts, strands);
        if ahead {
            before_substep(s, ext, sub_dt, contacts);
            if signature(s) == s.device.uploaded && s.contacts.searches == s.device.searched {
                let _span = tracing::debug_span!("particles_gpu_later").entered();
                let totals = s.device.later.apply(&mut s.particles);
                // The device's submission took the forces, as `advance` takes them.
                s.particles.ext.fill(glam::Vec3::ZERO);
                add_reactions(out, totals, pushing, sub_dt, n);
                done += 1;
                after_substep(s, out, contacts, strands);
                s.device.ahead[0] += 1;
            } else {
                let _span = tracing::debug_span!("particles_gpu_rerun").entered();
                d.upload(&s.particles);
                d.upload_cluster_state(s.device.later.first_state());
                ready = true;
                missed = true;
                s.device.ahead[1] += 1;
            }
        }
    }
    for h in 0..2 {
        out.held[h] = s.hand_state(h).0.map_or(0, |g| g.len());
    }
    s.device.on = Some(d);
    s.device.stale = false;
    s.device.missed = missed;
    n
}

/// What the CPU does before each device substep: the step's external forces in place, and
/// the contacts' search where the particles moved far enough (the CPU's substep searches
/// from the predicted positions: formed here as the prediction forms them).
fn before_substep(s: &mut ParticleSolver, ext: Option<&[glam::Vec3]>, dt: f32, contacts: bool) {
    let _span = tracing::debug_span!("particles_before_substep").entered();
    if let Some(e) = ext {
        s.particles.ext.copy_from_slice(e);
    }
    if contacts {
        let p = &s.particles;
        let g = s.params.gravity_m_per_s2;
        s.contacts.refresh_by(&p.body, |i| predicted(p, i, dt, g));
    }
}

/// What the CPU does after each device substep, from the particles read back: the contacts
/// touching counted, the strands weakened and torn.
fn after_substep(s: &mut ParticleSolver, out: &mut StepOutcome, contacts: bool, strands: bool) {
    let _span = tracing::debug_span!("particles_after_substep").entered();
    if contacts {
        s.contacts.count_touching(&s.particles);
    }
    if strands {
        out.breaks.extend(s.adhesion.update(&s.particles));
        out.bond_breaks.extend(s.bonds.update(&s.particles));
    }
}

/// The constraints or the pairs up where they changed, then one submission as `how` says
/// (split after its first substep where `ahead`) and its results read back: the first
/// substep's (or the submission's) instruments' totals.
fn run(
    s: &mut ParticleSolver,
    d: &mut ParticlesGpu,
    how: &Stepping,
    ahead: bool,
) -> Result<[[f32; 4]; 2], RenderError> {
    let _span = tracing::debug_span!("particles_gpu_run").entered();
    let now = signature(s);
    if now != s.device.uploaded {
        d.set_constraints(&s.constraints())?;
        s.device.uploaded = now;
        s.device.searched = s.contacts.searches;
    } else if s.contacts.searches != s.device.searched {
        let (pairs, colours) = s.contacts.pairs_by_colour();
        d.set_pairs(&pairs, colours, s.contacts.contact_distance_m())?;
        s.device.searched = s.contacts.searches;
    }
    s.device.submissions += 1;
    let totals = if ahead {
        d.advance_split(&mut s.particles, how)?;
        d.download_split(&mut s.particles, &mut s.device.later)?
    } else {
        d.advance(&mut s.particles, how, 1)?;
        d.download_lean(&mut s.particles)?
    };
    s.shape.fall_behind();
    s.device.kernel_s += d.kernel_seconds()?.unwrap_or(0.0);
    Ok(totals)
}

/// The tissue's force on each instrument from a submission's totals: minus what it did to
/// the particles, as the CPU's `ToolPush::reaction_n` and `Grasp::reaction_n` make it,
/// averaged over the step's `n` substeps of `sub_dt`.
fn add_reactions(
    out: &mut StepOutcome,
    totals: [[f32; 4]; 2],
    pushing: [bool; 2],
    sub_dt: f32,
    n: u32,
) {
    let inv_dt2 = 1.0 / (sub_dt * sub_dt);
    for h in 0..2 {
        if !pushing[h] {
            continue;
        }
        let [x, y, z, count] = totals[h];
        out.reactions[h] -= glam::Vec3::new(x, y, z) * inv_dt2 / n as f32;
        out.pushed[h] = out.pushed[h].max(count as usize);
    }
}

/// Where [`super::Particles::predict`] will put particle `i` in a substep of `dt` (the same
/// operations in the same order).
fn predicted(p: &super::Particles, i: usize, dt: f32, gravity: glam::Vec3) -> glam::Vec3 {
    let (x, v, w, e) = (p.x[i], p.v[i], p.w[i], p.ext[i]);
    if w > 0.0 {
        let v = v + dt * (gravity + e * w);
        x + dt * v
    } else {
        x
    }
}

/// Before a step the CPU runs while the solver has a device: the CPU holds the newest state
/// (each device step reads the particles and the clusters back), and after the CPU's step the
/// device's is old.
pub(super) fn before_cpu_step(s: &mut ParticleSolver) {
    s.read_device_clusters();
    s.device.stale();
}
