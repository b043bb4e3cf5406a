//! Haptics: `xrApplyHapticFeedback` and `xrStopHapticFeedback` on the hands a vibration
//! action is bound to.
//!
//! Vibration calls are written to `haptics.jsonl` in the output folder, one JSON object a line:
//! `{"t_s": .., "hand": "right", "amplitude": .., "frequency_hz": .., "duration_s": ..}`, or
//! `{"t_s": .., "hand": "right", "stop": true}` for `xrStopHapticFeedback` (`t_s`: display
//! time of the newest waited frame, seconds from the first; `frequency_hz` 0 means the
//! runtime's default; `duration_s` -1e-9 means the shortest pulse the device can make).

use crate::bindings::{action, action_index, bindings, hand_of, hands_for};
use crate::config::HAPTICS_FILE;
use crate::ffi::{arg, xr_try};
use crate::state::{Runtime, result, with_session};
use crate::tracking::{present, trace_time_s};
use openxr_sys as sys;
use std::io::Write;

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrApplyHapticFeedback" => {
                Some(transmute::<sys::pfn::ApplyHapticFeedback, V>(apply_haptics))
            }
            "xrStopHapticFeedback" => {
                Some(transmute::<sys::pfn::StopHapticFeedback, V>(stop_haptics))
            }
            _ => None,
        }
    }
}

/// The hands a haptic call reaches: bound, present, and the session focused.
fn haptic_hands(rt: &Runtime, info: &sys::HapticActionInfo) -> Result<Vec<usize>, sys::Result> {
    let k = action_index(rt, info.action)?;
    if action(rt, k).kind != sys::ActionType::VIBRATION_OUTPUT {
        return Err(sys::Result::ERROR_ACTION_TYPE_MISMATCH);
    }
    if !rt.input.attached {
        return Err(sys::Result::ERROR_ACTIONSET_NOT_ATTACHED);
    }
    let filter = hand_of(rt, info.subaction_path)?;
    let hands = hands_for(rt, k, filter)?;
    let focused = rt
        .session
        .as_ref()
        .is_some_and(|s| s.state == sys::SessionState::FOCUSED);
    if !focused {
        return Err(sys::Result::SESSION_NOT_FOCUSED);
    }
    Ok(hands
        .into_iter()
        .filter(|&h| present(rt, h, rt.now_ns) && !bindings(rt, k, h).is_empty())
        .collect())
}

/// Appends lines to `haptics.jsonl` (each line in one write, so a reader never sees half).
fn log_haptics(rt: &Runtime, lines: &[String]) {
    let Some(dir) = rt.config.as_ref().and_then(|c| c.out_dir.as_ref()) else {
        return;
    };
    let path = dir.join(HAPTICS_FILE);
    let written = std::fs::create_dir_all(dir).and_then(|()| {
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)?;
        f.write_all(lines.concat().as_bytes())
    });
    if let Err(e) = written {
        eprintln!("vesalius-sim-runtime: {}: {e}", path.display());
    }
}

unsafe extern "system" fn apply_haptics(
    session: sys::Session,
    info: *const sys::HapticActionInfo,
    feedback: *const sys::HapticBaseHeader,
) -> sys::Result {
    // SAFETY: the caller passes a valid struct or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a valid haptic structure or null (rejected).
    let header = xr_try!(unsafe { arg(feedback) });
    if header.ty != sys::HapticVibration::TYPE {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: the type tag says this is a vibration.
    let v = unsafe { &*feedback.cast::<sys::HapticVibration>() };
    let ns = v.duration.as_nanos();
    let sound = v.amplitude.is_finite()
        && (0.0..=1.0).contains(&v.amplitude)
        && v.frequency.is_finite()
        && v.frequency >= 0.0;
    if !sound || (ns <= 0 && ns != -1) {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let r = with_session(session, |rt| {
        let hands = haptic_hands(rt, info)?;
        let t = trace_time_s(rt.now_ns);
        let lines: Vec<String> = hands
            .iter()
            .map(|&h| {
                format!(
                    "{{\"t_s\":{t:.6},\"hand\":\"{}\",\"amplitude\":{},\"frequency_hz\":{},\"duration_s\":{}}}\n",
                    hand_name(h),
                    v.amplitude,
                    v.frequency,
                    ns as f64 / 1e9
                )
            })
            .collect();
        log_haptics(rt, &lines);
        Ok(())
    });
    result(r)
}

unsafe extern "system" fn stop_haptics(
    session: sys::Session,
    info: *const sys::HapticActionInfo,
) -> sys::Result {
    // SAFETY: the caller passes a valid struct or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    result(with_session(session, |rt| {
        let hands = haptic_hands(rt, info)?;
        let t = trace_time_s(rt.now_ns);
        let lines: Vec<String> = hands
            .iter()
            .map(|&h| {
                format!(
                    "{{\"t_s\":{t:.6},\"hand\":\"{}\",\"stop\":true}}\n",
                    hand_name(h)
                )
            })
            .collect();
        log_haptics(rt, &lines);
        Ok(())
    }))
}

fn hand_name(h: usize) -> &'static str {
    if h == 0 { "left" } else { "right" }
}
