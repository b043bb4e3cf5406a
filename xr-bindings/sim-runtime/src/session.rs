//! XR_KHR_vulkan_enable2 (the app's Vulkan instance and device are made through the runtime,
//! on whatever Vulkan driver the app loads) and the session life cycle with its state events.
//!
//! A begun session becomes SYNCHRONIZED at the app's first `xrWaitFrame` and VISIBLE, then
//! FOCUSED, at its first `xrEndFrame` (see `frame.rs`).

use crate::ffi::{arg, arg_mut, xr_try};
use crate::gpu::Device;
use crate::state::{
    FrameLoop, SessionData, check_system, enter, live, result, running, runtime, with_session,
};
use crate::system::SESSION;
use openxr_sys as sys;
use std::ffi::{c_char, c_void};
use sys::Handle;
use sys::platform::{VkDevice, VkGetInstanceProcAddr, VkInstance, VkPhysicalDevice};

/// The session functions and, when the app enabled it, XR_KHR_vulkan_enable2's.
pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    let vulkan = runtime().vulkan_enabled;
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrGetVulkanGraphicsRequirements2KHR" if vulkan => Some(transmute::<
                sys::pfn::GetVulkanGraphicsRequirements2KHR,
                V,
            >(requirements)),
            "xrCreateVulkanInstanceKHR" if vulkan => Some(transmute::<
                sys::pfn::CreateVulkanInstanceKHR,
                V,
            >(create_vulkan_instance)),
            "xrGetVulkanGraphicsDevice2KHR" if vulkan => Some(transmute::<
                sys::pfn::GetVulkanGraphicsDevice2KHR,
                V,
            >(graphics_device)),
            "xrCreateVulkanDeviceKHR" if vulkan => Some(transmute::<
                sys::pfn::CreateVulkanDeviceKHR,
                V,
            >(create_vulkan_device)),
            "xrCreateSession" => Some(transmute::<sys::pfn::CreateSession, V>(create_session)),
            "xrDestroySession" => Some(transmute::<sys::pfn::DestroySession, V>(destroy_session)),
            "xrBeginSession" => Some(transmute::<sys::pfn::BeginSession, V>(begin_session)),
            "xrEndSession" => Some(transmute::<sys::pfn::EndSession, V>(end_session)),
            "xrRequestExitSession" => Some(transmute::<sys::pfn::RequestExitSession, V>(
                request_exit_session,
            )),
            _ => None,
        }
    }
}

/// A Vulkan entry point through the app's `vkGetInstanceProcAddr`, as type `F`.
///
/// # Safety
/// `F` must be the function pointer type Vulkan declares for `name`.
unsafe fn vk_fn<F: Copy>(gipa: VkGetInstanceProcAddr, instance: usize, name: &[u8]) -> Option<F> {
    debug_assert_eq!(name.last(), Some(&0));
    // SAFETY: `name` is NUL-terminated; `instance` is null or the app's live VkInstance.
    let f = unsafe { gipa(instance as VkInstance, name.as_ptr().cast::<c_char>()) }?;
    // SAFETY: `F` is the pointer type Vulkan declares for `name` (caller's contract), and all
    // function pointers have the same size.
    Some(unsafe { std::mem::transmute_copy::<unsafe extern "system" fn(), F>(&f) })
}

type VkCreateInstance =
    unsafe extern "system" fn(*const c_void, *const c_void, *mut VkInstance) -> i32;
type VkEnumeratePhysicalDevices =
    unsafe extern "system" fn(VkInstance, *mut u32, *mut VkPhysicalDevice) -> i32;
type VkCreateDevice =
    unsafe extern "system" fn(VkPhysicalDevice, *const c_void, *const c_void, *mut VkDevice) -> i32;

unsafe extern "system" fn requirements(
    instance: sys::Instance,
    system: sys::SystemId,
    out: *mut sys::GraphicsRequirementsVulkanKHR,
) -> sys::Result {
    xr_try!(check_system(instance, system));
    // SAFETY: the caller passes a writable struct or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    out.min_api_version_supported = sys::Version::new(1, 0, 0);
    out.max_api_version_supported = sys::Version::new(1, 3, 0);
    runtime().vulkan.requirements_queried = true;
    sys::Result::SUCCESS
}

