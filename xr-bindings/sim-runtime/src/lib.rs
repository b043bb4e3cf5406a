//! A simulated OpenXR runtime: a shared library the Khronos loader loads from a runtime manifest
//! (`XR_RUNTIME_JSON`), as it would load SteamVR or Monado. So far it negotiates with the
//! loader, answers every core OpenXR 1.0 function name (those not implemented yet return
//! `XR_ERROR_FUNCTION_UNSUPPORTED`), and implements the instance, the system (a head-mounted
//! display with two 1080 x 1200 views, the HTC Vive's), XR_KHR_vulkan_enable2, the session
//! life cycle with its state events, the frame loop on a simulated 90 Hz clock, reference spaces
//! and eye views (Vive field of view, 63 mm IPD). Swapchains, actions, trace-driven poses and
//! haptics come next.

use openxr_sys as sys;
use std::ffi::{CStr, c_char};
use std::sync::Mutex;
use sys::Handle;

/// `?` for functions that return an `XrResult`: the error code is returned as it is.
macro_rules! xr_try {
    ($e:expr) => {
        match $e {
            Ok(v) => v,
            Err(code) => return code,
        }
    };
}

/// The one instance handle this runtime hands out.
const INSTANCE: u64 = 1;
/// The head-mounted display's system id.
const SYSTEM: u64 = 1;
/// The API version this runtime implements.
pub const API_VERSION: sys::Version = sys::Version::new(1, 0, 20);
pub const RUNTIME_NAME: &str = "Vesalius simulated runtime";
pub const SYSTEM_NAME: &str = "Vesalius simulated HMD (HTC Vive layout)";
/// Per-eye image size, pixels (the Vive's panels).
pub const EYE_SIZE: (u32, u32) = xr_bindings::vive::EYE_SIZE;
/// The graphics extension this runtime offers.
pub const VULKAN_ENABLE2: &str = "XR_KHR_vulkan_enable2";

/// Every function of the OpenXR 1.0 core, which the loader resolves when an instance is made.
pub const CORE_FUNCTIONS: [&str; 55] = [
    "xrGetInstanceProcAddr",
    "xrEnumerateApiLayerProperties",
    "xrEnumerateInstanceExtensionProperties",
    "xrCreateInstance",
    "xrDestroyInstance",
    "xrGetInstanceProperties",
    "xrPollEvent",
    "xrResultToString",
    "xrStructureTypeToString",
    "xrGetSystem",
    "xrGetSystemProperties",
    "xrEnumerateEnvironmentBlendModes",
    "xrCreateSession",
    "xrDestroySession",
    "xrEnumerateReferenceSpaces",
    "xrCreateReferenceSpace",
    "xrGetReferenceSpaceBoundsRect",
    "xrCreateActionSpace",
    "xrLocateSpace",
    "xrDestroySpace",
    "xrEnumerateViewConfigurations",
    "xrGetViewConfigurationProperties",
    "xrEnumerateViewConfigurationViews",
    "xrEnumerateSwapchainFormats",
    "xrCreateSwapchain",
    "xrDestroySwapchain",
    "xrEnumerateSwapchainImages",
    "xrAcquireSwapchainImage",
    "xrWaitSwapchainImage",
    "xrReleaseSwapchainImage",
    "xrBeginSession",
    "xrEndSession",
    "xrRequestExitSession",
    "xrWaitFrame",
    "xrBeginFrame",
    "xrEndFrame",
    "xrLocateViews",
    "xrStringToPath",
    "xrPathToString",
    "xrCreateActionSet",
    "xrDestroyActionSet",
    "xrCreateAction",
    "xrDestroyAction",
    "xrSuggestInteractionProfileBindings",
    "xrAttachSessionActionSets",
    "xrGetCurrentInteractionProfile",
    "xrGetActionStateBoolean",
    "xrGetActionStateFloat",
    "xrGetActionStateVector2f",
    "xrGetActionStatePose",
    "xrSyncActions",
    "xrEnumerateBoundSourcesForAction",
    "xrGetInputSourceLocalizedName",
    "xrApplyHapticFeedback",
    "xrStopHapticFeedback",
];

