//! The particle solver on the GPU: a world of shape-matching clusters stepped by the same
//! algorithm as the CPU's ([`Particles::predict`], [`ShapeMatching::project`],
//! [`Particles::finish`], the solver's floor), one compute invocation per particle or per
//! cluster (`shaders/particles.wgsl`). The particles, the clusters' frames and the springs'
//! multipliers live on the device; every substep and sweep of a submission is encoded in one
//! pass; the external forces go up with a submission and the state comes back when asked.
//!
//! The device's floats round as its compiler chooses (fused multiply-adds, its square roots),
//! so the GPU's bytes are its own: two runs on one adapter agree byte for byte, and the CPU's
//! positions within a tolerance (tested).

use super::Particles;
pub use super::gpu_sets::{ChainSegment, ChainSet, Constraints, DeviceChain, Set};
use super::gpu_tools::{DeviceTool, Entries, ToolKernels};
use super::shape::{ShapeMatching, coefficients};
use crate::gpu::compute::{self, PassTimer, bind};
use crate::gpu::{Gpu, RenderError};
use bytemuck::Zeroable;
use glam::Vec3;

pub(super) const SHADER: &str = include_str!("../../../shaders/particles.wgsl");

/// Most workgroups along one dimension of a dispatch (WebGPU's limit), and a workgroup's
/// invocations (the shader's `index`).
const MAX_GROUPS: u32 = 65_535;
const GROUP: u32 = 64;

/// Iterations of the rotation's extraction from a cold and a warm start (`shape.rs`).
const COLD_ROTATION_ITERATIONS: u32 = 30;
const WARM_ROTATION_ITERATIONS: u32 = 4;

/// The shader's `Params` (48 bytes, `vec3` aligned to 16).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    particles: u32,
    clusters: u32,
    dt: f32,
    inv_dt: f32,
    gravity: [f32; 3],
    keep: f32,
    floor_y: f32,
    floor_on: u32,
    cold_iterations: u32,
    warm_iterations: u32,
    lambdas: u32,
    pad: [u32; 3],
}

/// The shader's `Range`: one colour of one constraint set.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Range {
    first: u32,
    end: u32,
    lambda_base: u32,
    compliance: f32,
}

/// How a submission steps: steps of `dt_s`, each `substeps` substeps of `iterations` sweeps,
/// under gravity, with point damping, above a floor if there is one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepping {
    pub dt_s: f32,
    pub substeps: u32,
    pub iterations: u32,
    pub gravity_m_per_s2: Vec3,
    pub damping_per_s: f32,
    pub floor_y_m: Option<f32>,
}

/// The entry points.
const ENTRIES: [&str; 14] = [
    "predict",
    "match_goals",
    "shape_particles",
    "finish",
    "clear_lambdas",
    "project_stretches",
    "project_bends",
    "floor",
    "project_chains",
    "project_contacts",
    "push_tool",
    "grasp_tool",
    "tool_sums",
    "project_scheduled",
];
const PREDICT: usize = 0;
const MATCH: usize = 1;
const SHAPE: usize = 2;
const FINISH: usize = 3;
const CLEAR: usize = 4;
const STRETCHES: usize = 5;
const BENDS: usize = 6;
const FLOOR: usize = 7;
const CHAINS: usize = 8;
const CONTACTS: usize = 9;
const SCHEDULED: usize = 13;
const TOOLS: Entries = Entries {
    push: 10,
    grasp: 11,
    sums: 12,
};

/// How a sweep's constraints are dispatched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sweeps {
    /// In levels, one workgroup a sweep for the sets and one for the contacts
    /// (`gpu_schedule.rs`), where no level is too wide for one workgroup; else as `ByColour`.
    Scheduled,
    /// A dispatch for each colour of each set (the same bytes; kept to compare).
    ByColour,
}

/// One colour's dispatch (or a scheduled sweep's): its entry point, bind group and
/// workgroups.
struct ColourPass {
    entry: usize,
    bind: wgpu::BindGroup,
    groups: (u32, u32),
}