unsafe extern "system" fn create_vulkan_instance(
    instance: sys::Instance,
    info: *const sys::VulkanInstanceCreateInfoKHR,
    vk_instance: *mut VkInstance,
    vk_result: *mut i32,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    xr_try!(check_system(instance, info.system_id));
    let Some(gipa) = info.pfn_get_instance_proc_addr else {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    };
    if vk_instance.is_null() || vk_result.is_null() || info.vulkan_create_info.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: vkCreateInstance has the declared type.
    let Some(create) = (unsafe { vk_fn::<VkCreateInstance>(gipa, 0, b"vkCreateInstance\0") })
    else {
        return sys::Result::ERROR_RUNTIME_FAILURE;
    };
    // SAFETY: the app's create info and allocator are passed through unchanged, as the
    // extension specifies; `vk_instance` is writable.
    let vr = unsafe { create(info.vulkan_create_info, info.vulkan_allocator, vk_instance) };
    // SAFETY: `vk_result` is non-null (checked) and writable.
    unsafe { *vk_result = vr };
    if vr == 0 {
        let mut rt = runtime();
        rt.vulkan.gipa = Some(gipa);
        // SAFETY: vkCreateInstance succeeded, so `*vk_instance` holds the new instance.
        rt.vulkan.instance = unsafe { *vk_instance } as usize;
    }
    sys::Result::SUCCESS
}

unsafe extern "system" fn graphics_device(
    instance: sys::Instance,
    info: *const sys::VulkanGraphicsDeviceGetInfoKHR,
    physical: *mut VkPhysicalDevice,
) -> sys::Result {
    // SAFETY: the caller passes a valid get info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    xr_try!(check_system(instance, info.system_id));
    let vk = runtime().vulkan;
    let (Some(gipa), false) = (vk.gipa, physical.is_null()) else {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    };
    let vk_instance = info.vulkan_instance as usize;
    if vk_instance != vk.instance {
        return sys::Result::ERROR_GRAPHICS_DEVICE_INVALID;
    }
    // SAFETY: vkEnumeratePhysicalDevices has the declared type.
    let Some(enumerate) = (unsafe {
        vk_fn::<VkEnumeratePhysicalDevices>(gipa, vk_instance, b"vkEnumeratePhysicalDevices\0")
    }) else {
        return sys::Result::ERROR_RUNTIME_FAILURE;
    };
    // The first device: the headset's GPU on a real runtime; here whatever the driver lists
    // first (lavapipe where there is no GPU). Room for one: VK_INCOMPLETE is fine.
    let mut count = 1u32;
    let mut first: VkPhysicalDevice = std::ptr::null();
    // SAFETY: a live instance, and room for `count` handles.
    let r = unsafe { enumerate(info.vulkan_instance, &mut count, &mut first) };
    if r < 0 || count == 0 || first.is_null() {
        return sys::Result::ERROR_SYSTEM_INVALID;
    }
    // SAFETY: `physical` is non-null (checked) and writable.
    unsafe { *physical = first };
    sys::Result::SUCCESS
}

unsafe extern "system" fn create_vulkan_device(
    instance: sys::Instance,
    info: *const sys::VulkanDeviceCreateInfoKHR,
    vk_device: *mut VkDevice,
    vk_result: *mut i32,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    xr_try!(check_system(instance, info.system_id));
    let (Some(gipa), false, false) = (
        info.pfn_get_instance_proc_addr,
        vk_device.is_null(),
        vk_result.is_null(),
    ) else {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    };
    let vk = runtime().vulkan;
    // SAFETY: vkCreateDevice has the declared type.
    let Some(create) = (unsafe { vk_fn::<VkCreateDevice>(gipa, vk.instance, b"vkCreateDevice\0") })
    else {
        return sys::Result::ERROR_RUNTIME_FAILURE;
    };
    // SAFETY: the app's physical device, create info and allocator pass through unchanged;
    // `vk_device` and `vk_result` are writable.
    unsafe {
        *vk_result = create(
            info.vulkan_physical_device,
            info.vulkan_create_info,
            info.vulkan_allocator,
            vk_device,
        );
    }
    sys::Result::SUCCESS
}

/// Whether a structure chain holds a Vulkan graphics binding with live handles.
///
/// # Safety
/// `next` must be null or a valid OpenXR structure chain.
unsafe fn vulkan_binding(mut next: *const c_void) -> Option<sys::GraphicsBindingVulkanKHR> {
    while !next.is_null() {
        // SAFETY: every chained structure starts with (type, next) (caller's contract).
        let base = unsafe { &*next.cast::<sys::BaseInStructure>() };
        if base.ty == sys::GraphicsBindingVulkanKHR::TYPE {
            // SAFETY: the type tag says what the structure is.
            return Some(unsafe { *next.cast::<sys::GraphicsBindingVulkanKHR>() });
        }
        next = base.next.cast::<c_void>();
    }
    None
}