/// Runtime state behind the C interface.
pub(crate) struct Runtime {
    instance_alive: bool,
    /// Interned paths: XrPath n is `paths[n - 1]`.
    paths: Vec<String>,
    /// The app enabled XR_KHR_vulkan_enable2.
    pub(crate) vulkan_enabled: bool,
    pub(crate) vulkan: session::VulkanState,
    pub(crate) session: Option<session::SessionData>,
    /// Events not yet polled, oldest first.
    pub(crate) events: std::collections::VecDeque<session::Event>,
    pub(crate) config: Option<config::Config>,
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
    pub(crate) input: input::Input,
}

static RUNTIME: Mutex<Runtime> = Mutex::new(Runtime {
    instance_alive: false,
    paths: Vec::new(),
    vulkan_enabled: false,
    vulkan: session::VulkanState::NONE,
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
    input: input::Input::NEW,
});

mod config;
mod frame;
mod input;
mod spaces;
mod swapchain;
pub use config::{CONFIG_ENV, Config};
pub use frame::FRAME_PERIOD_NS;
pub use input::HAPTICS_FILE;
mod session;

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

/// Copies `s` into a fixed C string buffer, truncated and NUL-terminated.
fn write_c(dst: &mut [c_char], s: &str) {
    let n = s.len().min(dst.len().saturating_sub(1));
    for (d, b) in dst.iter_mut().zip(s.bytes().take(n)) {
        *d = b as c_char;
    }
    if let Some(end) = dst.get_mut(n) {
        *end = 0;
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

/// An input structure the caller passed: null is a validation failure.
///
/// # Safety
/// `p` must be null or point to a valid `T` that outlives `'a`.
pub(crate) unsafe fn arg<'a, T>(p: *const T) -> Result<&'a T, sys::Result> {
    // SAFETY: `p` is null or valid (caller's contract).
    unsafe { p.as_ref() }.ok_or(sys::Result::ERROR_VALIDATION_FAILURE)
}

/// An output structure the caller passed: null is a validation failure.
///
/// # Safety
/// `p` must be null or point to a writable `T`, not aliased, that outlives `'a`.
pub(crate) unsafe fn arg_mut<'a, T>(p: *mut T) -> Result<&'a mut T, sys::Result> {
    // SAFETY: `p` is null or valid and unaliased (caller's contract).
    unsafe { p.as_mut() }.ok_or(sys::Result::ERROR_VALIDATION_FAILURE)
}

/// The loader's entry point: agree on the interface and hand over `xrGetInstanceProcAddr`.
///
/// # Safety
/// `loader_info` and `request` must be valid, as the loader guarantees.
#[unsafe(no_mangle)]
pub unsafe extern "system" fn xrNegotiateLoaderRuntimeInterface(
    loader_info: *const sys::NegotiateLoaderInfo,
    request: *mut sys::NegotiateRuntimeRequest,
) -> sys::Result {
    // SAFETY: the loader passes valid pointers or null; null is rejected here.
    let (Some(info), Some(req)) = (unsafe { loader_info.as_ref() }, unsafe { request.as_mut() })
    else {
        return sys::Result::ERROR_INITIALIZATION_FAILED;
    };
    if info.struct_type != sys::NegotiateLoaderInfo::TYPE
        || req.struct_type != sys::NegotiateRuntimeRequest::TYPE
        || info.min_interface_version > 1
        || info.max_interface_version < 1
        || info.max_api_version.major() < 1
    {
        return sys::Result::ERROR_INITIALIZATION_FAILED;
    }
    req.runtime_interface_version = 1;
    req.runtime_api_version = API_VERSION;
    req.get_instance_proc_addr = Some(get_instance_proc_addr);
    sys::Result::SUCCESS
}

/// Answers every core function name; functions this runtime does not implement yet get
/// [`unsupported`].
unsafe extern "system" fn get_instance_proc_addr(
    instance: sys::Instance,
    name: *const c_char,
    function: *mut Option<sys::pfn::VoidFunction>,
) -> sys::Result {
    if name.is_null() || function.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: the caller passes a NUL-terminated name (checked non-null above).
    let name = unsafe { CStr::from_ptr(name) }.to_str().unwrap_or("");
    let pre_instance = matches!(
        name,
        "xrEnumerateInstanceExtensionProperties"
            | "xrEnumerateApiLayerProperties"
            | "xrCreateInstance"
    );
    if instance == sys::Instance::NULL && !pre_instance && name != "xrGetInstanceProcAddr" {
        // SAFETY: `function` is non-null (checked above) and writable, per the API.
        unsafe { *function = None };
        return sys::Result::ERROR_HANDLE_INVALID;
    }
    // SAFETY (all transmutes below): each turns a function pointer of the exact pfn type the
    // OpenXR API declares for that name into the untyped PFN_xrVoidFunction the API returns;
    // the caller casts it back to that same type before calling.
    let f: Option<sys::pfn::VoidFunction> = unsafe {
        use std::mem::transmute;
        match name {
            "xrGetInstanceProcAddr" => Some(transmute::<
                sys::pfn::GetInstanceProcAddr,
                sys::pfn::VoidFunction,
            >(get_instance_proc_addr)),
            "xrEnumerateInstanceExtensionProperties" => Some(transmute::<
                sys::pfn::EnumerateInstanceExtensionProperties,
                sys::pfn::VoidFunction,
            >(enumerate_extensions)),
            "xrEnumerateApiLayerProperties" => Some(transmute::<
                sys::pfn::EnumerateApiLayerProperties,
                sys::pfn::VoidFunction,
            >(enumerate_layers)),
            "xrCreateInstance" => {
                Some(transmute::<sys::pfn::CreateInstance, sys::pfn::VoidFunction>(create_instance))
            }
            "xrDestroyInstance" => Some(transmute::<
                sys::pfn::DestroyInstance,
                sys::pfn::VoidFunction,
            >(destroy_instance)),
            "xrGetInstanceProperties" => Some(transmute::<
                sys::pfn::GetInstanceProperties,
                sys::pfn::VoidFunction,
            >(get_instance_properties)),
            "xrGetSystem" => Some(transmute::<sys::pfn::GetSystem, sys::pfn::VoidFunction>(
                get_system,
            )),
            "xrGetSystemProperties" => Some(transmute::<
                sys::pfn::GetSystemProperties,
                sys::pfn::VoidFunction,
            >(get_system_properties)),
            "xrEnumerateViewConfigurations" => Some(transmute::<
                sys::pfn::EnumerateViewConfigurations,
                sys::pfn::VoidFunction,
            >(enumerate_view_configurations)),
            "xrEnumerateViewConfigurationViews" => {
                Some(transmute::<
                    sys::pfn::EnumerateViewConfigurationViews,
                    sys::pfn::VoidFunction,
                >(enumerate_view_configuration_views))
            }
            "xrPollEvent" => Some(transmute::<sys::pfn::PollEvent, sys::pfn::VoidFunction>(
                poll_event,
            )),
            "xrStringToPath" => Some(transmute::<sys::pfn::StringToPath, sys::pfn::VoidFunction>(
                string_to_path,
            )),
            "xrPathToString" => Some(transmute::<sys::pfn::PathToString, sys::pfn::VoidFunction>(
                path_to_string,
            )),
            n if session::lookup(n).is_some() => session::lookup(n),
            n if input::lookup(n).is_some() => input::lookup(n),
            n if CORE_FUNCTIONS.contains(&n) => Some(transmute::<
                unsafe extern "system" fn() -> sys::Result,
                sys::pfn::VoidFunction,
            >(unsupported)),
            _ => None,
        }
    };
    // SAFETY: `function` is non-null (checked above) and writable, per the API.
    unsafe { *function = f };
    if f.is_some() {
        sys::Result::SUCCESS
    } else {
        sys::Result::ERROR_FUNCTION_UNSUPPORTED
    }
}

/// Stands in for every core function not implemented yet. Every OpenXR function returns an
/// XrResult and takes only integer, handle and pointer arguments, which the calling convention
/// passes in registers and on a stack the caller cleans, so a callee that reads none of them
/// is safe to call through any of those signatures.
unsafe extern "system" fn unsupported() -> sys::Result {
    sys::Result::ERROR_FUNCTION_UNSUPPORTED
}

/// Fills a two-call-idiom array: writes the count, and the items when there is room.
///
/// # Safety
/// `count` must be writable; `out` must hold `capacity` items when `capacity` > 0.
pub(crate) unsafe fn two_call<T>(
    capacity: u32,
    count: *mut u32,
    out: *mut T,
    items: &[T],
    copy: impl Fn(&T, &mut T),
) -> sys::Result {
    if count.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: `count` is non-null and writable (caller's contract).
    unsafe { *count = items.len() as u32 };
    if capacity == 0 {
        return sys::Result::SUCCESS;
    }
    if (capacity as usize) < items.len() || out.is_null() {
        return sys::Result::ERROR_SIZE_INSUFFICIENT;
    }
    for (k, item) in items.iter().enumerate() {
        // SAFETY: `out` holds at least `capacity` >= items.len() elements (caller's contract).
        copy(item, unsafe { &mut *out.add(k) });
    }
    sys::Result::SUCCESS
}

unsafe extern "system" fn enumerate_extensions(
    _layer: *const c_char,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::ExtensionProperties,
) -> sys::Result {
    let mut vk2 = sys::ExtensionProperties {
        ty: sys::ExtensionProperties::TYPE,
        next: std::ptr::null_mut(),
        extension_name: [0; sys::MAX_EXTENSION_NAME_SIZE],
        extension_version: 2,
    };
    write_c(&mut vk2.extension_name, VULKAN_ENABLE2);
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe {
        two_call(capacity, count, out, &[vk2], |a, b| {
            b.extension_name = a.extension_name;
            b.extension_version = a.extension_version;
        })
    }
}

unsafe extern "system" fn enumerate_layers(
    capacity: u32,
    count: *mut u32,
    out: *mut sys::ApiLayerProperties,
) -> sys::Result {
    let none: [sys::ApiLayerProperties; 0] = [];
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &none, |_, _| {}) }
}

unsafe extern "system" fn create_instance(
    info: *const sys::InstanceCreateInfo,
    instance: *mut sys::Instance,
) -> sys::Result {
    // SAFETY: the caller passes a valid create-info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    if instance.is_null() || info.ty != sys::InstanceCreateInfo::TYPE {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let v = info.application_info.api_version;
    if v.major() != 1 || v.minor() != 0 {
        return sys::Result::ERROR_API_VERSION_UNSUPPORTED;
    }
    let mut vulkan = false;
    for k in 0..info.enabled_extension_count as usize {
        // SAFETY: the create info holds `enabled_extension_count` NUL-terminated names.
        let name = unsafe { CStr::from_ptr(*info.enabled_extension_names.add(k)) };
        if name.to_bytes() == VULKAN_ENABLE2.as_bytes() {
            vulkan = true;
        } else {
            return sys::Result::ERROR_EXTENSION_NOT_PRESENT;
        }
    }
    let config = match Config::from_env() {
        Ok(c) => c,
        Err(e) => {
            eprintln!("vesalius-sim-runtime: {e}");
            return sys::Result::ERROR_RUNTIME_FAILURE;
        }
    };
    let trace = match config.load_trace() {
        Ok(t) => t,
        Err(e) => {
            eprintln!("vesalius-sim-runtime: {e}");
            return sys::Result::ERROR_RUNTIME_FAILURE;
        }
    };
    if let Err(e) = config.start_outputs() {
        eprintln!("vesalius-sim-runtime: {e}");
        return sys::Result::ERROR_RUNTIME_FAILURE;
    }
    let mut rt = runtime();
    if rt.instance_alive {
        return sys::Result::ERROR_LIMIT_REACHED;
    }
    rt.instance_alive = true;
    rt.trace = trace;
    rt.input = input::Input::NEW;
    rt.config = Some(config);
    rt.lost = false;
    rt.headset_gone_polls = 0;
    rt.now_ns = 0;
    rt.state_log.clear();
    rt.sessions_made = 0;
    rt.frames_shown = 0;
    rt.paths.clear();
    rt.vulkan_enabled = vulkan;
    rt.vulkan = session::VulkanState::NONE;
    rt.session = None;
    rt.events.clear();
    // SAFETY: `instance` is non-null (checked) and writable, per the API.
    unsafe { *instance = sys::Instance::from_raw(INSTANCE) };
    sys::Result::SUCCESS
}

unsafe extern "system" fn destroy_instance(instance: sys::Instance) -> sys::Result {
    xr_try!(check_instance(instance));
    {
        let mut rt = runtime();
        rt.instance_alive = false;
        rt.paths.clear();
        rt.write_state_log();
        // Children go with the instance.
        rt.session = None;
        rt.events.clear();
        rt.vulkan = session::VulkanState::NONE;
    }
    sys::Result::SUCCESS
}

unsafe extern "system" fn get_instance_properties(
    instance: sys::Instance,
    props: *mut sys::InstanceProperties,
) -> sys::Result {
    xr_try!(check_instance(instance));
    // SAFETY: the caller passes a writable properties struct or null (rejected).
    let p = xr_try!(unsafe { arg_mut(props) });
    p.runtime_version = sys::Version::new(0, 1, 0);
    write_c(&mut p.runtime_name, RUNTIME_NAME);
    sys::Result::SUCCESS
}

unsafe extern "system" fn get_system(
    instance: sys::Instance,
    info: *const sys::SystemGetInfo,
    system: *mut sys::SystemId,
) -> sys::Result {
    xr_try!(check_instance(instance));
    // SAFETY: the caller passes a valid get-info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    if system.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    if info.form_factor != sys::FormFactor::HEAD_MOUNTED_DISPLAY {
        return sys::Result::ERROR_FORM_FACTOR_UNSUPPORTED;
    }
    {
        // After an injected loss the headset stays away for a few polls.
        let mut rt = runtime();
        if rt.headset_gone_polls > 0 {
            rt.headset_gone_polls -= 1;
            return sys::Result::ERROR_FORM_FACTOR_UNAVAILABLE;
        }
    }
    // SAFETY: `system` is non-null (checked) and writable, per the API.
    unsafe { *system = sys::SystemId::from_raw(SYSTEM) };
    sys::Result::SUCCESS
}

