//! The frame loop on a simulated 90 Hz display clock (`xrWaitFrame` returns at once with
//! deterministic predicted display times, so a headless run goes as fast as the app renders),
//! reference spaces, and the eye views the app renders from.

use super::session::{SESSION, enter, live, result, running, with_session};
use super::{arg, arg_mut, check_system, sys, two_call};
use sys::Handle;

/// The Vive's refresh period: 90 Hz, nanoseconds.
pub const FRAME_PERIOD_NS: i64 = 1_000_000_000 / xr_bindings::vive::REFRESH_HZ;
/// Predicted display time of the first frame, nanoseconds (any fixed non-zero origin).
pub const FIRST_DISPLAY_NS: i64 = 1_000_000_000;
/// Head height above the stage floor when no trace moves it, metres.
pub const HEAD_HEIGHT_M: f32 = 1.6;
/// Distance between the eyes, metres.
pub const IPD_M: f32 = xr_bindings::vive::IPD_M;
/// The Vive's left-eye field of view, radians (the right eye's is its mirror image).
pub const VIVE_LEFT_FOV: sys::Fovf = {
    let [angle_left, angle_right, angle_up, angle_down] = xr_bindings::vive::LEFT_FOV_RAD;
    sys::Fovf {
        angle_left,
        angle_right,
        angle_up,
        angle_down,
    }
};
/// Most composition layers a frame may submit.
const MAX_LAYERS: u32 = 16;

/// Where the app stands in the wait / begin / end cycle.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct FrameLoop {
    /// Frames returned by `xrWaitFrame`.
    pub(crate) waited: u64,
    /// The predicted display time of the waited frame not yet begun.
    pending: Option<i64>,
    /// The display time of the frame begun and not yet ended.
    begun: Option<i64>,
    /// Frames ended, and those that carried a two-view projection layer.
    pub(crate) ended: u64,
    pub(crate) projected: u64,
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct RefSpace {
    kind: sys::ReferenceSpaceType,
    pose: sys::Posef,
}

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrWaitFrame" => Some(transmute::<sys::pfn::WaitFrame, V>(wait_frame)),
            "xrBeginFrame" => Some(transmute::<sys::pfn::BeginFrame, V>(begin_frame)),
            "xrEndFrame" => Some(transmute::<sys::pfn::EndFrame, V>(end_frame)),
            "xrEnumerateEnvironmentBlendModes" => Some(transmute::<
                sys::pfn::EnumerateEnvironmentBlendModes,
                V,
            >(blend_modes)),
            "xrEnumerateReferenceSpaces" => Some(
                transmute::<sys::pfn::EnumerateReferenceSpaces, V>(reference_spaces),
            ),
            "xrCreateReferenceSpace" => Some(transmute::<sys::pfn::CreateReferenceSpace, V>(
                create_reference_space,
            )),
            "xrDestroySpace" => Some(transmute::<sys::pfn::DestroySpace, V>(destroy_space)),
            "xrLocateViews" => Some(transmute::<sys::pfn::LocateViews, V>(locate_views)),
            _ => None,
        }
    }
}

unsafe extern "system" fn wait_frame(
    session: sys::Session,
    _info: *const sys::FrameWaitInfo,
    state: *mut sys::FrameState,
) -> sys::Result {
    // SAFETY: the caller passes a writable frame state or null (rejected).
    let out = xr_try!(unsafe { arg_mut(state) });
    let r = with_session(session, |rt| {
        let (state, begun) = match rt.session.as_ref() {
            Some(s) => (s.state, s.begun),
            None => return Err(sys::Result::ERROR_HANDLE_INVALID),
        };
        if !begun {
            return Err(sys::Result::ERROR_SESSION_NOT_RUNNING);
        }
        // One display clock for the instance: it runs on across sessions.
        let t = if rt.now_ns == 0 {
            FIRST_DISPLAY_NS
        } else {
            rt.now_ns + FRAME_PERIOD_NS
        };
        rt.now_ns = t;
        if let Some(s) = rt.session.as_mut() {
            s.frames.waited += 1;
            s.frames.pending = Some(t);
        }
        let render = matches!(
            state,
            sys::SessionState::VISIBLE | sys::SessionState::FOCUSED
        );
        out.predicted_display_time = sys::Time::from_nanos(t);
        out.predicted_display_period = sys::Duration::from_nanos(FRAME_PERIOD_NS);
        out.should_render = render.into();
        // The app's frames are now in step with the display.
        if state == sys::SessionState::READY {
            enter(rt, sys::SessionState::SYNCHRONIZED);
        }
        // An injected loss: the headset goes away (unplugged, or its runtime service died).
        let loss = rt.config.as_ref().and_then(|c| c.inject.session_loss_s);
        if let Some(at) = loss
            && !rt.lost
            && (t - FIRST_DISPLAY_NS) as f64 >= at * 1e9
        {
            rt.lost = true;
            rt.headset_gone_polls = rt
                .config
                .as_ref()
                .map_or(0, |c| c.inject.headset_back_after_polls);
            enter(rt, sys::SessionState::LOSS_PENDING);
        }
        // A session on its way out still gets frames, flagged with the success code.
        Ok(if state == sys::SessionState::LOSS_PENDING {
            sys::Result::SESSION_LOSS_PENDING
        } else {
            sys::Result::SUCCESS
        })
    });
    r.unwrap_or_else(|e| e)
}

