//! Reference and action spaces, and where things are: the head and the controllers move as the
//! trace says (`[[head]]`, `[[left]]`, `[[right]]` keys in the operating field's frame, placed
//! in the room by `xr_bindings::stage`). `xrLocateSpace` and `xrLocateViews` answer from the
//! trace at the time asked, so the app sees the same motion however fast it renders.

use super::frame::FIRST_DISPLAY_NS;
use super::session::{SESSION, live, result, with_session};
use super::{Runtime, arg, arg_mut, sys};
use glam::{Mat3, Quat, Vec3};
use sys::Handle;

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

/// Trace time, seconds, of a display time in nanoseconds (0 at the first frame).
pub(crate) fn trace_time_s(display_ns: i64) -> f64 {
    ((display_ns - FIRST_DISPLAY_NS) as f64 / 1e9).max(0.0)
}

/// An orientation whose -Z points from `from` to `to`, +Y as near up as it can be (the head).
fn looking(from: Vec3, to: Vec3) -> Quat {
    let forward = (to - from).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
    let up = right.cross(forward);
    Quat::from_mat3(&Mat3::from_cols(right, up, -forward)).normalize()
}

/// The head (the eyes' midpoint) in STAGE at a display time.
pub(crate) fn head_at(rt: &Runtime, display_ns: i64) -> Rigid {
    let keys = rt.trace.as_ref().map_or(&[][..], |t| &t.head[..]);
    let (p, target) = xr_bindings::keyframes::sample_head(keys, trace_time_s(display_ns));
    Rigid {
        rot: looking(p, target),
        pos: xr_bindings::stage::field_to_stage(p),
    }
}