unsafe extern "system" fn get_system_properties(
    instance: sys::Instance,
    system: sys::SystemId,
    props: *mut sys::SystemProperties,
) -> sys::Result {
    xr_try!(check_system(instance, system));
    // SAFETY: the caller passes a writable properties struct or null (rejected).
    let p = xr_try!(unsafe { arg_mut(props) });
    p.system_id = system;
    p.vendor_id = 0;
    write_c(&mut p.system_name, SYSTEM_NAME);
    p.graphics_properties = sys::SystemGraphicsProperties {
        max_swapchain_image_width: 4096,
        max_swapchain_image_height: 4096,
        max_layer_count: 16,
    };
    p.tracking_properties = sys::SystemTrackingProperties {
        orientation_tracking: sys::TRUE,
        position_tracking: sys::TRUE,
    };
    sys::Result::SUCCESS
}

unsafe extern "system" fn enumerate_view_configurations(
    instance: sys::Instance,
    system: sys::SystemId,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::ViewConfigurationType,
) -> sys::Result {
    xr_try!(check_system(instance, system));
    let only = [sys::ViewConfigurationType::PRIMARY_STEREO];
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &only, |a, b| *b = *a) }
}

unsafe extern "system" fn enumerate_view_configuration_views(
    instance: sys::Instance,
    system: sys::SystemId,
    config: sys::ViewConfigurationType,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::ViewConfigurationView,
) -> sys::Result {
    xr_try!(check_system(instance, system));
    if config != sys::ViewConfigurationType::PRIMARY_STEREO {
        return sys::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
    }
    let view = sys::ViewConfigurationView {
        ty: sys::ViewConfigurationView::TYPE,
        next: std::ptr::null_mut(),
        recommended_image_rect_width: EYE_SIZE.0,
        max_image_rect_width: 4096,
        recommended_image_rect_height: EYE_SIZE.1,
        max_image_rect_height: 4096,
        recommended_swapchain_sample_count: 1,
        max_swapchain_sample_count: 1,
    };
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe {
        two_call(capacity, count, out, &[view, view], |a, b| {
            // Keep the caller's chain pointer.
            let next = b.next;
            *b = *a;
            b.next = next;
        })
    }
}

