//! Blood, drawn with the smoke's particles: where a source bleeds, a pool spreads over the
//! tissue and drops run from the source; when the bleeding stops, the pool stays as it was
//! and the drops end. Like the smoke, a pure function of the snapshot (its time and its
//! bleeding sources): the same snapshot draws the same pixels.
//!
//! The pool is a film of constant depth fed at a constant rate, so its area grows linearly
//! with the time it has bled, `POOL_M2_PER_S` a second (a 6 mm radius after 1 s), up to
//! `POOL_MAX_RADIUS_M`.

use super::smoke::{Particle, unit};
use crate::sim::Bleed;
use glam::Vec3;

/// The pool's area growth while it bleeds, m^2/s.
pub const POOL_M2_PER_S: f32 = 1.13e-4;
/// The pool's largest radius, m.
pub const POOL_MAX_RADIUS_M: f32 = 0.02;
/// Discs a pool is drawn with: one in the middle, the rest around it (an uneven outline).
const POOL_DISCS: u32 = 7;
/// Drops running from a source while it bleeds, each falling `DROP_FALL_M` over its period.
const DROPS: u32 = 4;
const DROP_PERIOD_S: f32 = 0.6;
const DROP_FALL_M: f32 = 0.012;
const DROP_RADIUS_M: f32 = 0.0008;
/// How far towards the viewer the blood is drawn, m: it lies on the surface, not inside it.
const LIFT_M: f32 = 0.0015;
const ALPHA: f32 = 0.9;
/// The particles' grey level for blood: a negative value tells the shader to draw blood.
pub const BLOOD_GREY: f32 = -1.0;

/// The pool's radius after bleeding `bled_s` seconds, m.
pub fn pool_radius_m(bled_s: f64) -> f32 {
    ((POOL_M2_PER_S * bled_s as f32) / std::f32::consts::PI)
        .sqrt()
        .min(POOL_MAX_RADIUS_M)
}

/// Appends the blood of `bleeds` at `time_s`, seen from `viewer`, keeping only particles
/// `keep` accepts (clear of the eyes' near planes).
pub(super) fn particles(
    bleeds: &[Bleed],
    time_s: f64,
    viewer: Vec3,
    keep: impl Fn(Vec3, f32) -> bool,
    out: &mut Vec<Particle>,
) {
    for (n, b) in bleeds.iter().enumerate() {
        let bled = b.bled_s(time_s);
        if bled <= 0.0 {
            continue;
        }
        let towards = (viewer - b.position).normalize_or_zero() * LIFT_M;
        let radius = pool_radius_m(bled);
        let seed = 0x9e37_79b9 ^ b.start_s.to_bits() ^ n as u64;
        let side = (viewer - b.position).cross(Vec3::Y).normalize_or(Vec3::X);
        let up = side.cross((viewer - b.position).normalize_or(Vec3::Z));
        let mut push = |centre: Vec3, r: f32, alpha: f32| {
            if keep(centre, r) {
                out.push(Particle {
                    centre: centre.to_array(),
                    look: [r, alpha, BLOOD_GREY],
                });
            }
        };
        for k in 0..POOL_DISCS {
            let (offset, r) = if k == 0 {
                (Vec3::ZERO, radius)
            } else {
                let a = (k as f32 + 0.6 * unit(seed, k, 0)) / (POOL_DISCS - 1) as f32
                    * std::f32::consts::TAU;
                let d = radius * (0.45 + 0.2 * unit(seed, k, 1));
                (
                    (side * a.cos() + up * a.sin()) * d,
                    radius * (0.45 + 0.2 * unit(seed, k, 2)),
                )
            };
            push(b.position + towards + offset, r, ALPHA);
        }
        if b.active(time_s) {
            let t = (time_s - b.start_s) as f32;
            for k in 0..DROPS {
                let phase = (t / DROP_PERIOD_S + k as f32 / DROPS as f32).fract();
                let fall = -up * (DROP_FALL_M * phase * phase);
                push(
                    b.position + towards + fall,
                    DROP_RADIUS_M,
                    ALPHA * (1.0 - phase),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pool_grows_as_the_square_root_of_the_time_bled_and_stops_when_stopped() {
        assert!((pool_radius_m(1.0) - 0.006).abs() < 1e-4);
        // Four times the time, twice the radius.
        assert!((pool_radius_m(4.0) / pool_radius_m(1.0) - 2.0).abs() < 1e-4);
        assert_eq!(pool_radius_m(1e4), POOL_MAX_RADIUS_M);
        let b = Bleed {
            position: Vec3::ZERO,
            start_s: 1.0,
            stop_s: Some(2.0),
        };
        assert_eq!(b.bled_s(0.5), 0.0);
        assert_eq!(b.bled_s(1.5), 0.5);
        assert_eq!(b.bled_s(5.0), 1.0);
        assert!(b.active(1.5) && !b.active(2.5));
        // Stopped: the same particles at any later time, and no drops.
        let draw = |t: f64| {
            let mut out = Vec::new();
            particles(&[b], t, Vec3::new(0.0, 0.1, 0.1), |_, _| true, &mut out);
            out
        };
        let (a, later) = (draw(3.0), draw(9.0));
        assert_eq!(a.len(), POOL_DISCS as usize);
        assert_eq!(
            a.iter().map(|p| p.centre).collect::<Vec<_>>(),
            later.iter().map(|p| p.centre).collect::<Vec<_>>()
        );
        // Bleeding: the pool and its drops.
        assert_eq!(draw(1.5).len(), (POOL_DISCS + DROPS) as usize);
        assert!(draw(0.5).is_empty());
    }
}
