//! Actions: action sets and actions, suggested bindings (the runtime is a Vive: it picks the
//! app's HTC Vive bindings, else its KHR simple controller bindings), attaching, syncing, the
//! four kinds of state, action spaces, and haptics. Button and trigger values come from the
//! trace's keys at the time of the last `xrSyncActions`; poses from `spaces.rs`.
//!
//! Vibration calls are written to `haptics.jsonl` in the output folder, one JSON object a line:
//! `{"t_s": .., "hand": "right", "amplitude": .., "frequency_hz": .., "duration_s": ..}`, or
//! `{"t_s": .., "hand": "right", "stop": true}` for `xrStopHapticFeedback` (`t_s`: display
//! time of the newest waited frame, seconds from the first; `frequency_hz` 0 means the
//! runtime's default; `duration_s` -1e-9 means the shortest pulse the device can make).

use super::session::{live, profile_changed, result, with_session};
use super::spaces::{Rigid, SpaceData, SpaceKind, add_space, check_pose, hand_at, trace_time_s};
use super::{Runtime, arg, arg_mut, check_instance, runtime, sys, two_call};
use std::ffi::c_char;
use std::io::Write;
use sys::Handle;

const SET_TAG: u64 = 2 << 32;
const ACTION_TAG: u64 = 3 << 32;
pub(crate) const HANDS: [&str; 2] = ["/user/hand/left", "/user/hand/right"];
/// The profiles this runtime's controllers answer to, most preferred first.
const PROFILES: [&str; 2] = [
    "/interaction_profiles/htc/vive_controller",
    "/interaction_profiles/khr/simple_controller",
];

struct SetData {
    /// Attached to a session: no more actions may be added.
    frozen: bool,
}

struct ActionData {
    set: usize,
    kind: sys::ActionType,
    /// Hands (0 left, 1 right) the action was created for; empty: no subaction paths.
    hands: Vec<usize>,
}

/// The instance's actions and the session's input state.
pub(crate) struct Input {
    sets: Vec<Option<SetData>>,
    actions: Vec<Option<ActionData>>,
    /// Suggested bindings: profile path, then (action, binding path) pairs.
    suggested: Vec<(String, Vec<(usize, String)>)>,
    /// The profile the runtime chose when the app attached its action sets.
    profile: Option<String>,
    attached: bool,
    /// Display time of the last `xrSyncActions` that found the session focused, and the one
    /// before (for `changedSinceLastSync`); 0: none.
    synced_ns: i64,
    before_ns: i64,
    /// Whether each hand's controller was there at the last sync.
    present: [bool; 2],
}

impl Input {
    pub(crate) const NEW: Input = Input {
        sets: Vec::new(),
        actions: Vec::new(),
        suggested: Vec::new(),
        profile: None,
        attached: false,
        synced_ns: 0,
        before_ns: 0,
        present: [false; 2],
    };

    /// A new session starts with nothing attached.
    pub(crate) fn reset_session(&mut self) {
        self.profile = None;
        self.attached = false;
        self.synced_ns = 0;
        self.before_ns = 0;
        self.present = [false; 2];
    }
}

fn set_index(h: sys::ActionSet) -> Option<usize> {
    let raw = h.into_raw();
    (raw & !0xffff_ffff == SET_TAG && raw & 0xffff_ffff != 0)
        .then(|| (raw & 0xffff_ffff) as usize - 1)
}

fn action_index(rt: &Runtime, h: sys::Action) -> Result<usize, sys::Result> {
    let raw = h.into_raw();
    let k = (raw & !0xffff_ffff == ACTION_TAG && raw & 0xffff_ffff != 0)
        .then(|| (raw & 0xffff_ffff) as usize - 1)
        .ok_or(sys::Result::ERROR_HANDLE_INVALID)?;
    match rt.input.actions.get(k) {
        Some(Some(_)) => Ok(k),
        _ => Err(sys::Result::ERROR_HANDLE_INVALID),
    }
}

fn action(rt: &Runtime, k: usize) -> &ActionData {
    // Callers pass indices `action_index` checked.
    rt.input.actions[k].as_ref().expect("checked action index")
}

