//! The membrane on the GPU: the same symplectic Euler substep as the CPU's (`forces.rs`,
//! `integrate.rs`), one compute invocation per node gathering its springs, tethers and
//! attachments (`shaders/membrane.wgsl`). The state lives on the device in the CPU's row-block
//! layout, in two buffers that the substeps read and write in turn; all substeps of a step are
//! encoded in one pass and one submission. Only the external forces go up each step; the state
//! comes back when asked.

use super::{LAYERS, Membrane};
use crate::gpu::compute::{self, PassTimer};
use crate::gpu::{Gpu, RenderError};
use bytemuck::Zeroable;
use std::time::Instant;

pub(super) const SHADER: &str = include_str!("../../../shaders/membrane.wgsl");

/// How the nodes are laid out in workgroups (the shader's entry points).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// 64 invocations along a row, a row of workgroups a row block (`substep_rows`).
    Rows,
    /// 256 invocations over the nodes in the state's order (`substep_flat`).
    Flat,
    /// 64 columns of one row in all four layers, a workgroup (`substep_layers`): a node's
    /// links and tethers read its column's other layers, which the same workgroup reads, so
    /// a grid too large for the GPU's cache reads each value from memory once.
    Layers,
}

impl Layout {
    pub fn name(self) -> &'static str {
        match self {
            Layout::Rows => "rows_of_64",
            Layout::Flat => "flat_256",
            Layout::Layers => "layers_together",
        }
    }

    fn entry(self) -> &'static str {
        match self {
            Layout::Rows => "substep_rows",
            Layout::Flat => "substep_flat",
            Layout::Layers => "substep_layers",
        }
    }
}

/// Most workgroups along one dimension of a dispatch (WebGPU's limit).
const MAX_GROUPS: u32 = 65_535;

/// The shader's `Params` (48 bytes, `vec3` aligned to 16).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    rows: u32,
    cols: u32,
    periodic: u32,
    external_count: u32,
    gravity: [f32; 3],
    damping_per_s: f32,
    dt: f32,
    groups_x: u32,
    tiles_c: u32,
    pad: u32,
}

/// The shader's `External`: a force on one node, N.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct External {
    node: u32,
    force: [f32; 3],
}

/// Another kernel's substeps over the same buffers: its pipeline, its two ping-pong bind
/// groups, its workgroups and the tiles across the grid (the active set's, `device.rs`).
pub(super) struct TileDispatch<'a> {
    pub pipeline: &'a wgpu::ComputePipeline,
    pub bind: &'a [wgpu::BindGroup; 2],
    pub groups: (u32, u32, u32),
    pub tiles_c: u32,
}

/// A membrane's state and springs on one device, and the kernel that steps them.
pub struct MembraneGpu {
    gpu: Gpu,
    pipeline: wgpu::ComputePipeline,
    pub(super) params: wgpu::Buffer,
    pub(super) state: [wgpu::Buffer; 2],
    pub(super) springs: wgpu::Buffer,
    pub(super) attach: wgpu::Buffer,
    pub(super) beta: wgpu::Buffer,
    pub(super) externals: wgpu::Buffer,
    external_capacity: usize,
    /// Bind group `k` reads state buffer `k` and writes the other.
    bind: [wgpu::BindGroup; 2],
    /// The state buffer that holds the newest state.
    pub(super) current: usize,
    rows: u32,
    cols: u32,
    periodic: bool,
    layout: Layout,
    timer: Option<PassTimer>,
}

fn bytes<T: bytemuck::Pod>(v: &[T]) -> &[u8] {
    bytemuck::cast_slice(v)
}

/// The damping times of each block padded to four (the shader reads `vec4`s).
fn beta4(m: &Membrane) -> Vec<[f32; 4]> {
    m.beta.iter().map(|b| [b[0], b[1], b[2], 0.0]).collect()
}

impl MembraneGpu {
    /// Uploads `m` (state, springs, attachments, damping) to `gpu`'s device and compiles the
    /// kernel. An error names what the device refused.
    pub fn new(gpu: &Gpu, m: &Membrane) -> Result<MembraneGpu, RenderError> {
        Self::with_layout(gpu, m, Layout::Flat)
    }

