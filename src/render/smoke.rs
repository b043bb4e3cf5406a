//! Smoke as particles: each emission of a snapshot becomes a few puffs whose place, size and
//! alpha are a pure function of the emission's age (the snapshot's time less the emission's)
//! and a hash of its time. Nothing is simulated or kept between frames and no clock or
//! random generator is read: the same snapshot draws the same pixels, so a replay's frames
//! are the same bytes.

use super::camera::NEAR_M;
use super::{EyeView, pipelines::PARTICLE_BYTES, tracked_buffer};
use crate::profiler::{Category, FrameCounters, Ledger, Tracked};
use crate::sim::Fnv;
use crate::sim::{Bleed, Emission, EmissionKind};
use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use std::sync::Arc;

/// How long a puff lasts, s: electrocautery smoke thins out within a second or two.
pub const LIFETIME_S: f32 = 1.5;
/// Puffs per emission (an emission every 15 ms while the hook cuts: about 330 puffs a second).
pub const PUFFS_PER_EMISSION: u32 = 5;
/// Rise speed, m/s, between these (warm vapour rising a few cm/s in the still cavity).
const RISE_M_PER_S: [f32; 2] = [0.02, 0.035];
/// Sideways drift, m/s, between these, in a direction of its own per puff.
const DRIFT_M_PER_S: [f32; 2] = [0.002, 0.008];
/// A swirl about the drift: amplitude, m, and angular speed, rad/s.
const SWIRL_M: f32 = 0.001;
const SWIRL_RAD_PER_S: f32 = 5.0;
/// Where puffs start: within this radius of the emission's point, m.
const SPREAD_M: f32 = 0.0015;
/// Radius at birth, m, and growth, m/s, between these (it spreads as it rises).
const START_RADIUS_M: f32 = 0.0015;
const GROWTH_M_PER_S: [f32; 2] = [0.004, 0.007];
/// Alpha at a puff's middle when young: low, since the puffs of 100 emissions overlap in a
/// continuous cut (the plume stays see-through: the trainee must see the plane).
const PEAK_ALPHA: f32 = 0.16;
/// The time a puff takes to appear (no popping in at full density), s.
const FADE_IN_S: f32 = 0.06;

/// One puff at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Puff {
    pub centre: Vec3,
    pub radius_m: f32,
    /// Alpha at the middle of the disc (the shader fades it to nothing at the rim).
    pub alpha: f32,
    /// Grey level, 0-1.
    pub grey: f32,
}

/// An emission's seed: a hash of its time's bits (the same emission keeps its seed as others
/// come and go around it in later snapshots).
pub fn seed(e: &Emission) -> u64 {
    let bits = e.time_s.to_bits();
    let mut h = Fnv::default();
    h.write(bits as u32);
    h.write((bits >> 32) as u32);
    h.write(match e.kind {
        EmissionKind::Smoke => 1,
    });
    h.0
}

/// A number in [0, 1) for puff `k`'s property `j` of the emission seeded `seed`.
pub(super) fn unit(seed: u64, k: u32, j: u32) -> f32 {
    let mut h = Fnv(seed);
    h.write(k);
    h.write(j);
    // FNV's last multiply mixes the last bytes into the high bits only partly: fold first.
    let x = h.0 ^ (h.0 >> 29);
    let x = x.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    (x >> 40) as f32 / (1u64 << 24) as f32
}

fn between(range: [f32; 2], u: f32) -> f32 {
    range[0] + (range[1] - range[0]) * u
}

/// Puff `k` of an emission at `origin` seeded `seed`, `age_s` after it; none before it or
/// from `LIFETIME_S` on. It rises (+y) at a constant speed, drifts and swirls sideways, grows,
/// and fades in quickly and out as the square of the life left.
pub fn puff(origin: Vec3, seed: u64, k: u32, age_s: f32) -> Option<Puff> {
    if !(0.0..LIFETIME_S).contains(&age_s) {
        return None;
    }
    let u = |j: u32| unit(seed, k, j);
    let start_angle = u(0) * std::f32::consts::TAU;
    let start_r = SPREAD_M * u(1).sqrt();
    let drift_angle = u(2) * std::f32::consts::TAU;
    let drift = between(DRIFT_M_PER_S, u(3));
    let rise = between(RISE_M_PER_S, u(4));
    let growth = between(GROWTH_M_PER_S, u(5));
    let phase = u(6) * std::f32::consts::TAU;
    let flat = |angle: f32| Vec3::new(angle.cos(), 0.0, angle.sin());
    let swirl = SWIRL_M * (SWIRL_RAD_PER_S * age_s + phase).sin();
    let centre = origin
        + flat(start_angle) * start_r
        + flat(drift_angle) * (drift * age_s)
        + flat(drift_angle + std::f32::consts::FRAC_PI_2) * swirl
        + Vec3::Y * (rise * age_s);
    let left = 1.0 - age_s / LIFETIME_S;
    let fade_in = (age_s / FADE_IN_S).min(1.0);
    Some(Puff {
        centre,
        radius_m: START_RADIUS_M + growth * age_s,
        alpha: PEAK_ALPHA * (0.7 + 0.3 * u(7)) * fade_in * left * left,
        grey: 0.72 + 0.2 * u(8),
    })
}

