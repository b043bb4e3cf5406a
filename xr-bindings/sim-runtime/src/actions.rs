//! The instance's action sets and actions and the session's input state, as data: handles,
//! the hands, the profiles the simulated controllers answer to, and name checks. What the
//! actions read is `bindings.rs`; the entry points are `input.rs` and `haptics.rs`.

use openxr_sys as sys;
use std::ffi::c_char;
use sys::Handle;

pub(crate) const SET_TAG: u64 = 2 << 32;
pub(crate) const ACTION_TAG: u64 = 3 << 32;
pub(crate) const HANDS: [&str; 2] = ["/user/hand/left", "/user/hand/right"];
/// The profiles this runtime's controllers answer to, most preferred first.
pub(crate) const PROFILES: [&str; 2] = [
    "/interaction_profiles/htc/vive_controller",
    "/interaction_profiles/khr/simple_controller",
];

pub(crate) struct SetData {
    /// Attached to a session: no more actions may be added.
    pub(crate) frozen: bool,
}

pub(crate) struct ActionData {
    pub(crate) set: usize,
    pub(crate) kind: sys::ActionType,
    /// Hands (0 left, 1 right) the action was created for; empty: no subaction paths.
    pub(crate) hands: Vec<usize>,
}

/// The instance's actions and the session's input state.
pub(crate) struct Input {
    pub(crate) sets: Vec<Option<SetData>>,
    pub(crate) actions: Vec<Option<ActionData>>,
    /// Suggested bindings: profile path, then (action, binding path) pairs.
    pub(crate) suggested: Vec<(String, Vec<(usize, String)>)>,
    /// The profile the runtime chose when the app attached its action sets.
    pub(crate) profile: Option<String>,
    pub(crate) attached: bool,
    /// Display time of the last `xrSyncActions` that found the session focused, and the one
    /// before (for `changedSinceLastSync`); 0: none.
    pub(crate) synced_ns: i64,
    pub(crate) before_ns: i64,
    /// Whether each hand's controller was there at the last sync.
    pub(crate) present: [bool; 2],
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

pub(crate) fn set_index(h: sys::ActionSet) -> Option<usize> {
    let raw = h.into_raw();
    (raw & !0xffff_ffff == SET_TAG && raw & 0xffff_ffff != 0)
        .then(|| (raw & 0xffff_ffff) as usize - 1)
}

/// A C string field of a create info, checked for the OpenXR name grammar.
pub(crate) fn name_of(field: &[c_char]) -> Result<String, sys::Result> {
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
