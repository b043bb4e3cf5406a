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
/// positions and velocities (`vec4` a particle each), the instruments' totals (32), the
/// timestamps (16), then the step starts (`vec4` a particle), the clusters' state (32 a
/// cluster) and goal frames (64). A session's substeps read only what lies before the step
/// starts (`lean`): the CPU's next substep forms its own step starts, and the clusters stay on
/// the device until the CPU steps them itself. Region 0 holds a submission's end, region 1 its
/// state after the first substep where it was split.
#[derive(Debug, Clone, Copy)]
pub(super) struct Readback {
    per_particle: u64,
    totals: u64,
    timestamps: u64,
    lean: u64,
    state: u64,
    frames: u64,
    pub(super) total: u64,
}

impl Readback {
    pub(super) fn of(particles: u64, clusters: u64) -> Readback {
        let per_particle = 16 * particles;
        let totals = 2 * per_particle;
        let timestamps = totals + 32;
        let lean = timestamps + 16;
        let state = lean + per_particle;
        let frames = state + 32 * clusters;
        Readback {
            per_particle,
            totals,
            timestamps,
            lean,
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

/// The `vec4`s from `at` in `raw` into `out`, as `from` makes each (zeros past the end).
fn vec4s_into<T>(raw: &[u8], at: u64, out: &mut [T], from: impl Fn([f32; 4]) -> T) {
    let start = (at as usize).min(raw.len());
    let bytes = &raw[start..raw.len().min(start + 16 * out.len())];
    // In place where the mapping is aligned (it is on every driver met), else word by word.
    let n = bytes.len() / 16;
    match bytemuck::try_cast_slice::<u8, [f32; 4]>(&bytes[..16 * n]) {
        Ok(rows) => out.iter_mut().zip(rows).for_each(|(d, r)| *d = from(*r)),
        Err(_) => out
            .iter_mut()
            .zip(bytes.chunks_exact(16))
            .for_each(|(d, r)| *d = from(bytemuck::pod_read_unaligned(r))),
    }
    out.iter_mut().skip(n).for_each(|d| *d = from([0.0; 4]));
}

fn xyz(v: [f32; 4]) -> Vec3 {
    Vec3::new(v[0], v[1], v[2])
}

/// One region's positions and velocities into `x` and `v`, and its step starts into `x0`
/// where asked.
fn particles_from(
    raw: &[u8],
    at: &Readback,
    x: &mut [Vec3],
    v: &mut [Vec3],
    x0: Option<&mut [Vec3]>,
) {
    vec4s_into(raw, 0, x, xyz);
    vec4s_into(raw, at.per_particle, v, xyz);
    if let Some(x0) = x0 {
        vec4s_into(raw, at.lean, x0, xyz);
    }
}

/// One region's clusters' state rows (two a cluster) into `state`, and frame rows (four)
/// into `frames` where asked.
fn clusters_from(
    raw: &[u8],
    at: &Readback,
    clusters: usize,
    state: &mut Vec<[f32; 4]>,
    frames: Option<&mut Vec<[f32; 4]>>,
) {
    state.resize(2 * clusters, [0.0; 4]);
    vec4s_into(raw, at.state, state, |r| r);
    if let Some(f) = frames {
        f.resize(4 * clusters, [0.0; 4]);
        vec4s_into(raw, at.frames, f, |r| r);
    }
}

/// The end of a submission split after its first substep, held on the CPU while the first
/// substep's state is checked ([`ParticlesGpu::download_split`]), and the first substep's
/// clusters' state, to go up again should the second substep run again.
#[derive(Debug, Default)]
pub struct Later {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    totals: [[f32; 4]; 2],
    first_state: Vec<[f32; 4]>,
}

impl Later {
    /// Takes the second substep's particles into `p` (the first's are dropped); returns the
    /// instruments' totals over the second substep. The clusters stay on the device.
    pub fn apply(&mut self, p: &mut Particles) -> [[f32; 4]; 2] {
        let n = self.x.len().min(p.len());
        p.x[..n].copy_from_slice(&self.x[..n]);
        p.v[..n].copy_from_slice(&self.v[..n]);
        self.totals
    }

    /// The first substep's clusters' state rows (to go up should the second run again).
    pub fn first_state(&self) -> &[[f32; 4]] {
        &self.first_state
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
        for (b, to) in [(&self.x, 0), (&self.v, n), (&self.x0, at.lean)] {
            encoder.copy_buffer_to_buffer(b, 0, &self.readback, base + to, n);
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
        self.read(p, Read::Particles).map(|_| ())
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
        self.read(p, Read::All(s))
    }

    /// What a session's substep reads: the positions and velocities into `p` (not the step
    /// starts, which the CPU's next substep forms itself), and the instruments' totals
    /// (returned). The clusters stay on the device ([`ParticlesGpu::download_clusters`]).
    pub fn download_lean(&self, p: &mut Particles) -> Result<[[f32; 4]; 2], RenderError> {
        self.read(p, Read::Lean)
    }

    /// The clusters' centres, rotations and goal frames of the last submission into `s`
    /// (before the CPU steps them itself).
    pub fn download_clusters(&self, s: &mut ShapeMatching) -> Result<(), RenderError> {
        self.read(&mut Particles::new(), Read::Clusters(s))
            .map(|_| ())
    }

    fn tools_active(&self) -> bool {
        self.tools.as_ref().is_some_and(|t| t.active())
    }

    fn read(&self, p: &mut Particles, what: Read<'_>) -> Result<[[f32; 4]; 2], RenderError> {
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
        let bytes = match what {
            Read::Lean => at.lean,
            Read::Particles => at.state,
            Read::All(_) | Read::Clusters(_) => at.total,
        };
        let (mut state, mut frames) = (Vec::new(), Vec::new());
        let n = p.len().min(self.particles as usize);
        let clusters = matches!(what, Read::All(_) | Read::Clusters(_));
        let x0 = matches!(what, Read::All(_) | Read::Particles);
        let (totals, seconds) = compute::with_mapped(&self.gpu, &self.readback, bytes, |raw| {
            let _span = tracing::debug_span!("particles_gpu_decode").entered();
            let x0 = x0.then_some(&mut p.x0[..n]);
            particles_from(raw, &at, &mut p.x[..n], &mut p.v[..n], x0);
            if clusters {
                let k = self.clusters as usize;
                clusters_from(raw, &at, k, &mut state, Some(&mut frames));
            }
            let totals = if self.tools_active() {
                totals_from(&raw[at.totals as usize..at.timestamps as usize])
            } else {
                [[0.0; 4]; 2]
            };
            let ts = &raw[at.timestamps as usize..at.lean as usize];
            (totals, self.timer.as_ref().map(|t| t.seconds_of(ts)))
        })?;
        self.gpu.check()?;
        self.read_kernel_s.set(seconds);
        if let Read::All(s) | Read::Clusters(s) = what {
            s.take_device_state(&state, &frames, &[]);
        }
        Ok(totals)
    }

    /// After [`ParticlesGpu::advance_split`]: waits for the device and reads both substeps in
    /// one round trip (as [`ParticlesGpu::download_lean`] reads), the first's particles into
    /// `p` and its clusters' state into `later`, the second's particles into `later`. Returns
    /// the instruments' totals over the first substep. An error where the last submission was
    /// not split, or something went up since it.
    pub fn download_split(
        &self,
        p: &mut Particles,
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
        for v in [&mut later.x, &mut later.v] {
            v.resize(n, Vec3::ZERO);
        }
        let clusters = self.clusters as usize;
        let tools = self.tools_active();
        let (first, seconds) =
            compute::with_mapped(&self.gpu, &self.readback, 2 * at.total, |raw| {
                let _span = tracing::debug_span!("particles_gpu_decode").entered();
                let (end, between) = raw.split_at(at.total as usize);
                particles_from(between, &at, &mut p.x[..n], &mut p.v[..n], None);
                particles_from(end, &at, &mut later.x, &mut later.v, None);
                clusters_from(between, &at, clusters, &mut later.first_state, None);
                let totals = |r: &[u8]| {
                    if tools {
                        totals_from(&r[at.totals as usize..at.timestamps as usize])
                    } else {
                        [[0.0; 4]; 2]
                    }
                };
                later.totals = totals(end);
                let ts = &end[at.timestamps as usize..at.lean as usize];
                (
                    totals(between),
                    self.timer.as_ref().map(|t| t.seconds_of(ts)),
                )
            })?;
        self.gpu.check()?;
        self.read_kernel_s.set(seconds);
        Ok(first)
    }
}

/// What [`ParticlesGpu::read`] reads.
enum Read<'a> {
    Lean,
    Particles,
    All(&'a mut ShapeMatching),
    Clusters(&'a mut ShapeMatching),
}