    /// [`MembraneGpu::new`] with the nodes in workgroups laid out as `layout` says.
    pub fn with_layout(
        gpu: &Gpu,
        m: &Membrane,
        layout: Layout,
    ) -> Result<MembraneGpu, RenderError> {
        let module = compute::compile(&gpu.device, "shaders/membrane.wgsl", SHADER)?;
        let pipeline = compute::pipeline(gpu, &module, layout.entry())?;
        let state = [
            compute::storage(gpu, "membrane state a", bytes(&m.state.data))?,
            compute::storage(gpu, "membrane state b", bytes(&m.state.data))?,
        ];
        let springs = compute::storage(gpu, "membrane springs", bytes(&m.rows_data))?;
        let attach = compute::storage(gpu, "membrane attachments", bytes(&m.attach))?;
        let beta = compute::storage(gpu, "membrane damping", bytes(&beta4(m)))?;
        let external_capacity = 64;
        let externals = compute::storage(
            gpu,
            "membrane external forces",
            &vec![0u8; external_capacity * std::mem::size_of::<External>()],
        )?;
        let params = compute::uniform(gpu, "membrane params", bytes(&[Params::zeroed()]));
        let bind = Self::bind_groups(
            gpu, &pipeline, &params, &state, &springs, &attach, &beta, &externals,
        );
        let out = MembraneGpu {
            gpu: gpu.clone(),
            pipeline,
            params,
            state,
            springs,
            attach,
            beta,
            externals,
            external_capacity,
            bind,
            current: 0,
            rows: m.rows as u32,
            cols: m.cols as u32,
            periodic: m.periodic,
            layout,
            timer: PassTimer::new(gpu),
        };
        gpu.check()?;
        Ok(out)
    }

