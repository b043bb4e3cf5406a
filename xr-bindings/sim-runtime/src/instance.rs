//! The instance and the system: extensions, creating the instance (which reads the settings
//! and the trace), the head-mounted display's properties and views, the event queue, and
//! paths.

use crate::actions::Input;
use crate::config::Config;
use crate::ffi::{arg, arg_mut, two_call, write_c, xr_try};
use crate::state::{VulkanState, check_instance, check_system, runtime};
use crate::system::{EYE_SIZE, INSTANCE, RUNTIME_NAME, SYSTEM, SYSTEM_NAME, VULKAN_ENABLE2};
use openxr_sys as sys;
use std::ffi::{CStr, c_char};
use sys::Handle;

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrEnumerateInstanceExtensionProperties" => Some(transmute::<
                sys::pfn::EnumerateInstanceExtensionProperties,
                V,
            >(enumerate_extensions)),
            "xrEnumerateApiLayerProperties" => Some(transmute::<
                sys::pfn::EnumerateApiLayerProperties,
                V,
            >(enumerate_layers)),
            "xrCreateInstance" => Some(transmute::<sys::pfn::CreateInstance, V>(create_instance)),
            "xrDestroyInstance" => {
                Some(transmute::<sys::pfn::DestroyInstance, V>(destroy_instance))
            }
            "xrGetInstanceProperties" => Some(transmute::<sys::pfn::GetInstanceProperties, V>(
                get_instance_properties,
            )),
            "xrGetSystem" => Some(transmute::<sys::pfn::GetSystem, V>(get_system)),
            "xrGetSystemProperties" => Some(transmute::<sys::pfn::GetSystemProperties, V>(
                get_system_properties,
            )),
            "xrEnumerateViewConfigurations" => Some(transmute::<
                sys::pfn::EnumerateViewConfigurations,
                V,
            >(enumerate_view_configurations)),
            "xrEnumerateViewConfigurationViews" => {
                Some(transmute::<sys::pfn::EnumerateViewConfigurationViews, V>(
                    enumerate_view_configuration_views,
                ))
            }
            "xrPollEvent" => Some(transmute::<sys::pfn::PollEvent, V>(poll_event)),
            "xrStringToPath" => Some(transmute::<sys::pfn::StringToPath, V>(string_to_path)),
            "xrPathToString" => Some(transmute::<sys::pfn::PathToString, V>(path_to_string)),
            _ => None,
        }
    }
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
    rt.input = Input::NEW;
    rt.config = Some(config);
    rt.lost = false;
    rt.headset_gone_polls = 0;
    rt.now_ns = 0;
    rt.state_log.clear();
    rt.sessions_made = 0;
    rt.frames_shown = 0;
    rt.paths.clear();
    rt.vulkan_enabled = vulkan;
    rt.vulkan = VulkanState::NONE;
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
        rt.vulkan = VulkanState::NONE;
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