/// Which hand a top-level path is; `None` for NULL; an error for any other path.
fn hand_of(rt: &Runtime, path: sys::Path) -> Result<Option<usize>, sys::Result> {
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

/// Whether a hand's controller is there at a display time: the trace moves it and no injected
/// controller loss covers the time.
pub(crate) fn present(rt: &Runtime, hand: usize, display_ns: i64) -> bool {
    let t = trace_time_s(display_ns);
    let lost = rt.config.as_ref().is_some_and(|c| {
        c.inject
            .controller_loss
            .iter()
            .any(|l| l.hand.index() == hand && l.from_s <= t && t < l.to_s)
    });
    !lost && hand_at(rt, hand, display_ns).is_some()
}

/// The binding paths of action `k` on `hand` in the chosen profile (the part after the hand).
fn bindings(rt: &Runtime, k: usize, hand: usize) -> Vec<&str> {
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
fn hands_for(rt: &Runtime, k: usize, filter: Option<usize>) -> Result<Vec<usize>, sys::Result> {
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
    let keys = if hand == 0 { &trace.left } else { &trace.right };
    let Some(s) = xr_bindings::keyframes::sample_hand(keys, trace_time_s(display_ns)) else {
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

/// An action's value (largest over the hands it covers) and whether any bound controller is
/// there, at the last sync and the one before.
struct Reading {
    active: bool,
    now: f32,
    before: f32,
    changed_at_ns: i64,
}

fn read(
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
        }
    }
    if r.now != r.before {
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

/// A C string field of a create info, checked for the OpenXR name grammar.
fn name_of(field: &[c_char]) -> Result<String, sys::Result> {
    let bytes: Vec<u8> = field
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    let ok = !bytes.is_empty()
        && bytes.len() < field.len()
        && bytes
            .iter()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"-_.".contains(b));
    if !ok {
        return Err(sys::Result::ERROR_NAME_INVALID);
    }
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrCreateActionSet" => {
                Some(transmute::<sys::pfn::CreateActionSet, V>(create_action_set))
            }
            "xrDestroyActionSet" => Some(transmute::<sys::pfn::DestroyActionSet, V>(
                destroy_action_set,
            )),
            "xrCreateAction" => Some(transmute::<sys::pfn::CreateAction, V>(create_action)),
            "xrDestroyAction" => Some(transmute::<sys::pfn::DestroyAction, V>(destroy_action)),
            "xrSuggestInteractionProfileBindings" => Some(transmute::<
                sys::pfn::SuggestInteractionProfileBindings,
                V,
            >(suggest_bindings)),
            "xrAttachSessionActionSets" => Some(transmute::<sys::pfn::AttachSessionActionSets, V>(
                attach_action_sets,
            )),
            "xrGetCurrentInteractionProfile" => Some(transmute::<
                sys::pfn::GetCurrentInteractionProfile,
                V,
            >(current_profile)),
            "xrSyncActions" => Some(transmute::<sys::pfn::SyncActions, V>(sync_actions)),
            "xrGetActionStateBoolean" => Some(transmute::<sys::pfn::GetActionStateBoolean, V>(
                state_boolean,
            )),
            "xrGetActionStateFloat" => {
                Some(transmute::<sys::pfn::GetActionStateFloat, V>(state_float))
            }
            "xrGetActionStateVector2f" => Some(transmute::<sys::pfn::GetActionStateVector2f, V>(
                state_vector2,
            )),
            "xrGetActionStatePose" => {
                Some(transmute::<sys::pfn::GetActionStatePose, V>(state_pose))
            }
            "xrEnumerateBoundSourcesForAction" => Some(transmute::<
                sys::pfn::EnumerateBoundSourcesForAction,
                V,
            >(bound_sources)),
            "xrCreateActionSpace" => Some(transmute::<sys::pfn::CreateActionSpace, V>(
                create_action_space,
            )),
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

unsafe extern "system" fn create_action_set(
    instance: sys::Instance,
    info: *const sys::ActionSetCreateInfo,
    out: *mut sys::ActionSet,
) -> sys::Result {
    xr_try!(check_instance(instance));
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable handle or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    xr_try!(name_of(&info.action_set_name));
    let mut rt = runtime();
    rt.input.sets.push(Some(SetData { frozen: false }));
    *out = sys::ActionSet::from_raw(SET_TAG | rt.input.sets.len() as u64);
    sys::Result::SUCCESS
}

unsafe extern "system" fn destroy_action_set(set: sys::ActionSet) -> sys::Result {
    let mut rt = runtime();
    match set_index(set).and_then(|k| rt.input.sets.get_mut(k)) {
        Some(slot @ Some(_)) => {
            *slot = None;
            sys::Result::SUCCESS
        }
        _ => sys::Result::ERROR_HANDLE_INVALID,
    }
}

unsafe extern "system" fn create_action(
    set: sys::ActionSet,
    info: *const sys::ActionCreateInfo,
    out: *mut sys::Action,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable handle or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    xr_try!(name_of(&info.action_name));
    let kinds = [
        sys::ActionType::BOOLEAN_INPUT,
        sys::ActionType::FLOAT_INPUT,
        sys::ActionType::VECTOR2F_INPUT,
        sys::ActionType::POSE_INPUT,
        sys::ActionType::VIBRATION_OUTPUT,
    ];
    if !kinds.contains(&info.action_type) {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    if info.count_subaction_paths > 0 && info.subaction_paths.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let mut rt = runtime();
    let Some(k) = set_index(set).filter(|&k| matches!(rt.input.sets.get(k), Some(Some(_)))) else {
        return sys::Result::ERROR_HANDLE_INVALID;
    };
    if rt.input.sets[k].as_ref().is_some_and(|s| s.frozen) {
        return sys::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED;
    }
    let mut hands = Vec::new();
    for i in 0..info.count_subaction_paths as usize {
        // SAFETY: the create info holds `count_subaction_paths` paths (checked non-null).
        let p = unsafe { *info.subaction_paths.add(i) };
        match hand_of(&rt, p) {
            Ok(Some(h)) if !hands.contains(&h) => hands.push(h),
            Ok(_) => return sys::Result::ERROR_PATH_UNSUPPORTED,
            Err(e) => return e,
        }
    }
    rt.input.actions.push(Some(ActionData {
        set: k,
        kind: info.action_type,
        hands,
    }));
    *out = sys::Action::from_raw(ACTION_TAG | rt.input.actions.len() as u64);
    sys::Result::SUCCESS
}

unsafe extern "system" fn destroy_action(a: sys::Action) -> sys::Result {
    let mut rt = runtime();
    let k = xr_try!(action_index(&rt, a));
    rt.input.actions[k] = None;
    sys::Result::SUCCESS
}

unsafe extern "system" fn suggest_bindings(
    instance: sys::Instance,
    info: *const sys::InteractionProfileSuggestedBinding,
) -> sys::Result {
    xr_try!(check_instance(instance));
    // SAFETY: the caller passes a valid struct or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    if info.count_suggested_bindings == 0 || info.suggested_bindings.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let mut rt = runtime();
    if rt.input.sets.iter().flatten().any(|s| s.frozen) {
        return sys::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED;
    }
    let Some(profile) = rt.path_text(info.interaction_profile).map(str::to_string) else {
        return sys::Result::ERROR_PATH_INVALID;
    };
    if !profile.starts_with("/interaction_profiles/") {
        return sys::Result::ERROR_PATH_UNSUPPORTED;
    }
    let mut pairs = Vec::new();
    for i in 0..info.count_suggested_bindings as usize {
        // SAFETY: the struct holds `count_suggested_bindings` bindings (checked non-null).
        let b = unsafe { *info.suggested_bindings.add(i) };
        let k = xr_try!(action_index(&rt, b.action));
        let Some(path) = rt.path_text(b.binding).map(str::to_string) else {
            return sys::Result::ERROR_PATH_INVALID;
        };
        if !HANDS.iter().any(|h| path.starts_with(&format!("{h}/"))) {
            return sys::Result::ERROR_PATH_UNSUPPORTED;
        }
        let output = path.contains("/output/");
        if output != (action(&rt, k).kind == sys::ActionType::VIBRATION_OUTPUT) {
            return sys::Result::ERROR_PATH_UNSUPPORTED;
        }
        pairs.push((k, path));
    }
    // A later suggestion for the same profile replaces the earlier one.
    rt.input.suggested.retain(|(p, _)| *p != profile);
    rt.input.suggested.push((profile, pairs));
    sys::Result::SUCCESS
}

unsafe extern "system" fn attach_action_sets(
    session: sys::Session,
    info: *const sys::SessionActionSetsAttachInfo,
) -> sys::Result {
    // SAFETY: the caller passes a valid struct or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    if info.count_action_sets > 0 && info.action_sets.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    result(with_session(session, |rt| {
        if rt.input.attached {
            return Err(sys::Result::ERROR_ACTIONSETS_ALREADY_ATTACHED);
        }
        let mut ks = Vec::new();
        for i in 0..info.count_action_sets as usize {
            // SAFETY: the struct holds `count_action_sets` handles (checked non-null).
            let h = unsafe { *info.action_sets.add(i) };
            match set_index(h).filter(|&k| matches!(rt.input.sets.get(k), Some(Some(_)))) {
                Some(k) => ks.push(k),
                None => return Err(sys::Result::ERROR_HANDLE_INVALID),
            }
        }
        for k in ks {
            if let Some(Some(s)) = rt.input.sets.get_mut(k) {
                s.frozen = true;
            }
        }
        rt.input.attached = true;
        rt.input.profile = PROFILES
            .iter()
            .find(|p| rt.input.suggested.iter().any(|(q, _)| q == *p))
            .map(|p| p.to_string());
        profile_changed(rt);
        Ok(())
    }))
}

unsafe extern "system" fn current_profile(
    session: sys::Session,
    top: sys::Path,
    out: *mut sys::InteractionProfileState,
) -> sys::Result {
    // SAFETY: the caller passes a writable struct or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    let r = with_session(session, |rt| {
        if !rt.input.attached {
            return Err(sys::Result::ERROR_ACTIONSET_NOT_ATTACHED);
        }
        let hand = hand_of(rt, top)?.ok_or(sys::Result::ERROR_PATH_UNSUPPORTED)?;
        let profile = rt.input.profile.clone();
        Ok(match profile {
            Some(p) if rt.input.present[hand] => rt.intern(&p),
            _ => sys::Path::NULL,
        })
    });
    out.interaction_profile = xr_try!(r);
    sys::Result::SUCCESS
}