unsafe extern "system" fn create_session(
    instance: sys::Instance,
    info: *const sys::SessionCreateInfo,
    session: *mut sys::Session,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    xr_try!(check_system(instance, info.system_id));
    if session.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: the create info's chain is a valid OpenXR chain (caller's contract).
    let Some(binding) = (unsafe { vulkan_binding(info.next) }) else {
        return sys::Result::ERROR_GRAPHICS_DEVICE_INVALID;
    };
    let mut rt = runtime();
    if !rt.vulkan.requirements_queried {
        return sys::Result::ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING;
    }
    if binding.instance.is_null() || binding.device.is_null() || binding.physical_device.is_null() {
        return sys::Result::ERROR_GRAPHICS_DEVICE_INVALID;
    }
    if rt.session.is_some() {
        return sys::Result::ERROR_LIMIT_REACHED;
    }
    let Some(gipa) = rt.vulkan.gipa else {
        // The app made its Vulkan instance without xrCreateVulkanInstanceKHR: this runtime
        // needs that call to reach the app's driver.
        return sys::Result::ERROR_GRAPHICS_DEVICE_INVALID;
    };
    if binding.instance as usize != rt.vulkan.instance {
        return sys::Result::ERROR_GRAPHICS_DEVICE_INVALID;
    }
    // SAFETY: the binding's handles are live (the app's contract) and were made through
    // `gipa`'s instance (checked just above).
    let device = unsafe { Device::load(gipa, &binding) };
    rt.sessions_made += 1;
    rt.input.reset_session();
    rt.session = Some(SessionData {
        state: sys::SessionState::UNKNOWN,
        begun: false,
        exit_requested: false,
        frames: FrameLoop::default(),
        spaces: Vec::new(),
        device: Some(device),
        swapchains: Vec::new(),
    });
    enter(&mut rt, sys::SessionState::IDLE);
    enter(&mut rt, sys::SessionState::READY);
    // SAFETY: `session` is non-null (checked) and writable.
    unsafe { *session = sys::Session::from_raw(SESSION) };
    sys::Result::SUCCESS
}

unsafe extern "system" fn destroy_session(session: sys::Session) -> sys::Result {
    result(with_session(session, |rt| {
        if let Some(s) = rt.session.as_mut() {
            s.release_gpu();
        }
        rt.session = None;
        rt.events.retain(|e| e.session != SESSION);
        rt.write_state_log();
        Ok(())
    }))
}

unsafe extern "system" fn begin_session(
    session: sys::Session,
    info: *const sys::SessionBeginInfo,
) -> sys::Result {
    // SAFETY: the caller passes a valid begin info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    result(with_session(session, |rt| {
        let s = live(rt)?;
        if s.begun {
            return Err(sys::Result::ERROR_SESSION_RUNNING);
        }
        if s.state != sys::SessionState::READY {
            return Err(sys::Result::ERROR_SESSION_NOT_READY);
        }
        if info.primary_view_configuration_type != sys::ViewConfigurationType::PRIMARY_STEREO {
            return Err(sys::Result::ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED);
        }
        s.begun = true;
        s.frames = FrameLoop::default();
        Ok(())
    }))
}

unsafe extern "system" fn request_exit_session(session: sys::Session) -> sys::Result {
    result(with_session(session, |rt| {
        let s = running(rt)?;
        s.exit_requested = true;
        // Down the graph one state at a time: FOCUSED -> VISIBLE -> SYNCHRONIZED -> STOPPING.
        let mut now = s.state;
        if now == sys::SessionState::FOCUSED {
            enter(rt, sys::SessionState::VISIBLE);
            now = sys::SessionState::VISIBLE;
        }
        if now == sys::SessionState::VISIBLE {
            enter(rt, sys::SessionState::SYNCHRONIZED);
        }
        enter(rt, sys::SessionState::STOPPING);
        Ok(())
    }))
}

unsafe extern "system" fn end_session(session: sys::Session) -> sys::Result {
    result(with_session(session, |rt| {
        let s = running(rt)?;
        if s.state != sys::SessionState::STOPPING {
            return Err(sys::Result::ERROR_SESSION_NOT_STOPPING);
        }
        s.begun = false;
        let exit = s.exit_requested;
        enter(rt, sys::SessionState::IDLE);
        if exit {
            enter(rt, sys::SessionState::EXITING);
        }
        Ok(())
    }))
}
