//! What the particle solver's device sends back (`gpu.rs`). Everything a download reads is
//! copied into one kept mappable buffer inside the submission that stepped, and decoded from
//! it in place. A submission split after its first substep also copies that substep's state
//! into a second region of the buffer, so that the CPU can check, from the first substep's
//! particles, whether anything falls between the two (`device.rs`), and either keep the second
//! substep or send the first's state up again.

use super::{Particles, ParticlesGpu};
use crate::gpu::RenderError;
use crate::gpu::compute;
use crate::models::particles::gpu_tools::totals_from;
use crate::models::particles::shape::ShapeMatching;
use glam::Vec3;

/// Where each part of a readback lies in a region of the readback buffer, bytes: the
/// positions, step starts and velocities (`vec4` a particle each), the instruments' totals
/// (32), the timestamps (16), then the clusters' state (32 a cluster) and goal frames (64).
/// Region 0 holds a submission's end, region 1 its state after the first substep where it was
/// split.
#[derive(Debug, Clone, Copy)]
pub(super) struct Readback {
    per_particle: u64,
    totals: u64,
    timestamps: u64,
    state: u64,
    frames: u64,
    pub(super) total: u64,
}

impl Readback {
    pub(super) fn of(particles: u64, clusters: u64) -> Readback {
        let per_particle = 16 * particles;
        let totals = 3 * per_particle;
        let timestamps = totals + 32;
        let state = timestamps + 16;
        let frames = state + 32 * clusters;
        Readback {
            per_particle,
            totals,
            timestamps,
            state,
            frames,
            total: frames + 64 * clusters,
        }
    }

    /// The readback buffer's size: both regions.
    pub(super) fn buffer_bytes(particles: u64, clusters: u64) -> u64 {
        2 * Readback::of(particles, clusters).total
    }
}

/// The `k`th `vec4` from `at` in `raw` (zeros past its end).
fn vec4_at(raw: &[u8], at: u64, k: usize) -> [f32; 4] {
    let from = at as usize + 16 * k;
    raw.get(from..from + 16)
        .map_or([0.0; 4], bytemuck::pod_read_unaligned::<[f32; 4]>)
}

/// One region's positions, step starts and velocities into `x`, `x0` and `v`.
fn particles_from(raw: &[u8], at: &Readback, x: &mut [Vec3], x0: &mut [Vec3], v: &mut [Vec3]) {
    let xyz = |v: [f32; 4]| Vec3::new(v[0], v[1], v[2]);
    for (k, ((x, x0), v)) in x.iter_mut().zip(x0).zip(v).enumerate() {
        *x = xyz(vec4_at(raw, 0, k));
        *x0 = xyz(vec4_at(raw, at.per_particle, k));
        *v = xyz(vec4_at(raw, 2 * at.per_particle, k));
    }
}

/// One region's clusters' state rows (two a cluster) and frame rows (four).
fn clusters_from(raw: &[u8], at: &Readback, clusters: usize) -> (Vec<[f32; 4]>, Vec<[f32; 4]>) {
    (
        (0..2 * clusters)
            .map(|j| vec4_at(raw, at.state, j))
            .collect(),
        (0..4 * clusters)
            .map(|j| vec4_at(raw, at.frames, j))
            .collect(),
    )
}

/// The end of a submission split after its first substep, held on the CPU while the first
/// substep's state is checked ([`ParticlesGpu::download_split`]).
#[derive(Debug, Default)]
pub struct Later {
    x: Vec<Vec3>,
    x0: Vec<Vec3>,
    v: Vec<Vec3>,
    state: Vec<[f32; 4]>,
    frames: Vec<[f32; 4]>,
    totals: [[f32; 4]; 2],
}

impl Later {
    /// Takes the second substep's particles and clusters into `p` and `s` (the first's are
    /// dropped); returns the instruments' totals over the second substep.
    pub fn apply(&mut self, p: &mut Particles, s: &mut ShapeMatching) -> [[f32; 4]; 2] {
        let n = self.x.len().min(p.len());
        p.x[..n].copy_from_slice(&self.x[..n]);
        p.x0[..n].copy_from_slice(&self.x0[..n]);
        p.v[..n].copy_from_slice(&self.v[..n]);
        s.take_device_state(&self.state, &self.frames, &[]);
        self.totals
    }
}

impl ParticlesGpu {
    /// Copies of everything a download reads into region `region` of the readback buffer
    /// (the timestamps too where `timed`).
    pub(super) fn encode_copies(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        region: u64,
        timed: bool,
    ) {
        let at = Readback::of(u64::from(self.particles), u64::from(self.clusters));
        let base = region * at.total;
        let n = at.per_particle;
        for (k, b) in [&self.x, &self.x0, &self.v].into_iter().enumerate() {
            encoder.copy_buffer_to_buffer(b, 0, &self.readback, base + k as u64 * n, n);
        }
        if let Some(t) = self.tools.as_ref().filter(|t| t.active()) {
            encoder.copy_buffer_to_buffer(&t.totals, 0, &self.readback, base + at.totals, 32);
        }
        if let (Some(t), true) = (&self.timer, timed) {
            t.copy_into(encoder, &self.readback, base + at.timestamps);
        }
        let k = u64::from(self.clusters);
        if k > 0 {
            let (state, frames) = (base + at.state, base + at.frames);
            encoder.copy_buffer_to_buffer(&self.cluster_state, 0, &self.readback, state, 32 * k);
            encoder.copy_buffer_to_buffer(&self.frames, 0, &self.readback, frames, 64 * k);
        }
        if region == 0 {
            self.copied.set(true);
        }
    }

