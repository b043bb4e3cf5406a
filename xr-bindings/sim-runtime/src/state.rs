//! The runtime's state behind the C interface, and the accessors every entry point uses: the
//! lock, the live session, its state changes and the events they queue. This module sits
//! under the entry points and depends only on plain data types (`config`, `pose`, `gpu`,
//! `actions`, `system`).

use crate::actions::Input;
use crate::config::Config;
use crate::gpu::{Device, Swapchain};
use crate::pose::SpaceData;
use crate::system::{INSTANCE, SESSION, SYSTEM};
use openxr_sys as sys;
use std::sync::Mutex;
use sys::Handle;
use sys::platform::VkGetInstanceProcAddr;

/// Runtime state behind the C interface.
pub(crate) struct Runtime {
    pub(crate) instance_alive: bool,
    /// Interned paths: XrPath n is `paths[n - 1]`.
    pub(crate) paths: Vec<String>,
    /// The app enabled XR_KHR_vulkan_enable2.
    pub(crate) vulkan_enabled: bool,
    pub(crate) vulkan: VulkanState,
    pub(crate) session: Option<SessionData>,
    /// Events not yet polled, oldest first.
    pub(crate) events: std::collections::VecDeque<Event>,
    pub(crate) config: Option<Config>,
    /// The injected session loss has happened.
    pub(crate) lost: bool,
    /// `xrGetSystem` calls left that find no headset.
    pub(crate) headset_gone_polls: u32,
    /// Display time of the newest waited frame, ns (event and log time stamps).
    pub(crate) now_ns: i64,
    /// Every session state entered: "display time ns, session number, state".
    pub(crate) state_log: Vec<String>,
    /// Sessions created under this instance.
    pub(crate) sessions_made: u32,
    /// Frames ended with a stereo projection layer, over all sessions (names the dumps).
    pub(crate) frames_shown: u64,
    /// The trace that moves the head and controllers (`trace` in the settings).
    pub(crate) trace: Option<xr_bindings::keyframes::KeyframeFile>,
    pub(crate) input: Input,
}

static RUNTIME: Mutex<Runtime> = Mutex::new(Runtime {
    instance_alive: false,
    paths: Vec::new(),
    vulkan_enabled: false,
    vulkan: VulkanState::NONE,
    session: None,
    events: std::collections::VecDeque::new(),
    config: None,
    lost: false,
    headset_gone_polls: 0,
    now_ns: 0,
    state_log: Vec::new(),
    sessions_made: 0,
    frames_shown: 0,
    trace: None,
    input: Input::NEW,
});

impl Runtime {
    /// The text of an interned path.
    pub(crate) fn path_text(&self, path: sys::Path) -> Option<&str> {
        (path.into_raw() as usize)
            .checked_sub(1)
            .and_then(|k| self.paths.get(k))
            .map(String::as_str)
    }

    /// The path for `text` (well-formed), interning it if new.
    pub(crate) fn intern(&mut self, text: &str) -> sys::Path {
        let n = match self.paths.iter().position(|p| p == text) {
            Some(k) => k + 1,
            None => {
                self.paths.push(text.to_string());
                self.paths.len()
            }
        };
        sys::Path::from_raw(n as u64)
    }

    /// Writes `session-states.log` into the configured output folder (whole, atomically).
    pub(crate) fn write_state_log(&self) {
        let Some(dir) = self.config.as_ref().and_then(|c| c.out_dir.as_ref()) else {
            return;
        };
        let mut text = self.state_log.join("\n");
        text.push('\n');
        let path = dir.join("session-states.log");
        let tmp = dir.join("session-states.log.partial");
        let written = std::fs::create_dir_all(dir)
            .and_then(|()| std::fs::write(&tmp, text))
            .and_then(|()| std::fs::rename(&tmp, &path));
        if let Err(e) = written {
            eprintln!("vesalius-sim-runtime: {}: {e}", path.display());
        }
    }
}

pub(crate) fn runtime() -> std::sync::MutexGuard<'static, Runtime> {
    match RUNTIME.lock() {
        Ok(g) => g,
        Err(poisoned) => poisoned.into_inner(),
    }
}

/// The instance handle is live, or the error to return.
pub(crate) fn check_instance(instance: sys::Instance) -> Result<(), sys::Result> {
    if instance.into_raw() == INSTANCE && runtime().instance_alive {
        Ok(())
    } else {
        Err(sys::Result::ERROR_HANDLE_INVALID)
    }
}

