//! Rigid transforms, and what a space is (plain data: where a space is at a given time is
//! `spaces.rs`'s business).

use glam::{Quat, Vec3};
use openxr_sys as sys;

/// A rigid transform: rotate, then translate (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Rigid {
    pub(crate) rot: Quat,
    pub(crate) pos: Vec3,
}

impl Rigid {
    pub(crate) const IDENTITY: Rigid = Rigid {
        rot: Quat::IDENTITY,
        pos: Vec3::ZERO,
    };

    pub(crate) fn then(self, inner: Rigid) -> Rigid {
        Rigid {
            rot: self.rot * inner.rot,
            pos: self.pos + self.rot * inner.pos,
        }
    }

    pub(crate) fn inverse(self) -> Rigid {
        let rot = self.rot.conjugate();
        Rigid {
            rot,
            pos: rot * -self.pos,
        }
    }

    pub(crate) fn from_xr(p: sys::Posef) -> Rigid {
        let q = p.orientation;
        Rigid {
            rot: Quat::from_xyzw(q.x, q.y, q.z, q.w),
            pos: Vec3::new(p.position.x, p.position.y, p.position.z),
        }
    }

    pub(crate) fn to_xr(self) -> sys::Posef {
        sys::Posef {
            orientation: sys::Quaternionf {
                x: self.rot.x,
                y: self.rot.y,
                z: self.rot.z,
                w: self.rot.w,
            },
            position: sys::Vector3f {
                x: self.pos.x,
                y: self.pos.y,
                z: self.pos.z,
            },
        }
    }
}

/// A pose the app passed: a unit quaternion and a finite position.
pub(crate) fn check_pose(p: sys::Posef) -> Result<Rigid, sys::Result> {
    let r = Rigid::from_xr(p);
    let norm = r.rot.length();
    if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 || !r.pos.is_finite() {
        return Err(sys::Result::ERROR_POSE_INVALID);
    }
    Ok(r)
}

#[derive(Debug, Clone, Copy)]
pub(crate) enum SpaceKind {
    Reference(sys::ReferenceSpaceType),
    /// A pose action's space, for one hand or (None) whichever the action is bound to.
    Action {
        action: usize,
        hand: Option<usize>,
    },
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct SpaceData {
    pub(crate) kind: SpaceKind,
    /// The space's origin relative to its reference (`pose_in_*_space`).
    pub(crate) offset: Rigid,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transforms_compose_and_invert() {
        let a = Rigid {
            rot: Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            pos: Vec3::new(1.0, 2.0, 3.0),
        };
        let b = Rigid {
            rot: Quat::from_rotation_x(0.3),
            pos: Vec3::new(-0.5, 0.0, 0.25),
        };
        let ab = a.then(b);
        // A quarter turn about +Y takes b's offset (-0.5, 0, 0.25) to (0.25, 0, 0.5).
        assert!(
            (ab.pos - Vec3::new(1.0 + 0.25, 2.0, 3.0 + 0.5)).length() < 1e-5,
            "{ab:?}"
        );
        let back = a.inverse().then(ab);
        assert!((back.pos - b.pos).length() < 1e-5);
        assert!((back.rot.dot(b.rot).abs() - 1.0).abs() < 1e-5);
        let p = Rigid::from_xr(ab.to_xr());
        assert_eq!(p, ab);
    }
}