unsafe extern "system" fn sync_actions(
    session: sys::Session,
    info: *const sys::ActionsSyncInfo,
) -> sys::Result {
    // SAFETY: the caller passes a valid struct or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    if info.count_active_action_sets > 0 && info.active_action_sets.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let r = with_session(session, |rt| {
        live(rt)?;
        for i in 0..info.count_active_action_sets as usize {
            // SAFETY: the struct holds `count_active_action_sets` entries (checked non-null).
            let a = unsafe { *info.active_action_sets.add(i) };
            let frozen = set_index(a.action_set)
                .and_then(|k| rt.input.sets.get(k))
                .map(|s| s.as_ref().is_some_and(|s| s.frozen));
            match frozen {
                None | Some(false) if set_index(a.action_set).is_none() => {
                    return Err(sys::Result::ERROR_HANDLE_INVALID);
                }
                Some(true) => {}
                _ => return Err(sys::Result::ERROR_ACTIONSET_NOT_ATTACHED),
            }
            hand_of(rt, a.subaction_path)?;
        }
        let focused = rt
            .session
            .as_ref()
            .is_some_and(|s| s.state == sys::SessionState::FOCUSED);
        if !focused {
            rt.input.synced_ns = 0;
            rt.input.before_ns = 0;
            return Ok(sys::Result::SESSION_NOT_FOCUSED);
        }
        rt.input.before_ns = rt.input.synced_ns;
        rt.input.synced_ns = rt.now_ns;
        // A controller that comes or goes changes what is bound: tell the app.
        let now = [present(rt, 0, rt.now_ns), present(rt, 1, rt.now_ns)];
        if now != rt.input.present {
            rt.input.present = now;
            profile_changed(rt);
        }
        Ok(sys::Result::SUCCESS)
    });
    r.unwrap_or_else(|e| e)
}