/// One particle as the smoke pipeline reads it (see `pipelines::PARTICLE_BYTES`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(super) struct Particle {
    pub centre: [f32; 3],
    /// Radius (m), alpha, grey (negative: blood, `blood::BLOOD_GREY`).
    pub look: [f32; 3],
}

const _: () = assert!(std::mem::size_of::<Particle>() as u64 == PARTICLE_BYTES);

/// The visible puffs of `emissions` at `time_s`, farthest from the eyes' midpoint first
/// (blending over needs back to front; the eyes of a stereo pair are close enough to share
/// one order). A puff reaching within twice the near plane of an eye is left out, as
/// instruments are clipped there: lavapipe draws near-clipped triangles of one view of a
/// multiview pass into the other's layer.
fn particles(
    emissions: &[Emission],
    bleeds: &[Bleed],
    time_s: f64,
    eyes: &[EyeView; 2],
    out: &mut Vec<Particle>,
) {
    out.clear();
    let viewer = 0.5 * (eyes[0].position + eyes[1].position);
    let clear = |centre: Vec3, radius_m: f32| {
        eyes.iter().all(|e| {
            let forward = e.orientation * Vec3::NEG_Z;
            (centre - e.position).dot(forward) > 2.0 * NEAR_M + radius_m
        })
    };
    let clear_of_eyes = |p: &Puff| clear(p.centre, p.radius_m);
    super::blood::particles(bleeds, time_s, viewer, clear, out);
    for e in emissions {
        let age = (time_s - e.time_s) as f32;
        let s = seed(e);
        for k in 0..PUFFS_PER_EMISSION {
            let p = puff(e.position, s, k, age).filter(|p| p.alpha > 0.0 && clear_of_eyes(p));
            if let Some(p) = p {
                out.push(Particle {
                    centre: p.centre.to_array(),
                    look: [p.radius_m, p.alpha, p.grey],
                });
            }
        }
    }
    // Far to near by squared distance; a stable sort keeps ties in emission order, so the
    // order is the same every time. (A puff off a non-finite position fails the eye test
    // above and is not here.)
    let d = |p: &Particle| Vec3::from_array(p.centre).distance_squared(viewer);
    out.sort_by(|a, b| d(b).total_cmp(&d(a)));
}

/// The smoke's particles on the GPU, one instance each, rebuilt every frame.
pub(super) struct SmokeBuffer {
    buffer: Tracked<wgpu::Buffer>,
    count: u32,
    particles: Vec<Particle>,
}

impl SmokeBuffer {
    pub fn new(device: &wgpu::Device, ledger: &Arc<Ledger>) -> Self {
        SmokeBuffer {
            buffer: instance_buffer(device, ledger, 0),
            count: 0,
            particles: Vec::new(),
        }
    }

    /// Particles currently in the buffer.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Fills the buffer with the puffs of `emissions` and the blood of `bleeds` at `time_s`
    /// for these eyes (grown by a quarter more than needed when they do not fit).
    pub fn update(
        &mut self,
        (device, queue, ledger): (&wgpu::Device, &wgpu::Queue, &Arc<Ledger>),
        (emissions, bleeds, time_s): (&[Emission], &[Bleed], f64),
        eyes: &[EyeView; 2],
    ) {
        particles(emissions, bleeds, time_s, eyes, &mut self.particles);
        let bytes = std::mem::size_of_val(&self.particles[..]) as u64;
        if bytes > self.buffer.bytes() {
            self.buffer = instance_buffer(device, ledger, bytes + bytes / 4);
        }
        if bytes > 0 {
            queue.write_buffer(&self.buffer, 0, bytemuck::cast_slice(&self.particles));
        }
        self.count = self.particles.len() as u32;
    }

    /// Draws every particle as one quad (6 vertices) in one instanced draw, with `pipeline`.
    pub fn draw(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        pipeline: &wgpu::RenderPipeline,
        c: &mut FrameCounters,
    ) {
        if self.count == 0 {
            return;
        }
        pass.set_pipeline(pipeline);
        c.setpass_calls += 1;
        pass.set_vertex_buffer(0, self.buffer.inner.slice(..));
        pass.draw(0..6, 0..self.count);
        c.draw_calls += 1;
        c.triangles += 2 * u64::from(self.count);
        c.vertices += 6 * u64::from(self.count);
    }
}

/// A buffer for at least `bytes` of particles (room for 64 at the least).
fn instance_buffer(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    bytes: u64,
) -> Tracked<wgpu::Buffer> {
    tracked_buffer(
        device,
        ledger,
        "smoke",
        bytes.max(64 * PARTICLE_BYTES),
        wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        Category::Mesh,
    )
}

#[cfg(test)]
mod tests {
    use super::super::camera::stereo_eyes;
    use super::*;

    fn emission(time_s: f64) -> Emission {
        Emission {
            time_s,
            position: Vec3::new(0.01, 0.02, 0.03),
            kind: EmissionKind::Smoke,
        }
    }

