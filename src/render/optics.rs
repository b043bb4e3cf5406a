//! How the picture is formed: the laparoscope's light at its tip, and for a monitor image the
//! scope's narrow view and its round image circle.
//!
//! The light model (the shader follows it, and [`irradiance`] states it for tests and docs):
//! a point source at the scope's tip, whose light guide spreads it as `cos(a)^SPOT_EXPONENT`
//! about the scope's axis, falling off with the inverse square of distance. Irradiance is
//! normalised to 1 on a surface facing the tip at the working distance on the axis:
//!
//! `E = min((d_ref / r)^2, MAX_GAIN) * cos(i) * cos(a)^SPOT_EXPONENT`
//!
//! with `r` the distance from the tip, `i` the angle of incidence and `a` the angle off the
//! axis. Light that bounces around the closed cavity reaches everything as `AMBIENT`. A surface
//! of albedo `c` shows `c * (AMBIENT + DIFFUSE_GAIN * E) + E * specular`, in linear light.
//! Near the rim of a monitor image's circle the picture fades to black over `RIM_FADE` of its
//! radius (the scope's vignette); outside it is black.

use super::camera::{EyeView, Fov};
use crate::sim::Viewpoint;
use glam::{Quat, Vec3};

/// The light guide's spread: irradiance off the axis goes as `cos(a)` to this power.
pub const SPOT_EXPONENT: f32 = 1.0;
/// Light reaching every surface after bouncing around the cavity, as a share of the
/// working-distance irradiance.
pub const AMBIENT: f32 = 0.04;
/// The gain on diffuse light (an albedo of 1 at irradiance 1 shows this bright).
pub const DIFFUSE_GAIN: f32 = 0.85;
/// Closer than the working distance the irradiance grows to at most this many times (the
/// camera's exposure control would stop down further; the picture saturates here).
pub const MAX_GAIN: f32 = 4.0;
/// The share of the image circle's radius over which the picture fades to black at its rim.
pub const RIM_FADE: f32 = 0.06;

/// How a renderer forms its picture.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Optics {
    /// The light's working distance, metres: a surface facing the tip this far along its axis
    /// receives irradiance 1. Zero: a headlight with no falloff (scenes with no field).
    pub light_reference_m: f32,
    /// The image circle's diameter as a share of the image's shorter side; `None`: the whole
    /// image (a headset's view).
    pub circle: Option<f32>,
}

impl Optics {
    /// A laparoscope's monitor image of a procedure's field seen from `view`: the light at
    /// the tip, the working distance the distance to the point it looks at, the circle
    /// filling the image's shorter side.
    pub fn monitor(view: &Viewpoint) -> Self {
        Optics {
            light_reference_m: (view.target - view.eye).length(),
            circle: Some(1.0),
        }
    }

    /// The same light seen in a headset (no image circle).
    pub fn headset(view: &Viewpoint) -> Self {
        Optics {
            circle: None,
            ..Self::monitor(view)
        }
    }

    /// The shader's optics vector for an image of `size` pixels: the working distance, the
    /// circle's radius in pixels (0: none) and the image's width and height.
    pub(super) fn uniform(&self, size: (u32, u32)) -> [f32; 4] {
        let radius = self
            .circle
            .map_or(0.0, |c| 0.5 * c * size.0.min(size.1) as f32);
        [self.light_reference_m, radius, size.0 as f32, size.1 as f32]
    }
}

/// The irradiance the light model gives a surface at `point` with normal `normal` (either
/// side), from a tip at `light` whose axis is `axis` (unit), working distance `reference_m`
/// (zero: no falloff).
pub fn irradiance(light: Vec3, axis: Vec3, point: Vec3, normal: Vec3, reference_m: f32) -> f32 {
    let d = point - light;
    let r = d.length().max(1e-6);
    let to_light = -d / r;
    let cos_i = normal.normalize_or_zero().dot(to_light).abs();
    if reference_m <= 0.0 {
        return cos_i;
    }
    let cos_a = axis.dot(d / r).max(0.0);
    ((reference_m / r).powi(2)).min(MAX_GAIN) * cos_i * cos_a.powf(SPOT_EXPONENT)
}

