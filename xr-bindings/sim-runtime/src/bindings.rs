//! What the actions read: their handles checked, the paths they are bound to in the profile
//! the runtime chose (it is a Vive: the app's HTC Vive bindings, else its KHR simple
//! controller bindings), and their values and poses from the trace (buttons and triggers at
//! the time of the last `xrSyncActions`, poses at any display time).

use crate::actions::{ACTION_TAG, ActionData, HANDS};
use crate::pose::Rigid;
use crate::state::Runtime;
use crate::tracking::{hand_at, present, trace_time_s};
use openxr_sys as sys;
use sys::Handle;

pub(crate) fn action_index(rt: &Runtime, h: sys::Action) -> Result<usize, sys::Result> {
    let raw = h.into_raw();
    let k = (raw & !0xffff_ffff == ACTION_TAG && raw & 0xffff_ffff != 0)
        .then(|| (raw & 0xffff_ffff) as usize - 1)
        .ok_or(sys::Result::ERROR_HANDLE_INVALID)?;
    match rt.input.actions.get(k) {
        Some(Some(_)) => Ok(k),
        _ => Err(sys::Result::ERROR_HANDLE_INVALID),
    }
}

pub(crate) fn action(rt: &Runtime, k: usize) -> &ActionData {
    // Callers pass indices `action_index` checked.
    rt.input.actions[k].as_ref().expect("checked action index")
}

/// Which hand a top-level path is; `None` for NULL; an error for any other path.
pub(crate) fn hand_of(rt: &Runtime, path: sys::Path) -> Result<Option<usize>, sys::Result> {
    if path == sys::Path::NULL {
        return Ok(None);
    }
    let text = rt.path_text(path).ok_or(sys::Result::ERROR_PATH_INVALID)?;
    HANDS
        .iter()
        .position(|h| *h == text)
        .map(Some)
        .ok_or(sys::Result::ERROR_PATH_UNSUPPORTED)
}

/// The binding paths of action `k` on `hand` in the chosen profile (the part after the hand).
pub(crate) fn bindings(rt: &Runtime, k: usize, hand: usize) -> Vec<&str> {
    let Some(profile) = rt.input.profile.as_deref() else {
        return Vec::new();
    };
    rt.input
        .suggested
        .iter()
        .filter(|(p, _)| p == profile)
        .flat_map(|(_, b)| b.iter())
        .filter(|(a, _)| *a == k)
        .filter_map(|(_, path)| path.strip_prefix(HANDS[hand]))
        .collect()
}

/// The hands an action's state covers under a subaction filter.
pub(crate) fn hands_for(
    rt: &Runtime,
    k: usize,
    filter: Option<usize>,
) -> Result<Vec<usize>, sys::Result> {
    let a = action(rt, k);
    match filter {
        Some(h) if a.hands.contains(&h) => Ok(vec![h]),
        Some(_) => Err(sys::Result::ERROR_PATH_UNSUPPORTED),
        None if a.hands.is_empty() => Ok(vec![0, 1]),
        None => Ok(a.hands.clone()),
    }
}

/// What one input component reads on the trace at a display time.
fn component(rt: &Runtime, hand: usize, binding: &str, display_ns: i64) -> f32 {
    let Some(trace) = rt.trace.as_ref() else {
        return 0.0;
    };
    let Some(s) = trace.sample_hand_of(hand, trace_time_s(display_ns)) else {
        return 0.0;
    };
    match binding {
        b if b.starts_with("/input/trigger/") || b == "/input/select/click" => s.trigger,
        b if b.starts_with("/input/squeeze/") => s.grip,
        "/input/trackpad/click" | "/input/thumbstick/click" | "/input/trackpad/force" => {
            f32::from(u8::from(s.mark))
        }
        _ => 0.0,
    }
}

/// What a two-axis input (the trackpad, a thumbstick) reads on the trace at a display time:
/// the thumb at the pressed edge, else at rest in the centre.
fn axes(rt: &Runtime, hand: usize, binding: &str, display_ns: i64) -> [f32; 2] {
    let pressed = rt
        .trace
        .as_ref()
        .and_then(|trace| trace.sample_hand_of(hand, trace_time_s(display_ns)))
        .and_then(|s| s.pad);
    match (binding, pressed) {
        ("/input/trackpad" | "/input/thumbstick", Some(d)) => d.axes(),
        _ => [0.0; 2],
    }
}

/// An action's value (largest over the hands it covers) and whether any bound controller is
/// there, at the last sync and the one before.
pub(crate) struct Reading {
    pub(crate) active: bool,
    pub(crate) now: f32,
    pub(crate) before: f32,
    pub(crate) changed_at_ns: i64,
    /// A two-axis action's value (the hand's farthest from the centre), now and before.
    pub(crate) axes: [f32; 2],
    pub(crate) axes_before: [f32; 2],
}

pub(crate) fn read(
    rt: &Runtime,
    info: &sys::ActionStateGetInfo,
    kind: sys::ActionType,
) -> Result<Reading, sys::Result> {
    let k = action_index(rt, info.action)?;
    if action(rt, k).kind != kind {
        return Err(sys::Result::ERROR_ACTION_TYPE_MISMATCH);
    }
    if !rt
        .input
        .sets
        .get(action(rt, k).set)
        .and_then(|s| s.as_ref())
        .is_some_and(|s| s.frozen)
    {
        return Err(sys::Result::ERROR_ACTIONSET_NOT_ATTACHED);
    }
    let filter = hand_of(rt, info.subaction_path)?;
    let hands = hands_for(rt, k, filter)?;
    let (t, t0) = (rt.input.synced_ns, rt.input.before_ns);
    let mut r = Reading {
        active: false,
        now: 0.0,
        before: 0.0,
        changed_at_ns: 0,
        axes: [0.0; 2],
        axes_before: [0.0; 2],
    };
    if t == 0 {
        return Ok(r);
    }
    for h in hands {
        if !present(rt, h, t) {
            continue;
        }
        for b in bindings(rt, k, h) {
            r.active = true;
            r.now = r.now.max(component(rt, h, b, t));
            if t0 > 0 {
                r.before = r.before.max(component(rt, h, b, t0));
            }
            if kind == sys::ActionType::VECTOR2F_INPUT {
                let far = |a: [f32; 2], b: [f32; 2]| {
                    if b[0].hypot(b[1]) > a[0].hypot(a[1]) {
                        b
                    } else {
                        a
                    }
                };
                r.axes = far(r.axes, axes(rt, h, b, t));
                if t0 > 0 {
                    r.axes_before = far(r.axes_before, axes(rt, h, b, t0));
                }
            }
        }
    }
    if r.now != r.before || r.axes != r.axes_before {
        r.changed_at_ns = t;
    }
    Ok(r)
}

/// The pose an action space follows: the hand's aim pose while its controller is there, the
/// session focused, and the action bound on it.
pub(crate) fn pose_source(
    rt: &Runtime,
    k: usize,
    hand: Option<usize>,
    display_ns: i64,
) -> Option<Rigid> {
    let focused = rt
        .session
        .as_ref()
        .is_some_and(|s| s.state == sys::SessionState::FOCUSED);
    if !focused {
        return None;
    }
    let hands = hands_for(rt, k, hand).ok()?;
    hands
        .into_iter()
        .filter(|&h| present(rt, h, display_ns) && !bindings(rt, k, h).is_empty())
        .find_map(|h| hand_at(rt, h, display_ns))
}