/// Runs `f` on the reading of an action for a state query.
fn with_reading(
    session: sys::Session,
    info: *const sys::ActionStateGetInfo,
    kind: sys::ActionType,
) -> Result<Reading, sys::Result> {
    // SAFETY: the caller passes a valid get info or null (rejected).
    let info = unsafe { arg(info) }?;
    with_session(session, |rt| read(rt, info, kind))
}

unsafe extern "system" fn state_boolean(
    session: sys::Session,
    info: *const sys::ActionStateGetInfo,
    state: *mut sys::ActionStateBoolean,
) -> sys::Result {
    // SAFETY: the caller passes a writable state or null (rejected).
    let state = xr_try!(unsafe { arg_mut(state) });
    let r = xr_try!(with_reading(session, info, sys::ActionType::BOOLEAN_INPUT));
    let (now, before) = (r.now > 0.5, r.before > 0.5);
    state.current_state = now.into();
    state.changed_since_last_sync = (r.active && now != before).into();
    state.last_change_time = sys::Time::from_nanos(r.changed_at_ns);
    state.is_active = r.active.into();
    sys::Result::SUCCESS
}

unsafe extern "system" fn state_float(
    session: sys::Session,
    info: *const sys::ActionStateGetInfo,
    state: *mut sys::ActionStateFloat,
) -> sys::Result {
    // SAFETY: the caller passes a writable state or null (rejected).
    let state = xr_try!(unsafe { arg_mut(state) });
    let r = xr_try!(with_reading(session, info, sys::ActionType::FLOAT_INPUT));
    state.current_state = r.now;
    state.changed_since_last_sync = (r.active && r.now != r.before).into();
    state.last_change_time = sys::Time::from_nanos(r.changed_at_ns);
    state.is_active = r.active.into();
    sys::Result::SUCCESS
}