/// The instance is live and `system` is its headset, or the error to return.
pub(crate) fn check_system(
    instance: sys::Instance,
    system: sys::SystemId,
) -> Result<(), sys::Result> {
    check_instance(instance)?;
    if system.into_raw() != SYSTEM {
        return Err(sys::Result::ERROR_SYSTEM_INVALID);
    }
    Ok(())
}

/// What the runtime keeps of the app's Vulkan objects (as addresses: the runtime state is
/// shared between threads, and it never dereferences them itself).
#[derive(Clone, Copy)]
pub(crate) struct VulkanState {
    pub(crate) gipa: Option<VkGetInstanceProcAddr>,
    pub(crate) instance: usize,
    pub(crate) requirements_queried: bool,
}

impl VulkanState {
    pub(crate) const NONE: VulkanState = VulkanState {
        gipa: None,
        instance: 0,
        requirements_queried: false,
    };
}

/// Where the app stands in the wait / begin / end cycle.
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct FrameLoop {
    /// Frames returned by `xrWaitFrame`.
    pub(crate) waited: u64,
    /// The predicted display time of the waited frame not yet begun.
    pub(crate) pending: Option<i64>,
    /// The display time of the frame begun and not yet ended.
    pub(crate) begun: Option<i64>,
    /// Frames ended, and those that carried a two-view projection layer.
    pub(crate) ended: u64,
    pub(crate) projected: u64,
}

pub(crate) struct SessionData {
    /// The latest state the runtime has put the session in (queued for the app).
    pub(crate) state: sys::SessionState,
    pub(crate) begun: bool,
    pub(crate) exit_requested: bool,
    pub(crate) frames: FrameLoop,
    /// Reference spaces: handle n is `spaces[n - 1]` (None once destroyed).
    pub(crate) spaces: Vec<Option<SpaceData>>,
    /// The app's Vulkan device from the session's graphics binding.
    pub(crate) device: Option<Device>,
    /// Swapchains: handle n is `swapchains[n - 1]` (None once destroyed).
    pub(crate) swapchains: Vec<Option<Swapchain>>,
}

impl SessionData {
    /// Frees the swapchains' images on the app's device.
    pub(crate) fn release_gpu(&mut self) {
        if let Some(dev) = self.device.as_ref() {
            for mut c in self.swapchains.drain(..).flatten() {
                c.destroy(dev);
            }
        }
    }
}

/// A session state change waiting in the event queue.
pub(crate) struct Event {
    pub(crate) session: u64,
    /// A session state change, or (None) XrEventDataInteractionProfileChanged.
    pub(crate) state: Option<sys::SessionState>,
    pub(crate) time_ns: i64,
}

pub(crate) fn enter(rt: &mut Runtime, state: sys::SessionState) {
    if let Some(s) = rt.session.as_mut() {
        s.state = state;
        rt.events.push_back(Event {
            session: SESSION,
            state: Some(state),
            time_ns: rt.now_ns,
        });
        let line = format!("{} {} {:?}", rt.now_ns, rt.sessions_made, state);
        rt.state_log.push(line);
    }
}

/// Tells the app that what its actions are bound to changed (attached, controller gone or back).
pub(crate) fn profile_changed(rt: &mut Runtime) {
    if rt.session.is_some() {
        rt.events.push_back(Event {
            session: SESSION,
            state: None,
            time_ns: rt.now_ns,
        });
    }
}

/// The live session, or the error for a bad handle.
pub(crate) fn with_session<T>(
    session: sys::Session,
    f: impl FnOnce(&mut Runtime) -> Result<T, sys::Result>,
) -> Result<T, sys::Result> {
    let mut rt = runtime();
    if session.into_raw() != SESSION || rt.session.is_none() || !rt.instance_alive {
        return Err(sys::Result::ERROR_HANDLE_INVALID);
    }
    f(&mut rt)
}

/// The session of a runtime `with_session` has checked.
pub(crate) fn live(rt: &mut Runtime) -> Result<&mut SessionData, sys::Result> {
    rt.session.as_mut().ok_or(sys::Result::ERROR_HANDLE_INVALID)
}

/// The session, which must have begun.
pub(crate) fn running(rt: &mut Runtime) -> Result<&mut SessionData, sys::Result> {
    let s = live(rt)?;
    if !s.begun {
        return Err(sys::Result::ERROR_SESSION_NOT_RUNNING);
    }
    Ok(s)
}

pub(crate) fn result(r: Result<(), sys::Result>) -> sys::Result {
    r.err().unwrap_or(sys::Result::SUCCESS)
}