    /// Waits for the device and copies its positions, step starts and velocities into `p`,
    /// all read in one round trip (`p` is written only once all of it came back).
    pub fn download(&self, p: &mut Particles) -> Result<(), RenderError> {
        self.read(p, None).map(|_| ())
    }

    /// [`ParticlesGpu::download`], and the clusters' centres, rotations and goal frames into
    /// `s` (in the same round trip), so the CPU can go on from here. The springs'
    /// multipliers stay on the device: every substep starts them at zero. Returns the
    /// instruments' totals over the last submission (`gpu_tools::totals_from`; zeros without
    /// instruments).
    pub fn download_all(
        &self,
        p: &mut Particles,
        s: &mut ShapeMatching,
    ) -> Result<[[f32; 4]; 2], RenderError> {
        self.read(p, Some(s))
    }

    fn tools_active(&self) -> bool {
        self.tools.as_ref().is_some_and(|t| t.active())
    }

    fn read(
        &self,
        p: &mut Particles,
        s: Option<&mut ShapeMatching>,
    ) -> Result<[[f32; 4]; 2], RenderError> {
        let at = Readback::of(u64::from(self.particles), u64::from(self.clusters));
        if !self.copied.get() {
            // Something went up since the last submission's copies: copy again.
            let mut encoder =
                self.gpu
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("particle readback"),
                    });
            self.encode_copies(&mut encoder, 0, true);
            self.gpu.queue.submit([encoder.finish()]);
        }
        let bytes = if s.is_some() { at.total } else { at.state };
        let mut rows = (Vec::new(), Vec::new());
        let n = p.len().min(self.particles as usize);
        let (totals, seconds) = compute::with_mapped(&self.gpu, &self.readback, bytes, |raw| {
            let _span = tracing::debug_span!("particles_gpu_decode").entered();
            particles_from(raw, &at, &mut p.x[..n], &mut p.x0[..n], &mut p.v[..n]);
            if s.is_some() {
                rows = clusters_from(raw, &at, self.clusters as usize);
            }
            let totals = if self.tools_active() {
                totals_from(&raw[at.totals as usize..at.timestamps as usize])
            } else {
                [[0.0; 4]; 2]
            };
            let ts = &raw[at.timestamps as usize..at.state as usize];
            (totals, self.timer.as_ref().map(|t| t.seconds_of(ts)))
        })?;
        self.gpu.check()?;
        self.read_kernel_s.set(seconds);
        if let Some(s) = s {
            s.take_device_state(&rows.0, &rows.1, &[]);
        }
        Ok(totals)
    }

    /// After [`ParticlesGpu::advance_split`]: waits for the device and reads both substeps in
    /// one round trip, the first's particles and clusters into `p` and `s` and the second's
    /// into `later`. Returns the instruments' totals over the first substep. An error where the
    /// last submission was not split, or something went up since it.
    pub fn download_split(
        &self,
        p: &mut Particles,
        s: &mut ShapeMatching,
        later: &mut Later,
    ) -> Result<[[f32; 4]; 2], RenderError> {
        if !(self.split.get() && self.copied.get()) {
            return Err(RenderError::Device(
                "no split submission's results to read: the last submission ran whole, or the \
                 particles went up since"
                    .into(),
            ));
        }
        let at = Readback::of(u64::from(self.particles), u64::from(self.clusters));
        let n = p.len().min(self.particles as usize);
        for v in [&mut later.x, &mut later.x0, &mut later.v] {
            v.resize(n, Vec3::ZERO);
        }
        let clusters = self.clusters as usize;
        let tools = self.tools_active();
        let mut first_rows = (Vec::new(), Vec::new());
        let (first, seconds) =
            compute::with_mapped(&self.gpu, &self.readback, 2 * at.total, |raw| {
                let _span = tracing::debug_span!("particles_gpu_decode").entered();
                let (end, between) = raw.split_at(at.total as usize);
                particles_from(between, &at, &mut p.x[..n], &mut p.x0[..n], &mut p.v[..n]);
                particles_from(end, &at, &mut later.x, &mut later.x0, &mut later.v);
                first_rows = clusters_from(between, &at, clusters);
                (later.state, later.frames) = clusters_from(end, &at, clusters);
                let totals = |r: &[u8]| {
                    if tools {
                        totals_from(&r[at.totals as usize..at.timestamps as usize])
                    } else {
                        [[0.0; 4]; 2]
                    }
                };
                later.totals = totals(end);
                let ts = &end[at.timestamps as usize..at.state as usize];
                (
                    totals(between),
                    self.timer.as_ref().map(|t| t.seconds_of(ts)),
                )
            })?;
        self.gpu.check()?;
        self.read_kernel_s.set(seconds);
        s.take_device_state(&first_rows.0, &first_rows.1, &[]);
        Ok(first)
    }
}