/// A particle world, its clusters and its stretch and bending constraints on one device, and
/// the kernels that step them.
pub struct ParticlesGpu {
    gpu: Gpu,
    pipelines: Vec<wgpu::ComputePipeline>,
    /// The per-particle and per-cluster entry points' bind groups (by entry; the colour
    /// passes have their own).
    binds: Vec<Option<wgpu::BindGroup>>,
    params: wgpu::Buffer,
    x: wgpu::Buffer,
    x0: wgpu::Buffer,
    v: wgpu::Buffer,
    ext: wgpu::Buffer,
    cluster_state: wgpu::Buffer,
    frames: wgpu::Buffer,
    coef: wgpu::Buffer,
    /// A sweep's colour passes after the clusters, in order, then the contacts' (remade
    /// alone at each search).
    passes: Vec<ColourPass>,
    contact_passes: Vec<ColourPass>,
    lambdas: u32,
    /// Memberships of clusters; stretch and bending constraints, chain segments, chain
    /// bending springs and contact pairs on the device (for the bytes a substep moves).
    memberships: u64,
    counts: [u64; 5],
    particles: u32,
    clusters: u32,
    /// Each entry's `k / m` (the coefficients are made from it for the substep), and the
    /// substep they were last made for.
    rate: Vec<f32>,
    coef_dt: f32,
    timer: Option<PassTimer>,
    /// The instruments, once a step has had one (`gpu_tools.rs`).
    tools: Option<ToolKernels>,
    sweeps: Sweeps,
    /// The levels of the scheduled sets and contacts (0 where dispatched by colour).
    levels: [usize; 2],
    /// Where each submission's results are copied to be read (mappable, kept): the
    /// positions, step starts and velocities, the instruments' totals, the timestamps, the
    /// clusters' state and frames (`gpu_readback.rs`), in two regions: a submission's end, and
    /// its first substep's state where it was split.
    readback: wgpu::Buffer,
    /// Whether the readback buffer holds the device's newest results (the last submission
    /// copied them and nothing was written up since).
    copied: std::cell::Cell<bool>,
    /// Whether the last submission was split after its first substep (its state copied).
    split: std::cell::Cell<bool>,
    /// The last submission's time on the GPU's clock, once read with its results.
    read_kernel_s: std::cell::Cell<Option<f64>>,
    /// Whether the device's external forces are all zero (none need go up while the CPU's are
    /// too).
    ext_zero: bool,
    /// What a scheduled sweep binds beside its schedule (the contacts' too: one kernel takes
    /// both): the multipliers, the chains, their segments, bending springs and rows.
    set_buffers: Vec<(u32, wgpu::Buffer)>,
}

#[path = "gpu_constraints.rs"]
mod constraints;
#[path = "gpu_readback.rs"]
mod readback;
pub use readback::Later;
use readback::Readback;

fn bytes<T: bytemuck::Pod>(v: &[T]) -> &[u8] {
    bytemuck::cast_slice(v)
}

/// Positions with inverse masses, as the shader's `vec4`s.
fn positions(x: &[Vec3], w: &[f32]) -> Vec<[f32; 4]> {
    x.iter().zip(w).map(|(p, &w)| [p.x, p.y, p.z, w]).collect()
}

fn vec4s(v: &[Vec3]) -> Vec<[f32; 4]> {
    v.iter().map(|p| [p.x, p.y, p.z, 0.0]).collect()
}

/// Workgroups for `n` invocations: x at most [`MAX_GROUPS`], and all of it when there is a y.
fn groups(n: u32) -> (u32, u32) {
    let total = n.div_ceil(GROUP).max(1);
    if total <= MAX_GROUPS {
        (total, 1)
    } else {
        (MAX_GROUPS, total.div_ceil(MAX_GROUPS))
    }
}

/// Whether every bit of `v` is zero (a negative zero is not).
fn bits_zero(v: Vec3) -> bool {
    v.to_array().iter().all(|c| c.to_bits() == 0)
}

impl ParticlesGpu {
    /// Uploads the particles `p`, their clusters `s` and the constraints `c` to `gpu`'s
    /// device and compiles the kernels. An error names what the device refused.
    pub fn new(
        gpu: &Gpu,
        p: &Particles,
        s: &ShapeMatching,
        c: &Constraints,
    ) -> Result<ParticlesGpu, RenderError> {
        Self::with_sweeps(gpu, p, s, c, Sweeps::Scheduled)
    }