    #[test]
    fn puffs_rise_grow_and_fade_out_by_the_end_of_their_life() {
        let e = emission(1.234);
        let s = seed(&e);
        for k in 0..PUFFS_PER_EMISSION {
            let at = |age: f32| puff(e.position, s, k, age);
            assert_eq!(at(-0.001), None, "not before the emission");
            assert_eq!(at(LIFETIME_S), None, "gone at the end of its life");
            let ages: Vec<f32> = (0..30).map(|n| n as f32 * LIFETIME_S / 30.0).collect();
            let puffs: Vec<Puff> = ages.iter().filter_map(|&a| at(a)).collect();
            assert_eq!(puffs.len(), ages.len());
            for w in puffs.windows(2) {
                assert!(w[1].centre.y > w[0].centre.y, "puff {k} rises: {w:?}");
                assert!(w[1].radius_m > w[0].radius_m, "puff {k} grows");
            }
            // A few cm/s: 0.3 s on it has risen 6-10.5 mm, and stayed within a cm sideways.
            let p = at(0.3).expect("alive");
            let rise = p.centre.y - e.position.y;
            assert!((0.006..=0.0105).contains(&rise), "rose {rise} m");
            let side = (p.centre - e.position).with_y(0.0).length();
            assert!(side < 0.01, "drifted {side} m");
            // Young puffs are seen; by the end of the lifetime alpha has gone to zero.
            assert!(at(0.2).expect("alive").alpha > 0.05);
            let late = at(LIFETIME_S - 0.01).expect("alive");
            assert!(late.alpha < 1e-3, "alpha {} near the end", late.alpha);
            let alphas: Vec<f32> = puffs.iter().skip(2).map(|p| p.alpha).collect();
            assert!(
                alphas.windows(2).all(|w| w[1] < w[0]),
                "fades out steadily: {alphas:?}"
            );
        }
    }

    #[test]
    fn puffs_are_a_pure_function_of_the_emission_and_its_age() {
        let (a, b) = (emission(0.5), emission(0.515));
        assert_eq!(seed(&a), seed(&emission(0.5)));
        assert_ne!(seed(&a), seed(&b));
        for k in 0..PUFFS_PER_EMISSION {
            assert_eq!(
                puff(a.position, seed(&a), k, 0.4),
                puff(a.position, seed(&a), k, 0.4)
            );
            // Another emission's puffs take other paths; and puffs of one emission differ.
            assert_ne!(
                puff(a.position, seed(&a), k, 0.4),
                puff(b.position, seed(&b), k, 0.4)
            );
        }
        assert_ne!(
            puff(a.position, seed(&a), 0, 0.4),
            puff(a.position, seed(&a), 1, 0.4)
        );
        // The hash spreads over [0, 1).
        let us: Vec<f32> = (0..1000).map(|k| unit(seed(&a), k, 3)).collect();
        assert!(us.iter().all(|u| (0.0..1.0).contains(u)));
        let mean = us.iter().sum::<f32>() / us.len() as f32;
        assert!((mean - 0.5).abs() < 0.05, "mean {mean}");
        assert!(us.iter().filter(|&&u| u < 0.1).count() > 50);
        // The same snapshot, the same particles in the same order.
        let list = [a, b, emission(1.0)];
        let (mut p, mut q) = (Vec::new(), Vec::new());
        let viewer = Vec3::new(0.1, 0.1, 0.1);
        let eyes = stereo_eyes(viewer, a.position, 0.06);
        particles(&list, &[], 1.1, &eyes, &mut p);
        particles(&list, &[], 1.1, &eyes, &mut q);
        assert_eq!(p.len(), 3 * PUFFS_PER_EMISSION as usize);
        assert_eq!(
            bytemuck::cast_slice::<_, u8>(&p),
            bytemuck::cast_slice::<_, u8>(&q)
        );
        // Back to front.
        let d: Vec<f32> = p
            .iter()
            .map(|p| Vec3::from_array(p.centre).distance(viewer))
            .collect();
        assert!(d.windows(2).all(|w| w[0] >= w[1]));
        // Past their lifetime, emissions draw nothing.
        particles(&list, &[], 2.6, &eyes, &mut p);
        assert!(p.is_empty());
        // Nor do puffs at the eyes or behind them.
        // Eyes 15 mm under the source looking up: the young puffs (2-3.5 mm up) are within
        // 2 cm of them, the older ones (12-21 mm up) not.
        let close = stereo_eyes(a.position - Vec3::Y * 0.015, a.position + Vec3::Y, 0.06);
        particles(&list, &[], 1.1, &close, &mut p);
        assert!(
            !p.is_empty() && p.len() < 3 * PUFFS_PER_EMISSION as usize,
            "{} puffs",
            p.len()
        );
        let behind = stereo_eyes(a.position + Vec3::Y, a.position + 2.0 * Vec3::Y, 0.06);
        particles(&list, &[], 1.1, &behind, &mut p);
        assert!(p.is_empty(), "{p:?}");
    }
}
