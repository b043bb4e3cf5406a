//! The instruments on the device ([`super::gpu::ParticlesGpu::set_tools`]): each hand either
//! pushes (its instrument's generalized cylinders, `ToolPush`) or grasps (its held particles'
//! springs, `Grasp`), projected in every sweep after the strands and before the contacts
//! between bodies, as the CPU's substep does. After each substep one workgroup sums a hand's
//! pushes (or springs' multipliers) in a fixed order into its totals, which come back with the
//! particles: the tool's reaction is what the tissue did to it, summed, with no atomics.

use crate::collision::{Instrument, ToolCylinder};
use crate::gpu::compute::{self, bind};
use crate::gpu::{Gpu, RenderError};
use glam::Vec3;

/// Most cylinders of one hand's instrument on the device (an L-hook has two, a grasper
/// three).
pub const MOST_CYLINDERS: usize = 4;

/// One hand's instrument as the device takes it for a step.
#[derive(Debug, Clone)]
pub enum DeviceTool<'a> {
    None,
    /// Pushes particles out of `instrument` grown by `radius_m` (those within `margin_m` more
    /// listed at each substep's first sweep).
    Push {
        instrument: &'a Instrument,
        radius_m: f32,
        margin_m: f32,
    },
    /// Holds each particle by a spring of `stiffness_n_per_m` to its offset from the jaw.
    Grasp {
        held: &'a [(u32, Vec3)],
        jaw: Vec3,
        stiffness_n_per_m: f32,
    },
}

impl DeviceTool<'_> {
    /// Whether the device can take it: an instrument of at most [`MOST_CYLINDERS`] cylinders,
    /// each of at most [`ToolCylinder::ROW_SAMPLES`] radius samples.
    pub fn fits(instrument: &Instrument) -> bool {
        let c = instrument.cylinders();
        c.len() <= MOST_CYLINDERS && c.iter().all(|c| c.rows().is_some())
    }
}

/// The shader's `Tool` (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ToolUniform {
    jaw: [f32; 3],
    alpha: f32,
    hand: u32,
    cylinders: u32,
    items: u32,
    first: u32,
    grow: f32,
    grow_wide: f32,
    pad: [u32; 2],
}

/// What a hand does this step on the device, and over how many items.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    Idle,
    Push,
    Grasp(u32),
}

/// The entry points the instruments use, by their index in the solver's pipelines.
#[derive(Debug, Clone, Copy)]
pub struct Entries {
    pub push: usize,
    pub grasp: usize,
    pub sums: usize,
}

/// One hand's buffers written each step and its bind groups (which keep its other buffers:
/// the pushes, the list, the springs' multipliers).
struct Hand {
    cylinders: wgpu::Buffer,
    held: wgpu::Buffer,
    capacity: u32,
    /// The uniforms of a substep's first sweep and of the later ones.
    uniforms: [wgpu::Buffer; 2],
    push: [wgpu::BindGroup; 2],
    grasp: [wgpu::BindGroup; 2],
    push_sums: wgpu::BindGroup,
    grasp_sums: wgpu::BindGroup,
}

/// Both hands' instruments on one device.
pub struct ToolKernels {
    hands: Vec<Hand>,
    pub totals: wgpu::Buffer,
    pub modes: [Mode; 2],
    particles: u32,
}

/// One dispatch: an entry point, its bind group and its workgroups.
pub struct Dispatch<'a> {
    pub entry: usize,
    pub bind: &'a wgpu::BindGroup,
    pub groups: (u32, u32),
}