/// A controller's aim pose in STAGE at a display time: where the trace puts the instrument,
/// its -Z towards the target (the app's convention). `None` for a hand the trace leaves out.
pub(crate) fn hand_at(rt: &Runtime, hand: usize, display_ns: i64) -> Option<Rigid> {
    let trace = rt.trace.as_ref()?;
    let keys = if hand == 0 { &trace.left } else { &trace.right };
    let s = xr_bindings::keyframes::sample_hand(keys, trace_time_s(display_ns))?;
    let dir = (s.target - s.position).normalize_or_zero();
    Some(Rigid {
        rot: Quat::from_rotation_arc(Vec3::NEG_Z, dir),
        pos: xr_bindings::stage::field_to_stage(s.position),
    })
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

/// Where a space's origin is in STAGE at a display time; `None` while it is not tracked
/// (an action space whose controller is lost, unbound or out of focus).
pub(crate) fn origin_in_stage(rt: &Runtime, space: SpaceData, display_ns: i64) -> Option<Rigid> {
    let base = match space.kind {
        SpaceKind::Reference(sys::ReferenceSpaceType::STAGE) => Rigid::IDENTITY,
        // LOCAL: level, at the head's starting place.
        SpaceKind::Reference(sys::ReferenceSpaceType::LOCAL) => Rigid {
            rot: Quat::IDENTITY,
            pos: head_at(rt, FIRST_DISPLAY_NS).pos,
        },
        SpaceKind::Reference(_) => head_at(rt, display_ns),
        SpaceKind::Action { action, hand } => {
            crate::input::pose_source(rt, action, hand, display_ns)?
        }
    };
    Some(base.then(space.offset))
}

/// Space handles carry the session in their high bits so a stray handle is caught.
pub(crate) fn space_handle(index: usize) -> u64 {
    (SESSION << 32) | (index as u64 + 1)
}

fn space_index(space: sys::Space) -> Option<usize> {
    let raw = space.into_raw();
    (raw >> 32 == SESSION && raw & 0xffff_ffff != 0).then(|| (raw & 0xffff_ffff) as usize - 1)
}

/// A live space of the session.
pub(crate) fn space(rt: &Runtime, space: sys::Space) -> Result<SpaceData, sys::Result> {
    let s = rt
        .session
        .as_ref()
        .ok_or(sys::Result::ERROR_HANDLE_INVALID)?;
    space_index(space)
        .and_then(|k| s.spaces.get(k).copied().flatten())
        .ok_or(sys::Result::ERROR_HANDLE_INVALID)
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

/// Adds a space to the session and returns its handle.
pub(crate) fn add_space(rt: &mut Runtime, data: SpaceData) -> Result<u64, sys::Result> {
    let s = live(rt)?;
    s.spaces.push(Some(data));
    Ok(space_handle(s.spaces.len() - 1))
}

pub(crate) const REFERENCE_SPACES: [sys::ReferenceSpaceType; 3] = [
    sys::ReferenceSpaceType::VIEW,
    sys::ReferenceSpaceType::LOCAL,
    sys::ReferenceSpaceType::STAGE,
];

pub(crate) unsafe extern "system" fn create_reference_space(
    session: sys::Session,
    info: *const sys::ReferenceSpaceCreateInfo,
    out: *mut sys::Space,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable handle or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    if !REFERENCE_SPACES.contains(&info.reference_space_type) {
        return sys::Result::ERROR_REFERENCE_SPACE_UNSUPPORTED;
    }
    let offset = xr_try!(check_pose(info.pose_in_reference_space));
    let h = xr_try!(with_session(session, |rt| {
        add_space(
            rt,
            SpaceData {
                kind: SpaceKind::Reference(info.reference_space_type),
                offset,
            },
        )
    }));
    *out = sys::Space::from_raw(h);
    sys::Result::SUCCESS
}

pub(crate) unsafe extern "system" fn destroy_space(space: sys::Space) -> sys::Result {
    let Some(k) = space_index(space) else {
        return sys::Result::ERROR_HANDLE_INVALID;
    };
    result(with_session(sys::Session::from_raw(SESSION), |rt| {
        let s = live(rt)?;
        match s.spaces.get_mut(k) {
            Some(slot @ Some(_)) => {
                *slot = None;
                Ok(())
            }
            _ => Err(sys::Result::ERROR_HANDLE_INVALID),
        }
    }))
}

fn tracked() -> sys::SpaceLocationFlags {
    sys::SpaceLocationFlags::ORIENTATION_VALID
        | sys::SpaceLocationFlags::POSITION_VALID
        | sys::SpaceLocationFlags::ORIENTATION_TRACKED
        | sys::SpaceLocationFlags::POSITION_TRACKED
}

pub(crate) unsafe extern "system" fn locate_space(
    space: sys::Space,
    base: sys::Space,
    time: sys::Time,
    location: *mut sys::SpaceLocation,
) -> sys::Result {
    // SAFETY: the caller passes a writable location or null (rejected).
    let location = xr_try!(unsafe { arg_mut(location) });
    if time.as_nanos() <= 0 {
        return sys::Result::ERROR_TIME_INVALID;
    }
    let t = time.as_nanos();
    let found = xr_try!(with_session(sys::Session::from_raw(SESSION), |rt| {
        let (a, b) = (self::space(rt, space)?, self::space(rt, base)?);
        Ok(origin_in_stage(rt, a, t).zip(origin_in_stage(rt, b, t)))
    }));
    match found {
        Some((a, b)) => {
            location.location_flags = tracked();
            location.pose = b.inverse().then(a).to_xr();
        }
        None => {
            location.location_flags = sys::SpaceLocationFlags::EMPTY;
            location.pose = sys::Posef::IDENTITY;
        }
    }
    sys::Result::SUCCESS
}

/// The Vive's left-eye field of view (the right eye's is its mirror image).
const VIVE_LEFT_FOV: sys::Fovf = {
    let [angle_left, angle_right, angle_up, angle_down] = xr_bindings::vive::LEFT_FOV_RAD;
    sys::Fovf {
        angle_left,
        angle_right,
        angle_up,
        angle_down,
    }
};

/// The two eyes' poses in `base` at a display time, and their fields of view.
pub(crate) fn eyes(rt: &Runtime, base: SpaceData, display_ns: i64) -> [(Rigid, sys::Fovf); 2] {
    let head = head_at(rt, display_ns);
    let to_base = origin_in_stage(rt, base, display_ns)
        .unwrap_or(Rigid::IDENTITY)
        .inverse();
    let eye = |side: f32| {
        to_base.then(head).then(Rigid {
            rot: Quat::IDENTITY,
            pos: Vec3::new(side * xr_bindings::vive::IPD_M / 2.0, 0.0, 0.0),
        })
    };
    let right_fov = sys::Fovf {
        angle_left: -VIVE_LEFT_FOV.angle_right,
        angle_right: -VIVE_LEFT_FOV.angle_left,
        ..VIVE_LEFT_FOV
    };
    [(eye(-1.0), VIVE_LEFT_FOV), (eye(1.0), right_fov)]
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

    #[test]
    fn the_looking_orientation_points_minus_z_at_the_target_with_y_up() {
        let q = looking(Vec3::new(0.0, 1.6, 0.0), Vec3::new(0.0, 1.0, -0.6));
        let fwd = q * Vec3::NEG_Z;
        assert!((fwd - Vec3::new(0.0, -0.6, -0.6).normalize()).length() < 1e-5);
        assert!((q * Vec3::X - Vec3::X).length() < 1e-5, "no roll");
    }
}