unsafe extern "system" fn begin_frame(
    session: sys::Session,
    _info: *const sys::FrameBeginInfo,
) -> sys::Result {
    let discarded = with_session(session, |rt| {
        let s = running(rt)?;
        let t = s
            .frames
            .pending
            .take()
            .ok_or(sys::Result::ERROR_CALL_ORDER_INVALID)?;
        // A frame begun and never ended is dropped for the new one.
        Ok(s.frames.begun.replace(t).is_some())
    });
    match xr_try!(discarded) {
        true => sys::Result::FRAME_DISCARDED,
        false => sys::Result::SUCCESS,
    }
}

/// Counts the projection layers with two views among the submitted layers.
///
/// # Safety
/// `layers` must hold `count` pointers to valid composition layers (or nulls, refused).
unsafe fn projection_layers(
    count: u32,
    layers: *const *const sys::CompositionLayerBaseHeader,
) -> Result<u32, sys::Result> {
    if count > MAX_LAYERS {
        return Err(sys::Result::ERROR_LAYER_LIMIT_EXCEEDED);
    }
    if count > 0 && layers.is_null() {
        return Err(sys::Result::ERROR_VALIDATION_FAILURE);
    }
    let mut stereo = 0;
    for k in 0..count as usize {
        // SAFETY: `layers` holds `count` entries (caller's contract).
        let layer = unsafe { *layers.add(k) };
        // SAFETY: a non-null entry points to a layer that starts with the base header.
        let Some(base) = (unsafe { layer.as_ref() }) else {
            return Err(sys::Result::ERROR_LAYER_INVALID);
        };
        if base.ty == sys::CompositionLayerProjection::TYPE {
            // SAFETY: the type tag says this is a projection layer.
            let p = unsafe { &*layer.cast::<sys::CompositionLayerProjection>() };
            if p.view_count != 2 || p.views.is_null() {
                return Err(sys::Result::ERROR_VALIDATION_FAILURE);
            }
            stereo += 1;
        }
    }
    Ok(stereo)
}

unsafe extern "system" fn end_frame(
    session: sys::Session,
    info: *const sys::FrameEndInfo,
) -> sys::Result {
    // SAFETY: the caller passes a valid end info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the end info's layer array is the caller's, valid for the call.
    let stereo = xr_try!(unsafe { projection_layers(info.layer_count, info.layers) });
    result(with_session(session, |rt| {
        let s = running(rt)?;
        let t = s
            .frames
            .begun
            .ok_or(sys::Result::ERROR_CALL_ORDER_INVALID)?;
        if info.display_time.as_nanos() != t {
            return Err(sys::Result::ERROR_TIME_INVALID);
        }
        if info.environment_blend_mode != sys::EnvironmentBlendMode::OPAQUE {
            return Err(sys::Result::ERROR_ENVIRONMENT_BLEND_MODE_UNSUPPORTED);
        }
        s.frames.begun = None;
        s.frames.ended += 1;
        if stereo > 0 {
            s.frames.projected += 1;
        }
        // The first frame shown: the trainee sees the scene and the app gets the input.
        if s.state == sys::SessionState::SYNCHRONIZED && !s.exit_requested {
            enter(rt, sys::SessionState::VISIBLE);
            enter(rt, sys::SessionState::FOCUSED);
        }
        Ok(())
    }))
}