unsafe extern "system" fn poll_event(
    instance: sys::Instance,
    event: *mut sys::EventDataBuffer,
) -> sys::Result {
    xr_try!(check_instance(instance));
    if event.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let Some(e) = runtime().events.pop_front() else {
        return sys::Result::EVENT_UNAVAILABLE;
    };
    match e.state {
        Some(state) => {
            let changed = sys::EventDataSessionStateChanged {
                ty: sys::EventDataSessionStateChanged::TYPE,
                next: std::ptr::null(),
                session: sys::Session::from_raw(e.session),
                state,
                time: sys::Time::from_nanos(e.time_ns),
            };
            // SAFETY: `event` is a non-null EventDataBuffer (4 kB), larger than the event
            // written, and suitably aligned for it (both start with the same header).
            unsafe {
                event
                    .cast::<sys::EventDataSessionStateChanged>()
                    .write(changed)
            };
        }
        None => {
            let changed = sys::EventDataInteractionProfileChanged {
                ty: sys::EventDataInteractionProfileChanged::TYPE,
                next: std::ptr::null(),
                session: sys::Session::from_raw(e.session),
            };
            // SAFETY: as above.
            unsafe {
                event
                    .cast::<sys::EventDataInteractionProfileChanged>()
                    .write(changed)
            };
        }
    }
    sys::Result::SUCCESS
}