    /// As [`ParticlesGpu::new`], its sweeps dispatched as `sweeps` says.
    pub fn with_sweeps(
        gpu: &Gpu,
        p: &Particles,
        s: &ShapeMatching,
        c: &Constraints,
        sweeps: Sweeps,
    ) -> Result<ParticlesGpu, RenderError> {
        let module = compute::compile(&gpu.device, "shaders/particles.wgsl", SHADER)?;
        let pipelines = ENTRIES
            .iter()
            .map(|e| compute::pipeline(gpu, &module, e))
            .collect::<Result<Vec<_>, _>>()?;
        let arrays = s.arrays();
        let storage = |label: &str, data: &[u8]| compute::storage(gpu, label, data);
        let x = storage("particle positions", bytes(&positions(&p.x, &p.w)))?;
        let x0 = storage("particle step starts", bytes(&positions(&p.x0, &p.w)))?;
        let v = storage("particle velocities", bytes(&vec4s(&p.v)))?;
        let ext = storage("particle forces", bytes(&vec4s(&p.ext)))?;
        let offsets = storage("cluster entry offsets", bytes(&arrays.offsets))?;
        let mu = storage("cluster multipliers", bytes(&arrays.mu))?;
        let info = storage("clusters", bytes(&arrays.info))?;
        let cluster_state = storage("cluster frames", bytes(&arrays.state))?;
        let member_index = storage("cluster members", bytes(&arrays.member_index))?;
        let member_mw = storage("cluster member masses", bytes(&arrays.member_mw))?;
        let frames = storage(
            "cluster goal frames",
            &vec![0u8; 64 * arrays.info.len().max(1)],
        )?;
        let entries = storage("cluster entries", bytes(&arrays.entries))?;
        let coef = storage(
            "cluster coefficients",
            &vec![0u8; 8 * arrays.rate.len().max(1)],
        )?;
        let params = compute::uniform(gpu, "particle params", bytes(&[Params::zeroed()]));
        // What each entry point binds (`layout: None` takes only what the entry uses).
        let fixed: [(usize, Vec<(u32, &wgpu::Buffer)>); 5] = [
            (
                PREDICT,
                vec![
                    (0, &params),
                    (1, &x),
                    (2, &x0),
                    (3, &v),
                    (4, &ext),
                    (5, &offsets),
                    (6, &mu),
                ],
            ),
            (
                MATCH,
                vec![
                    (0, &params),
                    (1, &x),
                    (7, &info),
                    (8, &cluster_state),
                    (9, &member_index),
                    (10, &member_mw),
                    (11, &frames),
                ],
            ),
            (
                SHAPE,
                vec![
                    (0, &params),
                    (1, &x),
                    (5, &offsets),
                    (6, &mu),
                    (11, &frames),
                    (12, &entries),
                    (13, &coef),
                ],
            ),
            (FINISH, vec![(0, &params), (1, &x), (2, &x0), (3, &v)]),
            (FLOOR, vec![(0, &params), (1, &x)]),
        ];
        let mut binds: Vec<Option<wgpu::BindGroup>> = (0..ENTRIES.len()).map(|_| None).collect();
        for (entry, buffers) in &fixed {
            binds[*entry] = Some(bind(gpu, &pipelines[*entry], ENTRIES[*entry], buffers));
        }
        let mut out = ParticlesGpu {
            gpu: gpu.clone(),
            pipelines,
            binds,
            params,
            x,
            x0,
            v,
            ext,
            cluster_state,
            frames,
            coef,
            passes: Vec::new(),
            contact_passes: Vec::new(),
            lambdas: 0,
            memberships: arrays.rate.len() as u64,
            counts: [0; 5],
            particles: p.len() as u32,
            clusters: arrays.info.len() as u32,
            rate: arrays.rate,
            coef_dt: 0.0,
            timer: PassTimer::new(gpu),
            tools: None,
            sweeps,
            levels: [0; 2],
            set_buffers: Vec::new(),
            readback: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("particle readback"),
                size: Readback::buffer_bytes(p.len() as u64, arrays.info.len() as u64),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            copied: std::cell::Cell::new(false),
            split: std::cell::Cell::new(false),
            read_kernel_s: std::cell::Cell::new(None),
            ext_zero: p.ext.iter().all(|e| bits_zero(*e)),
        };
        out.set_constraints(c)?;
        gpu.check()?;
        Ok(out)
    }