unsafe extern "system" fn state_vector2(
    session: sys::Session,
    info: *const sys::ActionStateGetInfo,
    state: *mut sys::ActionStateVector2f,
) -> sys::Result {
    // SAFETY: the caller passes a writable state or null (rejected).
    let state = xr_try!(unsafe { arg_mut(state) });
    // The trace has no trackpad position: the thumb rests at the centre.
    let r = xr_try!(with_reading(session, info, sys::ActionType::VECTOR2F_INPUT));
    state.current_state = sys::Vector2f { x: 0.0, y: 0.0 };
    state.changed_since_last_sync = false.into();
    state.last_change_time = sys::Time::from_nanos(0);
    state.is_active = r.active.into();
    sys::Result::SUCCESS
}

unsafe extern "system" fn state_pose(
    session: sys::Session,
    info: *const sys::ActionStateGetInfo,
    state: *mut sys::ActionStatePose,
) -> sys::Result {
    // SAFETY: the caller passes a writable state or null (rejected).
    let state = xr_try!(unsafe { arg_mut(state) });
    let r = xr_try!(with_reading(session, info, sys::ActionType::POSE_INPUT));
    state.is_active = r.active.into();
    sys::Result::SUCCESS
}

unsafe extern "system" fn bound_sources(
    session: sys::Session,
    info: *const sys::BoundSourcesForActionEnumerateInfo,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::Path,
) -> sys::Result {
    // SAFETY: the caller passes a valid struct or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    let paths = xr_try!(with_session(session, |rt| {
        if !rt.input.attached {
            return Err(sys::Result::ERROR_ACTIONSET_NOT_ATTACHED);
        }
        let k = action_index(rt, info.action)?;
        let mut full = Vec::new();
        for (h, hand) in HANDS.iter().enumerate() {
            for b in bindings(rt, k, h) {
                full.push(format!("{hand}{b}"));
            }
        }
        Ok(full.iter().map(|p| rt.intern(p)).collect::<Vec<_>>())
    }));
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &paths, |a, b| *b = *a) }
}

unsafe extern "system" fn create_action_space(
    session: sys::Session,
    info: *const sys::ActionSpaceCreateInfo,
    out: *mut sys::Space,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable handle or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    let offset = xr_try!(check_pose(info.pose_in_action_space));
    let h = xr_try!(with_session(session, |rt| {
        let k = action_index(rt, info.action)?;
        if action(rt, k).kind != sys::ActionType::POSE_INPUT {
            return Err(sys::Result::ERROR_ACTION_TYPE_MISMATCH);
        }
        let hand = hand_of(rt, info.subaction_path)?;
        hands_for(rt, k, hand)?;
        add_space(
            rt,
            SpaceData {
                kind: SpaceKind::Action { action: k, hand },
                offset,
            },
        )
    }));
    *out = sys::Space::from_raw(h);
    sys::Result::SUCCESS
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

/// The haptics log's name in the output folder.
pub const HAPTICS_FILE: &str = "haptics.jsonl";

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