    #[allow(clippy::too_many_arguments)]
    fn bind_groups(
        gpu: &Gpu,
        pipeline: &wgpu::ComputePipeline,
        params: &wgpu::Buffer,
        state: &[wgpu::Buffer; 2],
        springs: &wgpu::Buffer,
        attach: &wgpu::Buffer,
        beta: &wgpu::Buffer,
        externals: &wgpu::Buffer,
    ) -> [wgpu::BindGroup; 2] {
        let layout = pipeline.get_bind_group_layout(0);
        [0usize, 1].map(|k| {
            fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
                wgpu::BindGroupEntry {
                    binding,
                    resource: buffer.as_entire_binding(),
                }
            }
            gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("membrane substep"),
                layout: &layout,
                entries: &[
                    entry(0, params),
                    entry(1, &state[k]),
                    entry(2, &state[1 - k]),
                    entry(3, springs),
                    entry(4, attach),
                    entry(5, beta),
                    entry(6, externals),
                ],
            })
        })
    }

    /// The device it runs on.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// Sends `m`'s state (positions and velocities) up, replacing the device's.
    pub fn upload_state(&mut self, m: &Membrane) {
        self.gpu
            .queue
            .write_buffer(&self.state[self.current], 0, bytes(&m.state.data));
    }

    /// Sends `m`'s springs (after a cut) and damping up.
    pub fn upload_springs(&mut self, m: &Membrane) {
        self.gpu
            .queue
            .write_buffer(&self.springs, 0, bytes(&m.rows_data));
        self.gpu.queue.write_buffer(&self.beta, 0, bytes(&beta4(m)));
    }

    /// Sends `m`'s attachments (layer 0's targets, a detached layer) up.
    pub fn upload_attachments(&mut self, m: &Membrane) {
        self.gpu
            .queue
            .write_buffer(&self.attach, 0, bytes(&m.attach));
    }

    /// Advances `dt_s` in `substeps` equal symplectic substeps on the device, under `m`'s
    /// external forces (which are taken, as the CPU's step takes them), in one submission.
    /// Returns at once; [`MembraneGpu::download`] or [`MembraneGpu::kernel_seconds`] wait.
    pub fn advance(
        &mut self,
        m: &mut Membrane,
        dt_s: f32,
        substeps: usize,
    ) -> Result<(), RenderError> {
        let count = self.upload_externals(m)?.0;
        self.substeps(m, dt_s, substeps, count)
    }

    /// Sends `m`'s external forces up (taking them), sorted by node: how many, and whether
    /// their buffer had to grow (a bind group made before then binds the old one).
    pub(super) fn upload_externals(
        &mut self,
        m: &mut Membrane,
    ) -> Result<(u32, bool), RenderError> {
        let mut ext: Vec<External> = m
            .external
            .drain(..)
            .map(|(node, f)| External {
                node,
                force: f.to_array(),
            })
            .collect();
        ext.sort_by_key(|e| e.node);
        let grown = ext.len() > self.external_capacity;
        if grown {
            self.external_capacity = ext.len().next_power_of_two();
            self.externals = compute::storage(
                &self.gpu,
                "membrane external forces",
                &vec![0u8; self.external_capacity * std::mem::size_of::<External>()],
            )?;
            self.bind = Self::bind_groups(
                &self.gpu,
                &self.pipeline,
                &self.params,
                &self.state,
                &self.springs,
                &self.attach,
                &self.beta,
                &self.externals,
            );
        }
        if !ext.is_empty() {
            self.gpu.queue.write_buffer(&self.externals, 0, bytes(&ext));
        }
        Ok((ext.len() as u32, grown))
    }

    /// `substeps` substeps of `dt_s / substeps` under the `external_count` forces uploaded,
    /// in one submission of every node by this kernel's layout.
    fn substeps(
        &mut self,
        m: &Membrane,
        dt_s: f32,
        substeps: usize,
        external_count: u32,
    ) -> Result<(), RenderError> {
        let encoder = self.step_encoder(m, dt_s, substeps, external_count);
        self.gpu.queue.submit([encoder.finish()]);
        self.gpu.check()
    }

    /// A new encoder holding [`MembraneGpu::substeps`]' pass, for more to follow it in the
    /// same submission.
    fn step_encoder(
        &mut self,
        m: &Membrane,
        dt_s: f32,
        substeps: usize,
        external_count: u32,
    ) -> wgpu::CommandEncoder {
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("membrane step"),
            });
        self.encode_substeps(&mut encoder, m, dt_s, substeps, external_count, None);
        encoder
    }

    /// The substeps' pass into `encoder`: every node by this kernel's layout, or with `tiles`
    /// another pipeline over the same buffers. Their parameters are written to the queue, so
    /// one submission holds one such pass.
    pub(super) fn encode_substeps(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        m: &Membrane,
        dt_s: f32,
        substeps: usize,
        external_count: u32,
        tiles: Option<TileDispatch<'_>>,
    ) {
        let n = substeps.max(1);
        let groups = self.groups();
        let p = &m.params;
        let params = Params {
            rows: self.rows,
            cols: self.cols,
            periodic: u32::from(self.periodic),
            external_count,
            gravity: p.gravity.to_array(),
            damping_per_s: p.damping_per_s,
            dt: dt_s / n as f32,
            groups_x: groups.0,
            tiles_c: tiles.as_ref().map_or(0, |t| t.tiles_c),
            pad: 0,
        };
        self.gpu
            .queue
            .write_buffer(&self.params, 0, bytes(&[params]));
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("membrane substeps"),
                timestamp_writes: self.timer.as_ref().map(PassTimer::writes),
            });
            let (pipeline, bind, groups) = match tiles {
                Some(t) => (t.pipeline, t.bind, t.groups),
                None => (&self.pipeline, &self.bind, groups),
            };
            pass.set_pipeline(pipeline);
            for _ in 0..n {
                pass.set_bind_group(0, &bind[self.current], &[]);
                pass.dispatch_workgroups(groups.0, groups.1, groups.2);
                self.current = 1 - self.current;
            }
        }
        if let Some(t) = &self.timer {
            t.resolve(encoder);
        }
    }

    /// The workgroups of a substep's dispatch.
    fn groups(&self) -> (u32, u32, u32) {
        let blocks = LAYERS as u32 * self.rows;
        match self.layout {
            Layout::Rows => (self.cols.div_ceil(64), blocks, 1),
            Layout::Layers => (self.cols.div_ceil(64), self.rows, 1),
            Layout::Flat => {
                let total = (blocks * self.cols).div_ceil(256);
                let x = total.min(MAX_GROUPS);
                (x, total.div_ceil(x), 1)
            }
        }
    }

    /// [`MembraneGpu::advance`] with the first `probe.size() - 16` bytes of the newest state
    /// (a stand-in for what a session reads back each step, the tools' forces) and the pass's
    /// timestamps copied into `probe` in the same submission, then read in one round trip:
    /// the pass's time on the GPU's clock, seconds (none without timestamp queries).
    pub fn advance_and_probe(
        &mut self,
        m: &mut Membrane,
        dt_s: f32,
        substeps: usize,
        probe: &wgpu::Buffer,
    ) -> Result<Option<f64>, RenderError> {
        let count = self.upload_externals(m)?.0;
        let mut encoder = self.step_encoder(m, dt_s, substeps, count);
        let state_bytes = probe.size().saturating_sub(16);
        if state_bytes > 0 {
            encoder.copy_buffer_to_buffer(&self.state[self.current], 0, probe, 0, state_bytes);
        }
        if let Some(t) = &self.timer {
            t.copy_into(&mut encoder, probe, state_bytes);
        }
        self.gpu.queue.submit([encoder.finish()]);
        let timer = self.timer.as_ref();
        compute::with_mapped(&self.gpu, probe, probe.size(), |b| {
            let stamps = b.get(state_bytes as usize..).unwrap_or(&[]);
            timer.map(|t| t.seconds_of(stamps))
        })
    }

    /// Waits for the device and copies its state into `m`.
    pub fn download(&self, m: &mut Membrane) -> Result<(), RenderError> {
        let n = m.state.data.len();
        let raw = compute::read(&self.gpu, &self.state[self.current], 4 * n as u64)?;
        for (v, b) in m.state.data.iter_mut().zip(raw.chunks_exact(4)) {
            *v = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        Ok(())
    }

    /// The last step's time on the GPU's clock, seconds (waits for it); none where the device
    /// has no timestamp queries.
    pub fn kernel_seconds(&self) -> Result<Option<f64>, RenderError> {
        self.timer
            .as_ref()
            .map(|t| t.seconds(&self.gpu))
            .transpose()
    }

    /// Waits until everything submitted has run.
    pub fn wait(&self) -> Result<(), RenderError> {
        self.gpu
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Lost(e.to_string()))?;
        self.gpu.check()
    }

    /// The fewest bytes a substep moves through device memory: each node's state read and
    /// written (48 bytes), its nine spring fields read (36), the attachments of layers 0 and 3
    /// (16 bytes a node of those, 8 on average), the damping per row (negligible). Reads of
    /// neighbours are counted as cache hits.
    pub fn bytes_per_substep(&self) -> u64 {
        let nodes = u64::from(self.rows) * u64::from(self.cols) * LAYERS as u64;
        nodes * (48 + 36 + 8)
    }
}