    /// The fewest bytes a substep of `iterations` sweeps moves through device memory, each
    /// value read or written once (neighbours' reads counted as cache hits): the prediction
    /// (a particle's position read and written, its start written, its velocity read and
    /// written, its force read: 96 bytes; a membership's multiplier zeroed: 16); each sweep's
    /// goals (a membership's index, mass share and position: 36; a cluster's state read and
    /// written and its frame written: 128), its particles' pass (a particle's position read and
    /// written: 32; a membership's entry, coefficients, multiplier read and written and frame
    /// read: 88), a stretch constraint (itself, both ends read and written, its multiplier: 88),
    /// a bending one (itself, four ends, its multiplier: 168), a chain segment (itself, both
    /// ends, its rows written and read, its multiplier: 152), a chain's bending spring (88), a
    /// contact pair (itself, both ends: 72), the floor (a position read: 16); the velocities
    /// (48 a particle).
    pub fn bytes_per_substep(&self, iterations: u32) -> u64 {
        let (n, m, k) = (
            u64::from(self.particles),
            self.memberships,
            u64::from(self.clusters),
        );
        let [stretches, bends, segs, chain_bends, pairs] = self.counts;
        let sweep = m * 36
            + k * 128
            + n * 32
            + m * 88
            + stretches * 88
            + bends * 168
            + segs * 152
            + chain_bends * 88
            + pairs * 72
            + n * 16;
        let tools = self
            .tools
            .as_ref()
            .map_or(0, |t| t.bytes_per_substep(iterations));
        n * 96 + m * 16 + u64::from(iterations.max(1)) * sweep + n * 48 + tools
    }

    /// Sets each hand's instrument for the next submissions, whose substeps last `dt_s`
    /// (a grasp's springs depend on it): buffers for them are made at the first instrument,
    /// and again for a grasp of more than `most_held` particles. An error names what the
    /// device refused or cannot take.
    pub fn set_tools(
        &mut self,
        tools: &[DeviceTool; 2],
        dt_s: f32,
        most_held: u32,
    ) -> Result<(), RenderError> {
        let idle = tools.iter().all(|t| matches!(t, DeviceTool::None));
        if idle && self.tools.is_none() {
            return Ok(());
        }
        let held = tools
            .iter()
            .map(|t| match t {
                DeviceTool::Grasp { held, .. } => held.len() as u32,
                _ => 0,
            })
            .max()
            .unwrap_or(0)
            .max(most_held);
        if self.tools.as_ref().is_none_or(|k| k.capacity() < held) {
            let k = ToolKernels::new(
                &self.gpu,
                &self.pipelines,
                TOOLS,
                &self.x,
                self.particles,
                held,
            )?;
            self.tools = Some(k);
        }
        match &mut self.tools {
            Some(k) => k.set(&self.gpu, tools, dt_s),
            None => Ok(()),
        }
    }

    /// The dispatches a substep of `iterations` sweeps takes (each waits for the one before
    /// it), with the instruments of the latest submission.
    pub fn dispatches_per_substep(&self, iterations: u32, floor: bool) -> usize {
        let tools = self.tools.as_ref().filter(|t| t.active());
        let sweep = |first: bool| {
            usize::from(self.clusters > 0)
                + 1
                + self.passes.len()
                + self.contact_passes.len()
                + tools.map_or(0, |t| t.sweep(TOOLS, first, groups).len())
                + usize::from(floor)
        };
        let sweeps: usize = (0..iterations.max(1)).map(|k| sweep(k == 0)).sum();
        1 + usize::from(self.lambdas > 0) + sweeps + 1 + tools.map_or(0, |t| t.sums(TOOLS).len())
    }

    /// The dispatches a sweep takes for its constraint sets and contacts (a colour each, or
    /// one each where scheduled), and the scheduled sets' and contacts' levels.
    pub fn sweep_dispatches(&self) -> (usize, [usize; 2]) {
        (self.passes.len() + self.contact_passes.len(), self.levels)
    }

