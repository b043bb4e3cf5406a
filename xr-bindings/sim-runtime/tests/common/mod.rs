//! What the end-to-end tests share: the runtime manifest, and an app's OpenXR instance with a
//! Vulkan instance and device made through the simulated runtime (XR_KHR_vulkan_enable2, on
//! whatever Vulkan driver is installed: lavapipe in CI).

#![allow(dead_code)]

use ash::vk;
use ash::vk::Handle;
use openxr as xr;
use std::path::PathBuf;
use xr_bindings::Command;

/// The built runtime library: cargo builds the cdylib beside the test executable (in
/// target/<profile>/deps/) and, when it is a top-level artifact, copies it up a folder.
pub fn runtime_library() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("target/<profile>/deps");
    let name = "libvesalius_sim_runtime.so";
    [deps.join(name), deps.join("..").join(name)]
        .into_iter()
        .find(|p| p.exists())
        .unwrap_or_else(|| panic!("{name} was not built (looked in {})", deps.display()))
}

/// A scratch folder, removed when the test passes (kept when it fails, to look at).
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A fresh folder for one test, removed when it passes (keep the guard to the test's end).
pub fn temp_dir(tag: &str) -> Scratch {
    let dir = std::env::temp_dir().join(format!("vesalius-xr-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    Scratch(dir)
}

/// Writes the manifest into `dir` and points the loader at it (and the runtime at `config`).
///
/// Each test binary calls this once, before any loader call, from its only test.
pub fn use_runtime(dir: &std::path::Path, config: Option<&str>) -> PathBuf {
    let manifest = dir.join("runtime.json");
    std::fs::write(
        &manifest,
        vesalius_sim_runtime::manifest(&runtime_library().display().to_string()),
    )
    .expect("manifest");
    // SAFETY: one test per binary, and it calls this before the loader or runtime read the
    // environment; nothing else runs concurrently.
    unsafe { std::env::set_var("XR_RUNTIME_JSON", &manifest) };
    if let Some(text) = config {
        let path = dir.join("sim.toml");
        std::fs::write(&path, text).expect("config");
        // SAFETY: as above.
        unsafe { std::env::set_var(vesalius_sim_runtime::CONFIG_ENV, &path) };
    }
    manifest
}

pub fn app_info() -> xr::ApplicationInfo<'static> {
    xr::ApplicationInfo {
        application_name: "vesalius-test",
        application_version: 1,
        engine_name: "vesalius",
        engine_version: 1,
        api_version: xr::Version::new(1, 0, 0),
    }
}

/// An app's XR instance and the Vulkan instance and device made through the runtime.
pub struct Rig {
    pub instance: xr::Instance,
    pub system: xr::SystemId,
    ash_instance: ash::Instance,
    pub vk_instance: xr::sys::platform::VkInstance,
    pub physical: xr::sys::platform::VkPhysicalDevice,
    pub vk_device: xr::sys::platform::VkDevice,
    pub family: u32,
    _vk_entry: ash::Entry,
}

impl Rig {
    pub fn open() -> Rig {
        // SAFETY: Debian's loader conforms to the OpenXR specification.
        let entry = unsafe { xr::Entry::load(&()) }.expect("libopenxr_loader.so.1");
        let available = entry.enumerate_extensions().expect("extensions");
        assert!(available.khr_vulkan_enable2);
        let mut exts = xr::ExtensionSet::default();
        exts.khr_vulkan_enable2 = true;
        let instance = entry
            .create_instance(&app_info(), &exts, &[], &())
            .expect("instance");
        let system = instance
            .system(xr::FormFactor::HEAD_MOUNTED_DISPLAY)
            .expect("HMD");
        let req = instance
            .graphics_requirements::<xr::Vulkan>(system)
            .expect("requirements");
        assert!(req.min_api_version_supported <= xr::Version::new(1, 1, 0));
        // SAFETY: libvulkan.so.1 (Debian's loader) is a conforming Vulkan loader.
        let vk_entry =
            unsafe { ash::Entry::load() }.expect("libvulkan.so.1 (apt-get install libvulkan1)");
        let gipa = vk_entry.static_fn().get_instance_proc_addr;
        // SAFETY: vkGetInstanceProcAddr has the same signature in ash and in openxr-sys
        // (handles as pointer-sized values, a C string, an optional function pointer back).
        let gipa_xr = unsafe {
            std::mem::transmute::<
                vk::PFN_vkGetInstanceProcAddr,
                xr::sys::platform::VkGetInstanceProcAddr,
            >(gipa)
        };
        let app = vk::ApplicationInfo::default().api_version(vk::make_api_version(0, 1, 1, 0));
        let ci = vk::InstanceCreateInfo::default().application_info(&app);
        // SAFETY: a valid create info; the runtime calls vkCreateInstance with it.
        let vk_instance = unsafe {
            instance.create_vulkan_instance(
                system,
                gipa_xr,
                (&ci as *const vk::InstanceCreateInfo).cast(),
            )
        }
        .expect("xrCreateVulkanInstanceKHR")
        .expect("vkCreateInstance");
        // SAFETY: the instance was just created by vkCreateInstance.
        let ash_instance = unsafe {
            ash::Instance::load(
                vk_entry.static_fn(),
                vk::Instance::from_raw(vk_instance as u64),
            )
        };
        // SAFETY: a live Vulkan instance made through the runtime.
        let physical =
            unsafe { instance.vulkan_graphics_device(system, vk_instance) }.expect("device");
        let pd = vk::PhysicalDevice::from_raw(physical as u64);
        // SAFETY: `pd` came from this instance.
        let families = unsafe { ash_instance.get_physical_device_queue_family_properties(pd) };
        let family = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
            .expect("a graphics queue") as u32;
        let priority = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priority)];
        let dci = vk::DeviceCreateInfo::default().queue_create_infos(&queues);
        // SAFETY: a valid device create info for the runtime's physical device.
        let vk_device = unsafe {
            instance.create_vulkan_device(
                system,
                gipa_xr,
                physical,
                (&dci as *const vk::DeviceCreateInfo).cast(),
            )
        }
        .expect("xrCreateVulkanDeviceKHR")
        .expect("vkCreateDevice");
        Rig {
            instance,
            system,
            ash_instance,
            vk_instance,
            physical,
            vk_device,
            family,
            _vk_entry: vk_entry,
        }
    }

    /// A Vulkan session on the rig's device.
    pub fn session(
        &self,
    ) -> xr::Result<(
        xr::Session<xr::Vulkan>,
        xr::FrameWaiter,
        xr::FrameStream<xr::Vulkan>,
    )> {
        // SAFETY: the Vulkan handles were made through this runtime and outlive the session.
        unsafe {
            self.instance.create_session::<xr::Vulkan>(
                self.system,
                &xr::vulkan::SessionCreateInfo {
                    instance: self.vk_instance,
                    physical_device: self.physical,
                    device: self.vk_device,
                    queue_family_index: self.family,
                    queue_index: 0,
                },
            )
        }
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        // SAFETY: every session on the device is gone (the tests drop them first); children
        // before parents.
        unsafe {
            let device = ash::Device::load(
                self.ash_instance.fp_v1_0(),
                vk::Device::from_raw(self.vk_device as u64),
            );
            device.destroy_device(None);
            self.ash_instance.destroy_instance(None);
        }
    }
}

/// Carries out what the app's state machine asks of the session itself (begin, end); returns
/// what is left for the caller (exit, recreate).
pub fn obey(command: Option<Command>, session: &xr::Session<xr::Vulkan>) -> Option<Command> {
    match command {
        Some(Command::BeginSession) => {
            session
                .begin(xr::ViewConfigurationType::PRIMARY_STEREO)
                .expect("begin");
            None
        }
        Some(Command::EndSession) => {
            session.end().expect("end");
            None
        }
        other => other,
    }
}

/// One frame with no layers: wait, begin, `between` (the app's work), end.
pub fn frame(
    waiter: &mut xr::FrameWaiter,
    stream: &mut xr::FrameStream<xr::Vulkan>,
    between: impl FnOnce(&xr::FrameState),
) -> xr::FrameState {
    let state = waiter.wait().expect("wait");
    stream.begin().expect("begin frame");
    between(&state);
    stream
        .end(
            state.predicted_display_time,
            xr::EnvironmentBlendMode::OPAQUE,
            &[],
        )
        .expect("end frame");
    state
}
