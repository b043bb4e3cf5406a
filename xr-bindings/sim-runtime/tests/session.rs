//! A Vulkan session through the Khronos loader: the app's Vulkan instance and device are made
//! through the simulated runtime (XR_KHR_vulkan_enable2, on whatever Vulkan driver is
//! installed: lavapipe in CI), and the session walks IDLE -> READY -> SYNCHRONIZED -> VISIBLE
//! -> FOCUSED -> ... -> STOPPING -> IDLE -> EXITING under the app's state machine.

use ash::vk;
use ash::vk::Handle;
use openxr as xr;
use xr_bindings::{Command, SessionMachine};

fn runtime_library() -> std::path::PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let deps = exe.parent().expect("target/<profile>/deps");
    let name = "libvesalius_sim_runtime.so";
    [deps.join(name), deps.join("..").join(name)]
        .into_iter()
        .find(|p| p.exists())
        .unwrap_or_else(|| panic!("{name} was not built"))
}

#[test]
fn a_vulkan_session_walks_the_whole_life_cycle() {
    let dir = std::env::temp_dir().join(format!("vesalius-xr-session-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let manifest = dir.join("runtime.json");
    std::fs::write(
        &manifest,
        vesalius_sim_runtime::manifest(&runtime_library().display().to_string()),
    )
    .expect("manifest");
    // SAFETY: the only test in this binary; the variable is set before the loader reads it.
    unsafe { std::env::set_var("XR_RUNTIME_JSON", &manifest) };
    // SAFETY: Debian's loader conforms to the OpenXR specification.
    let entry = unsafe { xr::Entry::load(&()) }.expect("libopenxr_loader.so.1");
    let available = entry.enumerate_extensions().expect("extensions");
    assert!(available.khr_vulkan_enable2);
    let mut exts = xr::ExtensionSet::default();
    exts.khr_vulkan_enable2 = true;
    let instance = entry
        .create_instance(
            &xr::ApplicationInfo {
                application_name: "vesalius-test",
                application_version: 1,
                engine_name: "vesalius",
                engine_version: 1,
                api_version: xr::Version::new(1, 0, 0),
            },
            &exts,
            &[],
            &(),
        )
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
    // SAFETY: vkGetInstanceProcAddr has the same signature in ash and in openxr-sys (handles
    // as pointer-sized values, a C string, an optional function pointer back).
    let gipa_xr = unsafe {
        std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, xr::sys::platform::VkGetInstanceProcAddr>(
            gipa,
        )
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
    let physical = unsafe { instance.vulkan_graphics_device(system, vk_instance) }.expect("device");
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

    // SAFETY: the Vulkan handles were made through this runtime and outlive the session.
    let (session, mut waiter, mut stream) = unsafe {
        instance.create_session::<xr::Vulkan>(
            system,
            &xr::vulkan::SessionCreateInfo {
                instance: vk_instance,
                physical_device: physical,
                device: vk_device,
                queue_family_index: family,
                queue_index: 0,
            },
        )
    }
    .expect("session");
    let stage = session
        .create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY)
        .expect("stage space");

    let mut machine = SessionMachine::new();
    let mut buf = xr::EventDataBuffer::new();
    let mut asked_to_exit = false;
    let mut times = Vec::new();
    let mut rendered = 0;
    'run: for _ in 0..1000 {
        while let Some(event) = instance.poll_event(&mut buf).expect("poll") {
            let xr::Event::SessionStateChanged(e) = event else {
                continue;
            };
            match machine.on_state(e.state()) {
                Some(Command::BeginSession) => {
                    session
                        .begin(xr::ViewConfigurationType::PRIMARY_STEREO)
                        .expect("begin");
                }
                Some(Command::EndSession) => {
                    session.end().expect("end");
                }
                Some(Command::Exit) => break 'run,
                Some(Command::Recreate) => panic!("no loss was injected"),
                None => {}
            }
        }
        if machine.submits_frames() {
            let frame = waiter.wait().expect("wait");
            stream.begin().expect("begin frame");
            times.push(frame.predicted_display_time.as_nanos());
            if frame.should_render {
                rendered += 1;
                let (_, views) = session
                    .locate_views(
                        xr::ViewConfigurationType::PRIMARY_STEREO,
                        frame.predicted_display_time,
                        &stage,
                    )
                    .expect("views");
                assert_eq!(views.len(), 2);
                let (l, r) = (views[0].pose.position, views[1].pose.position);
                assert!(((r.x - l.x) - 0.063).abs() < 1e-6, "IPD {}", r.x - l.x);
                assert!((l.y - 1.6).abs() < 1e-6 && (r.y - 1.6).abs() < 1e-6);
                assert_eq!(views[0].fov.angle_left, -views[1].fov.angle_right);
            }
            stream
                .end(
                    frame.predicted_display_time,
                    xr::EnvironmentBlendMode::OPAQUE,
                    &[],
                )
                .expect("end frame");
        }
        if machine.focused() && rendered >= 120 && !asked_to_exit {
            // The trainee is done: ask the runtime to wind the session down.
            session.request_exit().expect("request exit");
            asked_to_exit = true;
        }
    }
    // A 90 Hz display: every predicted time one period after the last.
    assert!(times.len() > 120, "{} frames", times.len());
    assert!(
        times.windows(2).all(|w| w[1] - w[0] == 1_000_000_000 / 90),
        "display times step by 11.1 ms"
    );
    use xr::SessionState as S;
    assert_eq!(
        machine.history,
        [
            S::IDLE,
            S::READY,
            S::SYNCHRONIZED,
            S::VISIBLE,
            S::FOCUSED,
            S::VISIBLE,
            S::SYNCHRONIZED,
            S::STOPPING,
            S::IDLE,
            S::EXITING
        ]
    );
    assert!(machine.unexpected.is_empty(), "{:?}", machine.unexpected);
    // Ending twice is refused with the OpenXR error, not a crash.
    assert_eq!(
        session.end(),
        Err(xr::sys::Result::ERROR_SESSION_NOT_RUNNING)
    );
    drop(stage);
    drop(session);
    drop(waiter);
    drop(stream);
    // SAFETY: nothing uses the device or instance any more; children first.
    unsafe {
        let device = ash::Device::load(
            ash_instance.fp_v1_0(),
            vk::Device::from_raw(vk_device as u64),
        );
        device.destroy_device(None);
        ash_instance.destroy_instance(None);
    }
}