/// A copy of `m` for the comparisons and benchmarks: the CPU's symplectic integrator, no
/// active set, every node pushed out of place by a fixed pattern of about 1 mm so that every
/// spring works from the first substep.
pub fn pushed(m: &Membrane) -> Membrane {
    let mut c = m.clone();
    c.params.integrator = super::Integrator::Symplectic;
    c.activity = None;
    c.external.clear();
    for node in 0..c.len() {
        let k = node as f32;
        let d = 1e-3
            * glam::Vec3::new(
                (0.37 * k).sin(),
                (0.23 * k + 1.0).cos(),
                (0.11 * k + 2.0).sin(),
            );
        c.displace(node, d);
    }
    c
}

/// `substeps` of `dt_s` on the device and on the CPU from the same pushed state: the
/// relative difference of the velocities they reach, `|v_gpu - v_cpu| / |v_cpu|` over all
/// nodes. Float rounding alone differs (the sums run in another order), so it stays near the
/// float epsilon times the substeps.
pub fn compare(
    gpu: &Gpu,
    m: &Membrane,
    substeps: usize,
    dt_s: f32,
    layout: Layout,
) -> Result<f64, RenderError> {
    let mut cpu = pushed(m);
    let mut dev = cpu.clone();
    let mut k = MembraneGpu::with_layout(gpu, &dev, layout)?;
    k.advance(&mut dev, dt_s * substeps as f32, substeps)?;
    k.download(&mut dev)?;
    for _ in 0..substeps {
        cpu.step(dt_s);
    }
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for node in 0..cpu.len() {
        let (a, b) = (dev.velocity(node), cpu.velocity(node));
        diff += f64::from((a - b).length_squared());
        norm += f64::from(b.length_squared());
    }
    Ok((diff / norm.max(f64::MIN_POSITIVE)).sqrt())
}

/// What a timed run of the kernel measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KernelTiming {
    /// Steps (submissions) and substeps timed.
    pub steps: u64,
    pub substeps: u64,
    /// Wall seconds from the first submission to the last result on the CPU.
    pub wall_s: f64,
    /// The substeps' time on the GPU's clock, summed over the steps (none without timestamp
    /// queries).
    pub kernel_s: Option<f64>,
    pub bytes_per_substep: u64,
    /// The 99th percentile of a step's latency: from its submission to a few hundred of its
    /// values being readable on the CPU (what the haptic loop waits for), seconds.
    pub latency_p99_s: f64,
}