    /// The device it runs on.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Sends `p`'s positions, inverse masses and velocities up, replacing the device's (a
    /// rollback, a pinned particle).
    pub fn upload(&mut self, p: &Particles) {
        let q = &self.gpu.queue;
        q.write_buffer(&self.x, 0, bytes(&positions(&p.x, &p.w)));
        q.write_buffer(&self.v, 0, bytes(&vec4s(&p.v)));
        self.copied.set(false);
    }

    /// Advances `steps` steps as `how` says in one submission, under `p`'s external forces
    /// (taken: they act through every substep of the submission, as a step's act through
    /// its substeps on the CPU). Returns at once; [`ParticlesGpu::download`] waits.
    pub fn advance(
        &mut self,
        p: &mut Particles,
        how: &Stepping,
        steps: usize,
    ) -> Result<(), RenderError> {
        self.submit(p, how, steps, false)
    }

    /// [`ParticlesGpu::advance`] of one step of at least two substeps, split after the first:
    /// the first substep's state is copied out, the instruments' totals start again at zero,
    /// and the rest run in the same submission. Read both with
    /// [`ParticlesGpu::download_split`]. The bytes are those of a submission a substep.
    pub fn advance_split(&mut self, p: &mut Particles, how: &Stepping) -> Result<(), RenderError> {
        if how.substeps < 2 {
            return Err(RenderError::Device(
                "a submission split after its first substep needs two substeps or more".into(),
            ));
        }
        self.submit(p, how, 1, true)
    }