impl ToolKernels {
    /// The buffers for `particles` particles and `capacity` held particles a hand on `gpu`,
    /// bound to `x` (the positions) for `pipelines`.
    pub fn new(
        gpu: &Gpu,
        pipelines: &[wgpu::ComputePipeline],
        e: Entries,
        x: &wgpu::Buffer,
        particles: u32,
        capacity: u32,
    ) -> Result<ToolKernels, RenderError> {
        let totals = compute::storage(gpu, "instrument totals", &[0u8; 32])?;
        let hands = (0..2)
            .map(|h| Self::hand(gpu, pipelines, e, x, &totals, h, particles, capacity))
            .collect::<Result<Vec<_>, _>>()?;
        gpu.check()?;
        Ok(ToolKernels {
            hands,
            totals,
            modes: [Mode::Idle; 2],
            particles,
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn hand(
        gpu: &Gpu,
        pipelines: &[wgpu::ComputePipeline],
        e: Entries,
        x: &wgpu::Buffer,
        totals: &wgpu::Buffer,
        hand: u32,
        particles: u32,
        capacity: u32,
    ) -> Result<Hand, RenderError> {
        let storage = |label: &str, bytes: usize| compute::storage(gpu, label, &vec![0u8; bytes]);
        let n = particles.max(1) as usize;
        let cap = capacity.max(1) as usize;
        let cylinders = storage("instrument cylinders", 112 * MOST_CYLINDERS)?;
        let acc = storage("instrument pushes", 16 * n)?;
        let near = storage("instrument list", 4 * n)?;
        let held = storage("grasp held particles", 16 * cap)?;
        let lambda = storage("grasp multipliers", 16 * cap)?;
        let zero = bytemuck::bytes_of(&ToolUniform {
            hand,
            ..bytemuck::Zeroable::zeroed()
        })
        .to_vec();
        let uniforms = [
            compute::uniform(gpu, "instrument first sweep", &zero),
            compute::uniform(gpu, "instrument later sweeps", &zero),
        ];
        let group = |entry: usize, buffers: &[(u32, &wgpu::Buffer)]| {
            bind(gpu, &pipelines[entry], "instrument", buffers)
        };
        let push = [0usize, 1].map(|f| {
            group(
                e.push,
                &[
                    (1, x),
                    (23, &cylinders),
                    (24, &uniforms[f]),
                    (25, &acc),
                    (26, &near),
                ],
            )
        });
        let grasp = [0usize, 1].map(|f| {
            group(
                e.grasp,
                &[(1, x), (24, &uniforms[f]), (25, &lambda), (27, &held)],
            )
        });
        let push_sums = group(e.sums, &[(24, &uniforms[1]), (25, &acc), (28, totals)]);
        let grasp_sums = group(e.sums, &[(24, &uniforms[1]), (25, &lambda), (28, totals)]);
        Ok(Hand {
            cylinders,
            held,
            capacity: cap as u32,
            uniforms,
            push,
            grasp,
            push_sums,
            grasp_sums,
        })
    }

    /// The held particles each hand can take without new buffers.
    pub fn capacity(&self) -> u32 {
        self.hands.iter().map(|h| h.capacity).min().unwrap_or(0)
    }

    /// Sets each hand's instrument for the next submissions, for substeps of `dt_s` (each
    /// submission starts the totals at zero). An instrument the device cannot take is an error
    /// (check [`DeviceTool::fits`] first).
    pub fn set(
        &mut self,
        gpu: &Gpu,
        tools: &[DeviceTool; 2],
        dt_s: f32,
    ) -> Result<(), RenderError> {
        let q = &gpu.queue;
        for (h, t) in tools.iter().enumerate() {
            let hand = &self.hands[h];
            let mut u = ToolUniform {
                hand: h as u32,
                ..bytemuck::Zeroable::zeroed()
            };
            self.modes[h] = match t {
                DeviceTool::None => Mode::Idle,
                DeviceTool::Push {
                    instrument,
                    radius_m,
                    margin_m,
                } => {
                    let rows = instrument
                        .cylinders()
                        .iter()
                        .map(ToolCylinder::rows)
                        .collect::<Option<Vec<_>>>()
                        .filter(|r| r.len() <= MOST_CYLINDERS)
                        .ok_or_else(|| {
                            RenderError::Device(format!(
                                "an instrument of {} cylinders: the device takes at most {} of \
                                 at most {} radius samples each",
                                instrument.cylinders().len(),
                                MOST_CYLINDERS,
                                ToolCylinder::ROW_SAMPLES
                            ))
                        })?;
                    q.write_buffer(&hand.cylinders, 0, bytemuck::cast_slice(&rows));
                    u.cylinders = rows.len() as u32;
                    u.items = self.particles;
                    u.grow = *radius_m;
                    u.grow_wide = radius_m + margin_m;
                    Mode::Push
                }
                DeviceTool::Grasp {
                    held,
                    jaw,
                    stiffness_n_per_m,
                } => {
                    if held.len() > hand.capacity as usize {
                        return Err(RenderError::Device(format!(
                            "a grasp of {} particles: the device holds at most {}",
                            held.len(),
                            hand.capacity
                        )));
                    }
                    let rows: Vec<[f32; 4]> = held
                        .iter()
                        .map(|(i, o)| [o.x, o.y, o.z, f32::from_bits(*i)])
                        .collect();
                    if !rows.is_empty() {
                        q.write_buffer(&hand.held, 0, bytemuck::cast_slice(&rows));
                    }
                    u.jaw = jaw.to_array();
                    u.alpha = 1.0 / (stiffness_n_per_m * dt_s * dt_s);
                    u.items = held.len() as u32;
                    // A grasp without springs holds nothing, as on the CPU.
                    if *stiffness_n_per_m > 0.0 && !held.is_empty() {
                        Mode::Grasp(held.len() as u32)
                    } else {
                        Mode::Idle
                    }
                }
            };
            for (f, uniform) in hand.uniforms.iter().enumerate() {
                u.first = u32::from(f == 0);
                q.write_buffer(uniform, 0, bytemuck::bytes_of(&u));
            }
        }
        gpu.check()
    }

    /// Whether any hand pushes or grasps.
    pub fn active(&self) -> bool {
        self.modes.iter().any(|m| *m != Mode::Idle)
    }

    /// The dispatches of one sweep (`first`: a substep's first), hand by hand.
    pub fn sweep(
        &self,
        e: Entries,
        first: bool,
        groups: impl Fn(u32) -> (u32, u32),
    ) -> Vec<Dispatch<'_>> {
        let f = usize::from(!first);
        self.hands
            .iter()
            .zip(self.modes)
            .filter_map(|(h, m)| match m {
                Mode::Idle => None,
                Mode::Push => Some(Dispatch {
                    entry: e.push,
                    bind: &h.push[f],
                    groups: groups(self.particles),
                }),
                Mode::Grasp(n) => Some(Dispatch {
                    entry: e.grasp,
                    bind: &h.grasp[f],
                    groups: groups(n),
                }),
            })
            .collect()
    }

    /// The sums after a substep, hand by hand (one workgroup each).
    pub fn sums(&self, e: Entries) -> Vec<Dispatch<'_>> {
        self.hands
            .iter()
            .zip(self.modes)
            .filter_map(|(h, m)| {
                let bind = match m {
                    Mode::Idle => return None,
                    Mode::Push => &h.push_sums,
                    Mode::Grasp(_) => &h.grasp_sums,
                };
                Some(Dispatch {
                    entry: e.sums,
                    bind,
                    groups: (1, 1),
                })
            })
            .collect()
    }

    /// The fewest bytes the instruments move in a substep of `iterations` sweeps: a pushing
    /// hand's list (a position read and a flag written: 20 bytes a particle) and each sweep's
    /// test (a flag read, its sums read and written: 36), its sums (16); a grasping hand's
    /// held particle each sweep (its row, its position read and written, its multiplier read
    /// and written: 80).
    pub fn bytes_per_substep(&self, iterations: u32) -> u64 {
        let sweeps = u64::from(iterations.max(1));
        let n = u64::from(self.particles);
        self.modes
            .iter()
            .map(|m| match m {
                Mode::Idle => 0,
                Mode::Push => n * 20 + sweeps * n * 36 + n * 16,
                Mode::Grasp(k) => sweeps * u64::from(*k) * 80,
            })
            .sum()
    }
}

/// The totals read back: per hand, the sum over the submission's substeps of what it pushed
/// over each particle's inverse mass (or of its springs' multipliers), m kg, and the most
/// particles pushed in a substep's last sweep.
pub fn totals_from(raw: &[u8]) -> [[f32; 4]; 2] {
    let f = |k: usize| {
        raw.get(4 * k..4 * k + 4)
            .map_or(0.0, |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    [[f(0), f(1), f(2), f(3)], [f(4), f(5), f(6), f(7)]]
}
