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
use sys::Handle;

// The modules in layers, each using only those below it (`tests/layering.rs` checks that no
// module reaches back to itself):
// - entry points, by area: `instance`, `session` (with XR_KHR_vulkan_enable2), `frame`,
//   `spaces`, `swapchain`, `input`, `haptics`; `frame` uses `spaces` and `swapchain`, `input`
//   uses `spaces`;
// - what the entry points share: `bindings` (what actions read), over `tracking` (where the
//   trace puts the head and controllers);
// - the runtime's state and its accessors: `state`;
// - plain data and helpers: `actions`, `config`, `ffi`, `gpu`, `pose`, `system`.
mod actions;
mod bindings;
mod config;
mod ffi;
mod frame;
mod gpu;
mod haptics;
mod input;
mod instance;
mod pose;
mod session;
mod spaces;
mod state;
mod swapchain;
mod system;
mod tracking;

pub use config::{CONFIG_ENV, Config, ConfigError, HAPTICS_FILE};
pub use system::{
    API_VERSION, EYE_SIZE, FRAME_PERIOD_NS, RUNTIME_NAME, SYSTEM_NAME, VULKAN_ENABLE2,
};

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
    let f = lookup(name);
    // SAFETY: `function` is non-null (checked above) and writable, per the API.
    unsafe { *function = f };
    if f.is_some() {
        sys::Result::SUCCESS
    } else {
        sys::Result::ERROR_FUNCTION_UNSUPPORTED
    }
}

/// The function for a name: each area's entry points, then [`unsupported`] for the rest of the
/// core; `None` for a name this runtime does not know (or an extension the app did not enable).
fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (both transmutes): each turns a function pointer of the exact pfn type the
    // OpenXR API declares for that name into the untyped PFN_xrVoidFunction the API returns;
    // the caller casts it back to that same type before calling.
    unsafe {
        use std::mem::transmute;
        match name {
            "xrGetInstanceProcAddr" => Some(transmute::<
                sys::pfn::GetInstanceProcAddr,
                sys::pfn::VoidFunction,
            >(get_instance_proc_addr)),
            n => instance::lookup(n)
                .or_else(|| session::lookup(n))
                .or_else(|| frame::lookup(n))
                .or_else(|| spaces::lookup(n))
                .or_else(|| swapchain::lookup(n))
                .or_else(|| input::lookup(n))
                .or_else(|| haptics::lookup(n))
                .or_else(|| {
                    CORE_FUNCTIONS.contains(&n).then(|| {
                        transmute::<
                            unsafe extern "system" fn() -> sys::Result,
                            sys::pfn::VoidFunction,
                        >(unsupported)
                    })
                }),
        }
    }
}

/// Stands in for every core function not implemented yet. Every OpenXR function returns an
/// XrResult and takes only integer, handle and pointer arguments, which the calling convention
/// passes in registers and on a stack the caller cleans, so a callee that reads none of them
/// is safe to call through any of those signatures.
unsafe extern "system" fn unsupported() -> sys::Result {
    sys::Result::ERROR_FUNCTION_UNSUPPORTED
}

/// The runtime manifest (JSON) for the library at `library_path`.
pub fn manifest(library_path: &str) -> String {
    let escaped = library_path.replace('\\', "\\\\").replace('"', "\\\"");
    format!(
        "{{\n  \"file_format_version\": \"1.0.0\",\n  \"runtime\": {{\n    \"name\": \"{RUNTIME_NAME}\",\n    \"library_path\": \"{escaped}\"\n  }}\n}}\n"
    )
}