    fn submit(
        &mut self,
        p: &mut Particles,
        how: &Stepping,
        steps: usize,
        split: bool,
    ) -> Result<(), RenderError> {
        if p.len() != self.particles as usize {
            return Err(RenderError::Device(format!(
                "the particle world has {} particles; the device holds {}",
                p.len(),
                self.particles
            )));
        }
        let substeps = how.substeps.max(1);
        let dt = how.dt_s / substeps as f32;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(RenderError::Device(format!(
                "a substep of {dt} s is not a positive time"
            )));
        }
        let q = &self.gpu.queue;
        // The forces go up unless they and the device's are all zero.
        let zero = p.ext.iter().all(|e| bits_zero(*e));
        if !(zero && self.ext_zero) {
            q.write_buffer(&self.ext, 0, bytes(&vec4s(&p.ext)));
            self.ext_zero = zero;
        }
        p.ext.iter_mut().for_each(|e| *e = Vec3::ZERO);
        if self.coef_dt != dt {
            self.coef_dt = dt;
            let coef: Vec<[f32; 2]> = self.rate.iter().map(|&r| coefficients(r, dt)).collect();
            if !coef.is_empty() {
                q.write_buffer(&self.coef, 0, bytes(&coef));
            }
        }
        let params = Params {
            particles: self.particles,
            clusters: self.clusters,
            dt,
            inv_dt: 1.0 / dt,
            gravity: how.gravity_m_per_s2.to_array(),
            keep: (-how.damping_per_s.max(0.0) * dt).exp(),
            floor_y: how.floor_y_m.unwrap_or(0.0),
            floor_on: u32::from(how.floor_y_m.is_some()),
            cold_iterations: COLD_ROTATION_ITERATIONS,
            warm_iterations: WARM_ROTATION_ITERATIONS,
            lambdas: self.lambdas,
            pad: [0; 3],
        };
        q.write_buffer(&self.params, 0, bytes(&[params]));
        let tools = self.tools.as_ref().filter(|t| t.active());
        if let Some(t) = tools {
            q.write_buffer(&t.totals, 0, &[0u8; 32]);
        }
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("particle steps"),
            });
        let all = steps * substeps as usize;
        if split {
            // The first substep, its state into the readback's second region, the totals
            // at zero again (as a submission of its own starts them), then the rest.
            self.encode_substeps(&mut encoder, how, 1, (true, false));
            self.encode_copies(&mut encoder, 1, false);
            if let Some(t) = tools {
                encoder.clear_buffer(&t.totals, 0, None);
            }
            self.encode_substeps(&mut encoder, how, all - 1, (false, true));
        } else {
            self.encode_substeps(&mut encoder, how, all, (true, true));
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut encoder);
        }
        // The results into the readback buffer in the same submission, for a download.
        self.encode_copies(&mut encoder, 0, true);
        self.split.set(split);
        self.read_kernel_s.set(None);
        self.gpu.queue.submit([encoder.finish()]);
        self.gpu.check()
    }

    /// `count` substeps as `how` says in one compute pass, timed from its start and to its
    /// end as `timed` says.
    fn encode_substeps(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        how: &Stepping,
        count: usize,
        timed: (bool, bool),
    ) {
        let tools = self.tools.as_ref().filter(|t| t.active());
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("particle substeps"),
            timestamp_writes: self.timer.as_ref().and_then(|t| t.writes_part(timed)),
        });
        let per_particle = groups(self.particles);
        let per_cluster = groups(self.clusters);
        let per_lambda = groups(self.lambdas);
        let fixed = |pass: &mut wgpu::ComputePass, k: usize, (gx, gy): (u32, u32)| {
            if let Some(b) = &self.binds[k] {
                pass.set_pipeline(&self.pipelines[k]);
                pass.set_bind_group(0, b, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        };
        for _ in 0..count {
            fixed(&mut pass, PREDICT, per_particle);
            if self.lambdas > 0 {
                fixed(&mut pass, CLEAR, per_lambda);
            }
            for sweep in 0..how.iterations.max(1) {
                if self.clusters > 0 {
                    fixed(&mut pass, MATCH, per_cluster);
                }
                fixed(&mut pass, SHAPE, per_particle);
                // The constraint sets, the instruments, then the contacts between bodies.
                let mut ordered: Vec<(usize, &wgpu::BindGroup, (u32, u32))> = self
                    .passes
                    .iter()
                    .map(|c| (c.entry, &c.bind, c.groups))
                    .collect();
                let tool_passes =
                    tools.map_or_else(Vec::new, |t| t.sweep(TOOLS, sweep == 0, groups));
                ordered.extend(tool_passes.iter().map(|d| (d.entry, d.bind, d.groups)));
                ordered.extend(
                    self.contact_passes
                        .iter()
                        .map(|c| (c.entry, &c.bind, c.groups)),
                );
                for (entry, bind, (gx, gy)) in ordered {
                    pass.set_pipeline(&self.pipelines[entry]);
                    pass.set_bind_group(0, bind, &[]);
                    pass.dispatch_workgroups(gx, gy, 1);
                }
                if how.floor_y_m.is_some() {
                    fixed(&mut pass, FLOOR, per_particle);
                }
            }
            fixed(&mut pass, FINISH, per_particle);
            for d in tools.map_or_else(Vec::new, |t| t.sums(TOOLS)) {
                pass.set_pipeline(&self.pipelines[d.entry]);
                pass.set_bind_group(0, d.bind, &[]);
                pass.dispatch_workgroups(d.groups.0, d.groups.1, 1);
            }
        }
    }

    /// Sends the clusters' centres, rotations and warm starts of `s` up (after the CPU
    /// stepped them).
    pub fn upload_shape(&mut self, s: &ShapeMatching) {
        self.upload_cluster_state(&s.state_rows());
    }

    /// Sends the clusters' state rows (two a cluster, as [`ShapeMatching::state_rows`] makes
    /// them, or as a split submission's first substep left them) up.
    pub fn upload_cluster_state(&mut self, rows: &[[f32; 4]]) {
        if !rows.is_empty() && rows.len() == 2 * self.clusters as usize {
            self.gpu
                .queue
                .write_buffer(&self.cluster_state, 0, bytes(rows));
            self.copied.set(false);
        }
    }

    /// The last submission's time on the GPU's clock, seconds (waits for it); none where the
    /// device has no timestamp queries.
    pub fn kernel_seconds(&self) -> Result<Option<f64>, RenderError> {
        if let Some(s) = self.read_kernel_s.take() {
            return Ok(Some(s));
        }
        self.timer
            .as_ref()
            .map(|t| t.seconds(&self.gpu))
            .transpose()
    }
}

#[cfg(test)]
#[path = "gpu_tests.rs"]
mod tests;