unsafe extern "system" fn string_to_path(
    instance: sys::Instance,
    s: *const c_char,
    path: *mut sys::Path,
) -> sys::Result {
    xr_try!(check_instance(instance));
    if s.is_null() || path.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: `s` is a non-null NUL-terminated string (caller's contract).
    let Ok(text) = (unsafe { CStr::from_ptr(s) }).to_str() else {
        return sys::Result::ERROR_PATH_FORMAT_INVALID;
    };
    let well_formed = xr_bindings::is_path(text);
    if !well_formed {
        return sys::Result::ERROR_PATH_FORMAT_INVALID;
    }
    let p = runtime().intern(text);
    // SAFETY: `path` is non-null (checked) and writable.
    unsafe { *path = p };
    sys::Result::SUCCESS
}

unsafe extern "system" fn path_to_string(
    instance: sys::Instance,
    path: sys::Path,
    capacity: u32,
    count: *mut u32,
    buffer: *mut c_char,
) -> sys::Result {
    xr_try!(check_instance(instance));
    let Some(text) = runtime().path_text(path).map(str::to_string) else {
        return sys::Result::ERROR_PATH_INVALID;
    };
    let mut bytes: Vec<c_char> = text.bytes().map(|b| b as c_char).collect();
    bytes.push(0);
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, buffer, &bytes, |a, b| *b = *a) }
}

/// The runtime manifest (JSON) for the library at `library_path`.
pub fn manifest(library_path: &str) -> String {
    let escaped = library_path.replace('\\', "\\\\").replace('"', "\\\"");
    format!(
        "{{\n  \"file_format_version\": \"1.0.0\",\n  \"runtime\": {{\n    \"name\": \"{RUNTIME_NAME}\",\n    \"library_path\": \"{escaped}\"\n  }}\n}}\n"
    )
}
