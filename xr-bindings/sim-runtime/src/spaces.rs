//! Reference and action spaces: where each is in STAGE at a display time (the head and the
//! controllers as `tracking.rs` has them from the trace), `xrLocateSpace`, and the eye views
//! the app renders from (Vive field of view, 63 mm IPD).

use crate::bindings::pose_source;
use crate::ffi::{arg, arg_mut, two_call, xr_try};
use crate::pose::{Rigid, SpaceData, SpaceKind, check_pose};
use crate::state::{Runtime, live, result, with_session};
use crate::system::{FIRST_DISPLAY_NS, SESSION};
use crate::tracking::head_at;
use glam::{Quat, Vec3};
use openxr_sys as sys;
use sys::Handle;

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrEnumerateReferenceSpaces" => Some(
                transmute::<sys::pfn::EnumerateReferenceSpaces, V>(reference_spaces),
            ),
            "xrCreateReferenceSpace" => Some(transmute::<sys::pfn::CreateReferenceSpace, V>(
                create_reference_space,
            )),
            "xrDestroySpace" => Some(transmute::<sys::pfn::DestroySpace, V>(destroy_space)),
            "xrLocateSpace" => Some(transmute::<sys::pfn::LocateSpace, V>(locate_space)),
            _ => None,
        }
    }
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
        SpaceKind::Action { action, hand } => pose_source(rt, action, hand, display_ns)?,
    };
    Some(base.then(space.offset))
}

/// Space handles carry the session in their high bits so a stray handle is caught.
fn space_handle(index: usize) -> u64 {
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

/// Adds a space to the session and returns its handle.
pub(crate) fn add_space(rt: &mut Runtime, data: SpaceData) -> Result<u64, sys::Result> {
    let s = live(rt)?;
    s.spaces.push(Some(data));
    Ok(space_handle(s.spaces.len() - 1))
}

const REFERENCE_SPACES: [sys::ReferenceSpaceType; 3] = [
    sys::ReferenceSpaceType::VIEW,
    sys::ReferenceSpaceType::LOCAL,
    sys::ReferenceSpaceType::STAGE,
];

unsafe extern "system" fn create_reference_space(
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

unsafe extern "system" fn destroy_space(space: sys::Space) -> sys::Result {
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

unsafe extern "system" fn locate_space(
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

unsafe extern "system" fn reference_spaces(
    session: sys::Session,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::ReferenceSpaceType,
) -> sys::Result {
    let r = result(with_session(session, |_| Ok(())));
    if r != sys::Result::SUCCESS {
        return r;
    }
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &REFERENCE_SPACES, |a, b| *b = *a) }
}