/// Times steps of `substeps` substeps of `dt_s` each on the pushed copy of `m`, each step one
/// submission followed by a small readback (as a coupled step reads the tool's
/// neighbourhood), after one untimed step: `max_steps` steps, or fewer once `budget_s` wall
/// seconds have passed (at least 5).
pub fn time(
    gpu: &Gpu,
    m: &Membrane,
    substeps: usize,
    dt_s: f32,
    max_steps: u64,
    budget_s: f64,
    layout: Layout,
) -> Result<KernelTiming, RenderError> {
    let mut dev = pushed(m);
    let mut k = MembraneGpu::with_layout(gpu, &dev, layout)?;
    // Each step reads back 1 KB of the state (a session reads the tools' forces) and the
    // pass's timestamps, copied in the step's own submission: one round trip a step, as a
    // session's step takes.
    let probe = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("membrane bench probe"),
        size: 1024u64.min(4 * dev.state.data.len() as u64) + 16,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    k.advance_and_probe(&mut dev, dt_s, substeps, &probe)?;
    let mut latencies = Vec::new();
    let mut kernel = k.timer.as_ref().map(|_| 0.0);
    let t0 = Instant::now();
    let mut steps = 0u64;
    while steps < max_steps.max(5) && (steps < 5 || t0.elapsed().as_secs_f64() < budget_s) {
        steps += 1;
        let t = Instant::now();
        let s = k.advance_and_probe(&mut dev, dt_s, substeps, &probe)?;
        latencies.push(t.elapsed().as_secs_f64());
        if let (Some(sum), Some(s)) = (kernel.as_mut(), s) {
            *sum += s;
        }
    }
    let wall_s = t0.elapsed().as_secs_f64();
    latencies.sort_by(f64::total_cmp);
    let p99 = latencies
        .get(((latencies.len() as f64 * 0.99).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(0.0);
    Ok(KernelTiming {
        steps,
        substeps: steps * substeps as u64,
        wall_s,
        kernel_s: kernel,
        bytes_per_substep: k.bytes_per_substep(),
        latency_p99_s: p99,
    })
}

/// The benchmark line of the kernel (its workgroups laid out as `layout` says; named
/// `membrane` for the default layout, `membrane_<layout>` for another) at `m`'s size, every
/// node awake: steps of `dt_s`, each in
/// as many substeps as the CPU takes at `safety` of the explicit limit, for `budget_s` wall
/// seconds (at most 5,000 steps); with the adapter, the substep rate, the bytes a substep
/// moves at the least and the bandwidth that makes on the GPU's clock, and the velocities'
/// difference from the CPU's after a few substeps.
pub fn bench_line(
    gpu: &Gpu,
    m: &Membrane,
    dt_s: f32,
    safety: f32,
    budget_s: f64,
    layout: Layout,
) -> Result<crate::sim::BenchLine, RenderError> {
    let n = m.substeps_for(dt_s, safety);
    let check = compare(gpu, m, n.min(20), dt_s / n as f32, layout)?;
    let t = time(gpu, m, n, dt_s, 5000, budget_s, layout)?;
    let name = match layout {
        Layout::Flat => "membrane".to_string(),
        other => format!("membrane_{}", other.name()),
    };
    let mut line = crate::sim::BenchLine::repeated(&name, t.steps, t.wall_s);
    line.dt_s = dt_s;
    line.realtime_factor = line.steps_per_s * f64::from(dt_s);
    line.vertices = m.len();
    line.constraints = m.springs();
    line.threads = 1;
    line.mass_spring = crate::sim::MassSpring {
        nodes: Some(m.len()),
        springs: Some(m.springs()),
        integrator: Some(super::Integrator::Symplectic.name()),
        substeps: Some(n),
        step_limit_s: Some(m.step_limit),
    };
    let moved = t.bytes_per_substep as f64 * t.substeps as f64;
    line.compute = crate::sim::ComputeFigures {
        backend: Some("gpu"),
        adapter: Some(gpu.describe()),
        substeps_per_step: Some(n),
        substeps_per_s: Some(t.substeps as f64 / t.wall_s.max(1e-12)),
        bytes_per_substep: Some(t.bytes_per_substep),
        kernel_s: t.kernel_s,
        wall_s: Some(t.wall_s),
        gb_per_s: t.kernel_s.map(|k| moved / k.max(1e-12) * 1e-9),
        kernel_substeps_per_s: t.kernel_s.map(|k| t.substeps as f64 / k.max(1e-12)),
        latency_p99_ms: Some(1e3 * t.latency_p99_s),
        check_rel_err: Some(check),
        dispatches_per_substep: Some(1),
        // Each step's substeps go in one submission (`substeps`).
        submissions_per_step: Some(1.0),
        ..Default::default()
    };
    Ok(line)
}
