//! Eye poses and projections as an XR runtime gives them: a pose per eye and four field-of-view
//! angles (OpenXR's `XrFovf`), turned into view-projection matrices (right-handed, looking down
//! -Z, depth 0 at the near plane and 1 at the far plane, as wgpu expects).

use glam::{Mat4, Quat, Vec2, Vec3, Vec4};

/// Field of view of one eye, radians; `left` and `down` are negative (OpenXR convention).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fov {
    pub left: f32,
    pub right: f32,
    pub up: f32,
    pub down: f32,
}

impl Fov {
    /// About what SteamVR reports for the HTC Vive's left eye; the right eye is its mirror.
    pub const VIVE_LEFT: Fov = {
        let [left, right, up, down] = xr_bindings::vive::LEFT_FOV_RAD;
        Fov {
            left,
            right,
            up,
            down,
        }
    };

    pub fn mirrored(self) -> Fov {
        Fov {
            left: -self.right,
            right: -self.left,
            up: self.up,
            down: self.down,
        }
    }
}

/// Default interpupillary distance for headless rendering, metres.
pub const DEFAULT_IPD_M: f32 = xr_bindings::vive::IPD_M;
/// The Vive's per-eye resolution, pixels.
pub const VIVE_EYE_SIZE: (u32, u32) = xr_bindings::vive::EYE_SIZE;
/// Clip planes, metres: the laparoscopic scene lies 5 cm to 1 m from the eye.
pub const NEAR_M: f32 = 0.01;
pub const FAR_M: f32 = 5.0;

/// One eye: where it is, where it looks, how wide it sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EyeView {
    pub position: Vec3,
    pub orientation: Quat,
    pub fov: Fov,
}

impl EyeView {
    pub fn projection(&self) -> Mat4 {
        let (tl, tr) = (self.fov.left.tan(), self.fov.right.tan());
        let (tu, td) = (self.fov.up.tan(), self.fov.down.tan());
        let (w, h) = (tr - tl, tu - td);
        let (n, f) = (NEAR_M, FAR_M);
        Mat4::from_cols(
            Vec4::new(2.0 / w, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 2.0 / h, 0.0, 0.0),
            Vec4::new((tr + tl) / w, (tu + td) / h, -f / (f - n), -1.0),
            Vec4::new(0.0, 0.0, -f * n / (f - n), 0.0),
        )
    }

    pub fn view(&self) -> Mat4 {
        Mat4::from_rotation_translation(self.orientation, self.position).inverse()
    }

    pub fn view_proj(&self) -> Mat4 {
        self.projection() * self.view()
    }

    /// Where a world point lands in an image of `size` pixels (x right, y down), if in front.
    pub fn project(&self, p: Vec3, size: (u32, u32)) -> Option<Vec2> {
        let c = self.view_proj() * p.extend(1.0);
        if c.w <= 0.0 {
            return None;
        }
        let ndc = c.truncate() / c.w;
        Some(Vec2::new(
            (ndc.x * 0.5 + 0.5) * size.0 as f32,
            (0.5 - ndc.y * 0.5) * size.1 as f32,
        ))
    }
}

/// Two eyes of a head at `head` looking at `target` (up is +Y), `ipd_m` apart, Vive fields of view.
pub fn stereo_eyes(head: Vec3, target: Vec3, ipd_m: f32) -> [EyeView; 2] {
    let forward = (target - head).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
    let up = right.cross(forward);
    let orientation = Quat::from_mat3(&glam::Mat3::from_cols(right, up, -forward));
    let half = right * (ipd_m * 0.5);
    [
        EyeView {
            position: head - half,
            orientation,
            fov: Fov::VIVE_LEFT,
        },
        EyeView {
            position: head + half,
            orientation,
            fov: Fov::VIVE_LEFT.mirrored(),
        },
    ]
}

/// Both eyes at a procedure's viewpoint over its field (the headless and mirror view).
pub fn field_eyes(view: &crate::sim::Viewpoint, ipd_m: f32) -> [EyeView; 2] {
    stereo_eyes(view.eye, view.target, ipd_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fov_edges_map_to_the_image_edges() {
        let e = EyeView {
            position: Vec3::ZERO,
            orientation: Quat::IDENTITY,
            fov: Fov::VIVE_LEFT,
        };
        let size = (1080, 1200);
        // A point on the right edge of the field at 1 m.
        let p = Vec3::new(Fov::VIVE_LEFT.right.tan(), 0.0, -1.0);
        let px = e.project(p, size).expect("in front");
        assert!((px.x - 1080.0).abs() < 0.5, "{px}");
        let top = Vec3::new(0.0, Fov::VIVE_LEFT.up.tan(), -1.0);
        assert!(e.project(top, size).expect("in front").y.abs() < 0.5);
        // Depth: near plane 0, far plane 1.
        let c = e.view_proj() * Vec4::new(0.0, 0.0, -NEAR_M, 1.0);
        assert!((c.z / c.w).abs() < 1e-5);
        let c = e.view_proj() * Vec4::new(0.0, 0.0, -FAR_M, 1.0);
        assert!((c.z / c.w - 1.0).abs() < 1e-4);
    }

    #[test]
    fn the_eyes_are_an_ipd_apart_and_see_a_near_point_shifted() {
        let [l, r] = stereo_eyes(Vec3::new(0.0, 0.0, 0.3), Vec3::ZERO, 0.063);
        assert!(((r.position - l.position).length() - 0.063).abs() < 1e-6);
        let size = (1080, 1200);
        let (pl, pr) = (
            l.project(Vec3::ZERO, size).expect("in front"),
            r.project(Vec3::ZERO, size).expect("in front"),
        );
        // The left eye sees the point further right than the right eye does.
        assert!(pl.x > pr.x);
        assert!((pl.y - pr.y).abs() < 1e-3);
    }
}