unsafe extern "system" fn blend_modes(
    instance: sys::Instance,
    system: sys::SystemId,
    config: sys::ViewConfigurationType,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::EnvironmentBlendMode,
) -> sys::Result {
    xr_try!(check_system(instance, system));
    if config != sys::ViewConfigurationType::PRIMARY_STEREO {
        return sys::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
    }
    let modes = [sys::EnvironmentBlendMode::OPAQUE];
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &modes, |a, b| *b = *a) }
}

const SPACES: [sys::ReferenceSpaceType; 3] = [
    sys::ReferenceSpaceType::VIEW,
    sys::ReferenceSpaceType::LOCAL,
    sys::ReferenceSpaceType::STAGE,
];

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
    unsafe { two_call(capacity, count, out, &SPACES, |a, b| *b = *a) }
}

/// Space handles carry the session in their high bits so a stray handle is caught.
fn space_handle(index: usize) -> u64 {
    (SESSION << 32) | (index as u64 + 1)
}

fn space_index(space: sys::Space) -> Option<usize> {
    let raw = space.into_raw();
    (raw >> 32 == SESSION && raw & 0xffff_ffff != 0).then(|| (raw & 0xffff_ffff) as usize - 1)
}

unsafe extern "system" fn create_reference_space(
    session: sys::Session,
    info: *const sys::ReferenceSpaceCreateInfo,
    space: *mut sys::Space,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    if space.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    if !SPACES.contains(&info.reference_space_type) {
        return sys::Result::ERROR_REFERENCE_SPACE_UNSUPPORTED;
    }
    let q = info.pose_in_reference_space.orientation;
    let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
    if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 {
        return sys::Result::ERROR_POSE_INVALID;
    }
    let r = with_session(session, |rt| {
        let s = live(rt)?;
        s.spaces.push(Some(RefSpace {
            kind: info.reference_space_type,
            pose: info.pose_in_reference_space,
        }));
        Ok(space_handle(s.spaces.len() - 1))
    });
    match r {
        Ok(h) => {
            // SAFETY: `space` is non-null (checked) and writable.
            unsafe { *space = sys::Space::from_raw(h) };
            sys::Result::SUCCESS
        }
        Err(e) => e,
    }
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

/// Rotates `v` by the unit quaternion `q`.
fn rotate(q: sys::Quaternionf, v: [f32; 3]) -> [f32; 3] {
    let (x, y, z, w) = (q.x, q.y, q.z, q.w);
    // t = 2 q.xyz x v; v' = v + w t + q.xyz x t
    let t = [
        2.0 * (y * v[2] - z * v[1]),
        2.0 * (z * v[0] - x * v[2]),
        2.0 * (x * v[1] - y * v[0]),
    ];
    [
        v[0] + w * t[0] + (y * t[2] - z * t[1]),
        v[1] + w * t[1] + (z * t[0] - x * t[2]),
        v[2] + w * t[2] + (x * t[1] - y * t[0]),
    ]
}

fn conjugate(q: sys::Quaternionf) -> sys::Quaternionf {
    sys::Quaternionf {
        x: -q.x,
        y: -q.y,
        z: -q.z,
        w: q.w,
    }
}

fn multiply(a: sys::Quaternionf, b: sys::Quaternionf) -> sys::Quaternionf {
    sys::Quaternionf {
        w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
        x: a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        y: a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        z: a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
    }
}

/// The head's pose in a reference space: standing at the stage origin, eyes 1.6 m up, looking
/// down -Z; LOCAL's origin is the head's starting pose; VIEW is the head itself. Then the
/// space's own offset (`pose_in_reference_space`) is undone.
fn head_in(space: RefSpace) -> sys::Posef {
    let base = match space.kind {
        sys::ReferenceSpaceType::STAGE => [0.0, HEAD_HEIGHT_M, 0.0],
        _ => [0.0, 0.0, 0.0],
    };
    let inv = conjugate(space.pose.orientation);
    let p = space.pose.position;
    let d = rotate(inv, [base[0] - p.x, base[1] - p.y, base[2] - p.z]);
    sys::Posef {
        orientation: multiply(inv, sys::Quaternionf::IDENTITY),
        position: sys::Vector3f {
            x: d[0],
            y: d[1],
            z: d[2],
        },
    }
}

unsafe extern "system" fn locate_views(
    session: sys::Session,
    info: *const sys::ViewLocateInfo,
    state: *mut sys::ViewState,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::View,
) -> sys::Result {
    // SAFETY: the caller passes a valid locate info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable view state or null (rejected).
    let state = xr_try!(unsafe { arg_mut(state) });
    if info.view_configuration_type != sys::ViewConfigurationType::PRIMARY_STEREO {
        return sys::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
    }
    if info.display_time.as_nanos() <= 0 {
        return sys::Result::ERROR_TIME_INVALID;
    }
    let space = match with_session(session, |rt| {
        let s = rt
            .session
            .as_ref()
            .ok_or(sys::Result::ERROR_HANDLE_INVALID)?;
        space_index(info.space)
            .and_then(|k| s.spaces.get(k).copied().flatten())
            .ok_or(sys::Result::ERROR_HANDLE_INVALID)
    }) {
        Ok(s) => s,
        Err(e) => return e,
    };
    let head = head_in(space);
    let eye = |side: f32, fov: sys::Fovf| {
        let off = rotate(head.orientation, [side * IPD_M / 2.0, 0.0, 0.0]);
        sys::View {
            ty: sys::View::TYPE,
            next: std::ptr::null_mut(),
            pose: sys::Posef {
                orientation: head.orientation,
                position: sys::Vector3f {
                    x: head.position.x + off[0],
                    y: head.position.y + off[1],
                    z: head.position.z + off[2],
                },
            },
            fov,
        }
    };
    let right_fov = sys::Fovf {
        angle_left: -VIVE_LEFT_FOV.angle_right,
        angle_right: -VIVE_LEFT_FOV.angle_left,
        ..VIVE_LEFT_FOV
    };
    let views = [eye(-1.0, VIVE_LEFT_FOV), eye(1.0, right_fov)];
    state.view_state_flags = sys::ViewStateFlags::ORIENTATION_VALID
        | sys::ViewStateFlags::POSITION_VALID
        | sys::ViewStateFlags::ORIENTATION_TRACKED
        | sys::ViewStateFlags::POSITION_TRACKED;
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe {
        two_call(capacity, count, out, &views, |a, b| {
            b.pose = a.pose;
            b.fov = a.fov;
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_helpers_match_a_quarter_turn() {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        // A quarter turn about +Y takes +X to -Z.
        let q = sys::Quaternionf {
            x: 0.0,
            y: h,
            z: 0.0,
            w: h,
        };
        let v = rotate(q, [1.0, 0.0, 0.0]);
        assert!((v[0]).abs() < 1e-6 && (v[2] + 1.0).abs() < 1e-6, "{v:?}");
        let back = rotate(conjugate(q), v);
        assert!((back[0] - 1.0).abs() < 1e-6);
        let two = multiply(q, q);
        let w = rotate(two, [1.0, 0.0, 0.0]);
        assert!((w[0] + 1.0).abs() < 1e-6, "half turn: {w:?}");
    }

    #[test]
    fn the_head_stands_1_6_m_up_on_the_stage_and_at_the_origin_of_local() {
        let id = sys::Posef::IDENTITY;
        let stage = head_in(RefSpace {
            kind: sys::ReferenceSpaceType::STAGE,
            pose: id,
        });
        assert_eq!(stage.position.y, HEAD_HEIGHT_M);
        let local = head_in(RefSpace {
            kind: sys::ReferenceSpaceType::LOCAL,
            pose: id,
        });
        assert_eq!(local.position.y, 0.0);
        // A stage space whose origin is raised 1 m sees the head 0.6 m up.
        let raised = head_in(RefSpace {
            kind: sys::ReferenceSpaceType::STAGE,
            pose: sys::Posef {
                orientation: sys::Quaternionf::IDENTITY,
                position: sys::Vector3f {
                    x: 0.0,
                    y: 1.0,
                    z: 0.0,
                },
            },
        });
        assert!((raised.position.y - 0.6).abs() < 1e-6);
    }
}