/// The fraction of the light that survives the rim fade at `r` pixels from the image's centre
/// of a circle of radius `radius` pixels (1 inside, 0 outside).
pub fn rim(r: f32, radius: f32) -> f32 {
    if radius <= 0.0 {
        return 1.0;
    }
    let inner = radius * (1.0 - RIM_FADE);
    let t = ((r - inner) / (radius - inner)).clamp(0.0, 1.0);
    1.0 - t * t * (3.0 - 2.0 * t)
}

/// Two eyes of a stereo laparoscope's monitor image at `view`: the scope's `fov_deg` across
/// the image's shorter side of `size`, the longer side wider in proportion, `ipd_m` apart.
pub fn scope_eyes(view: &Viewpoint, fov_deg: f32, size: (u32, u32), ipd_m: f32) -> [EyeView; 2] {
    let short = (0.5 * fov_deg.to_radians()).tan();
    let (w, h) = (size.0.max(1) as f32, size.1.max(1) as f32);
    let (tx, ty) = if w <= h {
        (short, short * h / w)
    } else {
        (short * w / h, short)
    };
    let fov = Fov {
        left: -tx.atan(),
        right: tx.atan(),
        up: ty.atan(),
        down: -ty.atan(),
    };
    let forward = (view.target - view.eye).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
    let up = right.cross(forward);
    let orientation = Quat::from_mat3(&glam::Mat3::from_cols(right, up, -forward));
    let half = right * (ipd_m * 0.5);
    [view.eye - half, view.eye + half].map(|position| EyeView {
        position,
        orientation,
        fov,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn irradiance_falls_with_the_square_of_distance_and_off_the_axis() {
        let axis = Vec3::NEG_Z;
        let n = Vec3::Z;
        let at = |z: f32| irradiance(Vec3::ZERO, axis, Vec3::new(0.0, 0.0, -z), n, 0.1);
        assert!((at(0.1) - 1.0).abs() < 1e-6);
        assert!((at(0.2) - 0.25).abs() < 1e-6);
        assert!((at(0.4) - 1.0 / 16.0).abs() < 1e-6);
        // Close up it saturates at MAX_GAIN.
        assert!((at(0.01) - MAX_GAIN).abs() < 1e-6);
        // On a plane facing the tip, a point at angle a off the axis: r = d / cos a, incidence
        // a, so E = cos(a)^(3 + SPOT_EXPONENT).
        let a = 25f32.to_radians();
        let p = Vec3::new(0.1 * a.tan(), 0.0, -0.1);
        let e = irradiance(Vec3::ZERO, axis, p, n, 0.1);
        assert!((e - a.cos().powf(3.0 + SPOT_EXPONENT)).abs() < 1e-5, "{e}");
        // No reference: a plain headlight.
        assert!(
            (irradiance(Vec3::ZERO, axis, Vec3::new(0.0, 0.0, -3.0), n, 0.0) - 1.0).abs() < 1e-6
        );
    }

    #[test]
    fn the_rim_fades_only_at_the_edge_of_the_circle() {
        assert_eq!(rim(0.0, 100.0), 1.0);
        assert_eq!(rim(93.0, 100.0), 1.0);
        assert!(rim(97.0, 100.0) > 0.0 && rim(97.0, 100.0) < 1.0);
        assert_eq!(rim(100.0, 100.0), 0.0);
        assert_eq!(rim(150.0, 100.0), 0.0);
        assert_eq!(rim(150.0, 0.0), 1.0);
    }

    #[test]
    fn the_scope_sees_its_angle_across_the_shorter_side() {
        let view = Viewpoint {
            eye: Vec3::new(0.0, 0.0, 0.2),
            target: Vec3::ZERO,
        };
        let size = (540, 600);
        let [l, _] = scope_eyes(&view, 70.0, size, 0.0);
        // A point 35 degrees right of the axis lands on the right edge.
        let p = Vec3::new(0.2 * 35f32.to_radians().tan(), 0.0, 0.0);
        let px = l.project(p, size).expect("in front");
        assert!((px.x - 540.0).abs() < 0.5, "{px}");
        // Vertically the view is wider in proportion: the same angle lands inside.
        let q = Vec3::new(0.0, 0.2 * 35f32.to_radians().tan(), 0.0);
        let py = l.project(q, size).expect("in front");
        assert!((py.y - 300.0 + 270.0).abs() < 0.5, "{py}");
    }
}
