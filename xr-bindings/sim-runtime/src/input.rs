//! Actions: action sets and actions, suggested bindings, attaching, syncing, the four kinds
//! of state, and action spaces. What the actions are bound to and read is `bindings.rs`;
//! vibration is `haptics.rs`.

use crate::actions::{
    ACTION_TAG, ActionData, HANDS, PROFILES, SET_TAG, SetData, name_of, set_index,
};
use crate::bindings::{Reading, action, action_index, bindings, hand_of, hands_for, read};
use crate::ffi::{arg, arg_mut, two_call, xr_try};
use crate::pose::{SpaceData, SpaceKind, check_pose};
use crate::spaces::add_space;
use crate::state::{check_instance, live, profile_changed, result, runtime, with_session};
use crate::tracking::present;
use openxr_sys as sys;
use sys::Handle;

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
    // The trace's pad presses put the thumb at the pressed edge; else it rests at the centre.
    let r = xr_try!(with_reading(session, info, sys::ActionType::VECTOR2F_INPUT));
    state.current_state = sys::Vector2f {
        x: r.axes[0],
        y: r.axes[1],
    };
    state.changed_since_last_sync = (r.active && r.axes != r.axes_before).into();
    state.last_change_time = sys::Time::from_nanos(r.changed_at_ns);
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
