//! The frame loop on a simulated 90 Hz display clock (`xrWaitFrame` returns at once with
//! deterministic predicted display times, so a headless run goes as fast as the app renders),
//! and the eye views the app renders from.

use crate::ffi::{arg, arg_mut, two_call, xr_try};
use crate::spaces;
use crate::state::{check_system, enter, result, running, with_session};
use crate::swapchain::{self, ViewImage};
use crate::system::{FIRST_DISPLAY_NS, FRAME_PERIOD_NS};
use openxr_sys as sys;

/// Most composition layers a frame may submit.
const MAX_LAYERS: u32 = 16;

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

/// The views of the first two-view projection layer among the submitted layers.
///
/// # Safety
/// `layers` must hold `count` pointers to valid composition layers (or nulls, refused).
unsafe fn projection_views(
    count: u32,
    layers: *const *const sys::CompositionLayerBaseHeader,
) -> Result<Vec<ViewImage>, sys::Result> {
    if count > MAX_LAYERS {
        return Err(sys::Result::ERROR_LAYER_LIMIT_EXCEEDED);
    }
    if count > 0 && layers.is_null() {
        return Err(sys::Result::ERROR_VALIDATION_FAILURE);
    }
    let mut views = Vec::new();
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
            for e in 0..2 {
                // SAFETY: the layer holds `view_count` (2) views.
                let v = unsafe { &*p.views.add(e) };
                if views.len() < 2 {
                    views.push(ViewImage {
                        swapchain: v.sub_image.swapchain,
                        layer: v.sub_image.image_array_index,
                        rect: v.sub_image.image_rect,
                    });
                }
            }
        }
    }
    Ok(views)
}

unsafe extern "system" fn end_frame(
    session: sys::Session,
    info: *const sys::FrameEndInfo,
) -> sys::Result {
    // SAFETY: the caller passes a valid end info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the end info's layer array is the caller's, valid for the call.
    let views = xr_try!(unsafe { projection_views(info.layer_count, info.layers) });
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
        swapchain::check_views(rt, &views)?;
        let s = running(rt)?;
        s.frames.begun = None;
        s.frames.ended += 1;
        if !views.is_empty() {
            s.frames.projected += 1;
            let n = rt.frames_shown;
            rt.frames_shown += 1;
            let every = rt.config.as_ref().map_or(0, |c| c.frames_every);
            if every > 0 && n % u64::from(every) == 0 {
                swapchain::dump_views(rt, n, &views);
            }
        }
        // The first frame shown: the trainee sees the scene and the app gets the input.
        let s = running(rt)?;
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
    let t = info.display_time.as_nanos();
    let views = xr_try!(with_session(session, |rt| {
        let base = spaces::space(rt, info.space)?;
        Ok(spaces::eyes(rt, base, t).map(|(pose, fov)| sys::View {
            ty: sys::View::TYPE,
            next: std::ptr::null_mut(),
            pose: pose.to_xr(),
            fov,
        }))
    }));
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
