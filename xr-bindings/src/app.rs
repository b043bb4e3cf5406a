//! The application's side of OpenXR: the instance through the Khronos loader, the Vulkan
//! instance and device made through the runtime (XR_KHR_vulkan_enable2) and wrapped into wgpu
//! (wgpu-hal `from_raw` / `device_from_raw`, then `create_device_from_hal`), the actions from
//! the interaction profiles, and a session with a stage space, an aim-pose space per hand and
//! a two-layer swapchain whose images are wgpu textures.
//!
//! Threading follows the openxr crate's split: [`xr::FrameWaiter`] (xrWaitFrame) may move to
//! another thread, [`xr::FrameStream`] (xrBeginFrame / xrEndFrame) and [`XrSession`] (images,
//! actions) stay with the renderer; neither can be used from two threads at once.

use crate::profiles::{self, Action, Hand};
use ash::vk;
use ash::vk::Handle as _;
use openxr as xr;
use wgpu::hal::api::Vulkan as HalVulkan;

#[derive(Debug, thiserror::Error)]
pub enum XrError {
    #[error(
        "the OpenXR loader could not be loaded: {0} (apt-get install libopenxr-loader1; then start SteamVR or Monado, or use --xr-sim)"
    )]
    Loader(String),
    #[error(
        "no OpenXR runtime answered: {0} (start SteamVR or Monado, or point XR_RUNTIME_JSON at a runtime manifest; `vesalius xr-sim manifest` writes the simulated one's)"
    )]
    NoRuntime(String),
    #[error("the OpenXR runtime lacks {0}, which Vesalius needs")]
    MissingExtension(&'static str),
    #[error("no headset is connected ({0})")]
    NoHeadset(String),
    #[error("Vulkan: {0}")]
    Vulkan(String),
    #[error("{call} failed: {result}")]
    Call {
        call: &'static str,
        result: xr::sys::Result,
    },
    #[error("interaction profiles: {0}")]
    Profiles(String),
}

/// Turns an OpenXR call's error into [`XrError::Call`].
fn call<T>(name: &'static str, r: xr::Result<T>) -> Result<T, XrError> {
    r.map_err(|result| XrError::Call { call: name, result })
}

/// The wgpu device that lives on the runtime's Vulkan device.
pub struct XrGpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// The device draws both eyes in one pass.
    pub multiview: bool,
}

/// The app's actions, each on both hands (subaction paths `/user/hand/left` and `.../right`).
pub struct Controls {
    pub set: xr::ActionSet,
    pub aim: xr::Action<xr::Posef>,
    pub grip: xr::Action<xr::Posef>,
    pub trigger: xr::Action<f32>,
    pub squeeze: xr::Action<bool>,
    pub click: xr::Action<bool>,
    pub menu: xr::Action<bool>,
    pub trackpad: xr::Action<xr::Vector2f>,
    pub haptic: xr::Action<xr::Haptic>,
    /// `/user/hand/left`, `/user/hand/right`.
    pub hands: [xr::Path; 2],
}

struct VulkanHandles {
    instance: u64,
    physical: u64,
    device: u64,
    family: u32,
}

/// An OpenXR instance with its headset, Vulkan device and actions.
pub struct XrApp {
    pub controls: Controls,
    pub instance: xr::Instance,
    pub system: xr::SystemId,
    /// The runtime's name as it reports it ("SteamVR/OpenXR", "Monado", ...).
    pub runtime_name: String,
    /// Recommended per-eye image size, pixels.
    pub eye_size: (u32, u32),
    vk: VulkanHandles,
}

/// Vulkan API version the app asks for at most (and at least 1.1, for multiview).
const VK_API: u32 = vk::make_api_version(0, 1, 3, 0);

impl XrApp {
    /// Loads the OpenXR loader, makes an instance on the active runtime, finds the headset,
    /// makes the Vulkan instance and device through the runtime, and wraps them into wgpu.
    pub fn open(app_name: &str) -> Result<(XrApp, XrGpu), XrError> {
        // SAFETY: libopenxr_loader.so.1 is the Khronos loader, which honours its C interface.
        let entry = unsafe { xr::Entry::load(&()) }.map_err(|e| XrError::Loader(e.to_string()))?;
        let available = entry
            .enumerate_extensions()
            .map_err(|e| XrError::NoRuntime(e.to_string()))?;
        if !available.khr_vulkan_enable2 {
            return Err(XrError::MissingExtension("XR_KHR_vulkan_enable2"));
        }
        let mut exts = xr::ExtensionSet::default();
        exts.khr_vulkan_enable2 = true;
        let instance = entry
            .create_instance(
                &xr::ApplicationInfo {
                    application_name: app_name,
                    application_version: 1,
                    engine_name: "vesalius",
                    engine_version: 1,
                    api_version: xr::Version::new(1, 0, 0),
                },
                &exts,
                &[],
                &(),
            )
            .map_err(|e| XrError::NoRuntime(e.to_string()))?;
        let runtime_name = call("xrGetInstanceProperties", instance.properties())?.runtime_name;
        let system = instance
            .system(xr::FormFactor::HEAD_MOUNTED_DISPLAY)
            .map_err(|e| XrError::NoHeadset(e.to_string()))?;
        let views = call(
            "xrEnumerateViewConfigurationViews",
            instance.enumerate_view_configuration_views(
                system,
                xr::ViewConfigurationType::PRIMARY_STEREO,
            ),
        )?;
        let eye_size = views.first().map_or((1080, 1200), |v| {
            (
                v.recommended_image_rect_width,
                v.recommended_image_rect_height,
            )
        });
        let (gpu, vk) = vulkan(&instance, system)?;
        let controls = controls(&instance)?;
        Ok((
            XrApp {
                controls,
                instance,
                system,
                runtime_name,
                eye_size,
                vk,
            },
            gpu,
        ))
    }

    /// Starts a session on the app's device with its spaces and a swapchain of `eye_size`
    /// pixels per eye, two array layers (left, right), in `format` (an sRGB RGBA format).
    pub fn session(
        &self,
        device: &wgpu::Device,
        eye_size: (u32, u32),
    ) -> Result<(XrSession, xr::FrameWaiter, xr::FrameStream<xr::Vulkan>), XrError> {
        // SAFETY: the Vulkan handles were made through this runtime and live as long as the
        // wgpu device, which the caller keeps beyond the session.
        let (session, waiter, stream) = call("xrCreateSession", unsafe {
            self.instance.create_session::<xr::Vulkan>(
                self.system,
                &xr::vulkan::SessionCreateInfo {
                    instance: self.vk.instance as _,
                    physical_device: self.vk.physical as _,
                    device: self.vk.device as _,
                    queue_family_index: self.vk.family,
                    queue_index: 0,
                },
            )
        })?;
        let c = &self.controls;
        call(
            "xrAttachSessionActionSets",
            session.attach_action_sets(&[&c.set]),
        )?;
        let stage = call(
            "xrCreateReferenceSpace",
            session.create_reference_space(xr::ReferenceSpaceType::STAGE, xr::Posef::IDENTITY),
        )?;
        let aim = [0, 1].map(|h| {
            call(
                "xrCreateActionSpace",
                c.aim
                    .create_space(&session, c.hands[h], xr::Posef::IDENTITY),
            )
        });
        let [left, right] = aim;
        let (left, right) = (left?, right?);
        let formats = call(
            "xrEnumerateSwapchainFormats",
            session.enumerate_swapchain_formats(),
        )?;
        let want = vk::Format::R8G8B8A8_SRGB.as_raw() as u32;
        if !formats.contains(&want) {
            return Err(XrError::Vulkan(format!(
                "the runtime offers no R8G8B8A8_SRGB swapchain (it offers {formats:?})"
            )));
        }
        let swapchain = call(
            "xrCreateSwapchain",
            session.create_swapchain(&xr::SwapchainCreateInfo {
                create_flags: xr::SwapchainCreateFlags::EMPTY,
                usage_flags: xr::SwapchainUsageFlags::COLOR_ATTACHMENT
                    | xr::SwapchainUsageFlags::SAMPLED
                    | xr::SwapchainUsageFlags::TRANSFER_SRC,
                format: want,
                sample_count: 1,
                width: eye_size.0,
                height: eye_size.1,
                face_count: 1,
                array_size: 2,
                mip_count: 1,
            }),
        )?;
        let images = call("xrEnumerateSwapchainImages", swapchain.enumerate_images())?;
        let textures = images
            .into_iter()
            .map(|raw| wrap_image(device, raw, eye_size))
            .collect();
        Ok((
            XrSession {
                swapchain,
                textures,
                aim: [left, right],
                stage,
                session,
                eye_size,
            },
            waiter,
            stream,
        ))
    }

    /// Reads the next event, if any.
    pub fn poll<'a>(
        &self,
        buffer: &'a mut xr::EventDataBuffer,
    ) -> Result<Option<xr::Event<'a>>, XrError> {
        call("xrPollEvent", self.instance.poll_event(buffer))
    }

    /// Whether the headset is there now (after a loss it comes back some time later).
    pub fn headset_present(&self) -> bool {
        self.instance
            .system(xr::FormFactor::HEAD_MOUNTED_DISPLAY)
            .is_ok()
    }
}

/// Makes the Vulkan instance and device through the runtime and wraps them into wgpu.
fn vulkan(
    instance: &xr::Instance,
    system: xr::SystemId,
) -> Result<(XrGpu, VulkanHandles), XrError> {
    let req = call(
        "xrGetVulkanGraphicsRequirements2KHR",
        instance.graphics_requirements::<xr::Vulkan>(system),
    )?;
    if req.min_api_version_supported > xr::Version::new(1, 1, 0) {
        return Err(XrError::Vulkan(format!(
            "the runtime needs Vulkan {} or later; Vesalius asks for 1.1",
            req.min_api_version_supported
        )));
    }
    let verr = |what: &str, e: &dyn std::fmt::Display| XrError::Vulkan(format!("{what}: {e}"));
    // The newest version both sides allow, up to 1.3.
    let max = req.max_api_version_supported;
    let api = if max >= xr::Version::new(1, 3, 0) {
        VK_API
    } else {
        vk::make_api_version(0, 1, u32::from(max.minor()).max(1), 0)
    };
    // SAFETY: libvulkan.so.1 is the Khronos Vulkan loader.
    let entry = unsafe { ash::Entry::load() }
        .map_err(|e| verr("libvulkan.so.1 (apt-get install libvulkan1)", &e))?;
    let flags = wgpu::InstanceFlags::empty();
    let extensions = wgpu::hal::vulkan::Instance::desired_extensions(&entry, api, flags)
        .map_err(|e| verr("instance extensions", &e))?;
    let ext_ptrs: Vec<*const std::ffi::c_char> = extensions.iter().map(|e| e.as_ptr()).collect();
    let app = vk::ApplicationInfo::default()
        .application_name(c"vesalius")
        .engine_name(c"vesalius")
        .api_version(api);
    let ci = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_extension_names(&ext_ptrs);
    let gipa = entry.static_fn().get_instance_proc_addr;
    // SAFETY: both are vkGetInstanceProcAddr's signature (handles as pointer-sized values).
    let gipa_xr = unsafe {
        std::mem::transmute::<vk::PFN_vkGetInstanceProcAddr, xr::sys::platform::VkGetInstanceProcAddr>(
            gipa,
        )
    };
    // SAFETY: a valid create info, read during the call.
    let raw_instance = call("xrCreateVulkanInstanceKHR", unsafe {
        instance.create_vulkan_instance(
            system,
            gipa_xr,
            (&ci as *const vk::InstanceCreateInfo).cast(),
        )
    })?
    .map_err(|e| verr("vkCreateInstance", &vk::Result::from_raw(e)))?;
    let vk_instance = vk::Instance::from_raw(raw_instance as u64);
    // SAFETY: the instance was just made by this entry's loader.
    let ash_instance = unsafe { ash::Instance::load(entry.static_fn(), vk_instance) };
    // SAFETY: a live instance made through the runtime.
    let physical = call("xrGetVulkanGraphicsDevice2KHR", unsafe {
        instance.vulkan_graphics_device(system, raw_instance)
    })?;
    let pd = vk::PhysicalDevice::from_raw(physical as u64);
    // SAFETY: the instance and its extensions are the ones `desired_extensions` chose; wgpu-hal
    // owns the instance from here (no drop callback) and destroys it when wgpu drops it.
    let hal_instance = unsafe {
        wgpu::hal::vulkan::Instance::from_raw(
            entry,
            ash_instance.clone(),
            api,
            0,
            None,
            extensions,
            flags,
            wgpu::MemoryBudgetThresholds::default(),
            false,
            None,
        )
    }
    .map_err(|e| verr("wgpu instance", &e))?;
    let exposed = hal_instance
        .expose_adapter(pd)
        .ok_or_else(|| XrError::Vulkan("wgpu cannot use the runtime's GPU".into()))?;
    let multiview = exposed.features.contains(wgpu::Features::MULTIVIEW);
    let features = if multiview {
        wgpu::Features::MULTIVIEW
    } else {
        wgpu::Features::empty()
    };
    let mut limits = wgpu::Limits::default().using_resolution(exposed.capabilities.limits.clone());
    if multiview {
        limits.max_multiview_view_count = 2;
    }
    let dev_exts = exposed.adapter.required_device_extensions(features);
    let mut pd_features = exposed
        .adapter
        .physical_device_features(&dev_exts, features);
    // SAFETY: `pd` belongs to the live instance.
    let families = unsafe { ash_instance.get_physical_device_queue_family_properties(pd) };
    let family = families
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
        .ok_or_else(|| XrError::Vulkan("the GPU has no graphics queue".into()))?
        as u32;
    let priority = [1.0f32];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(family)
        .queue_priorities(&priority)];
    let dev_ptrs: Vec<*const std::ffi::c_char> = dev_exts.iter().map(|e| e.as_ptr()).collect();
    let dci = pd_features.add_to_device_create(
        vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&dev_ptrs),
    );
    // SAFETY: a valid device create info for the runtime's physical device.
    let raw_device = call("xrCreateVulkanDeviceKHR", unsafe {
        instance.create_vulkan_device(
            system,
            gipa_xr,
            physical,
            (&dci as *const vk::DeviceCreateInfo).cast(),
        )
    })?
    .map_err(|e| verr("vkCreateDevice", &vk::Result::from_raw(e)))?;
    // SAFETY: the device was just made on this instance.
    let ash_device = unsafe {
        ash::Device::load(
            ash_instance.fp_v1_0(),
            vk::Device::from_raw(raw_device as u64),
        )
    };
    // SAFETY: the device was made from this adapter with `dev_exts` and `pd_features`, on
    // `family`; wgpu-hal owns it from here.
    let open = unsafe {
        exposed.adapter.device_from_raw(
            ash_device,
            None,
            &dev_exts,
            features,
            &limits,
            &wgpu::MemoryHints::Performance,
            family,
            0,
        )
    }
    .map_err(|e| verr("wgpu device", &e))?;
    // SAFETY: the hal objects come from this instance and are handed over whole.
    let wgpu_instance = unsafe { wgpu::Instance::from_hal::<HalVulkan>(hal_instance) };
    // SAFETY: as above.
    let adapter = unsafe { wgpu_instance.create_adapter_from_hal(exposed) };
    // SAFETY: `open` was made from this adapter with these features and limits.
    let (device, queue) = unsafe {
        adapter.create_device_from_hal(
            open,
            &wgpu::DeviceDescriptor {
                label: Some("vesalius-xr"),
                required_features: features,
                required_limits: limits,
                ..Default::default()
            },
        )
    }
    .map_err(|e| verr("wgpu device", &e))?;
    Ok((
        XrGpu {
            instance: wgpu_instance,
            adapter,
            device,
            queue,
            multiview,
        },
        VulkanHandles {
            instance: raw_instance as u64,
            physical: physical as u64,
            device: raw_device as u64,
            family,
        },
    ))
}

/// The colour format of the eye images.
pub const EYE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// A swapchain image as a two-layer wgpu texture (the runtime keeps ownership).
fn wrap_image(device: &wgpu::Device, raw: u64, size: (u32, u32)) -> wgpu::Texture {
    let desc = wgpu::TextureDescriptor {
        label: Some("xr swapchain image"),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: 2,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: EYE_FORMAT,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    };
    // The same texture as wgpu-hal describes it (its usage in hal terms).
    let hal_desc = wgpu::hal::TextureDescriptor {
        label: desc.label,
        size: desc.size,
        mip_level_count: desc.mip_level_count,
        sample_count: desc.sample_count,
        dimension: desc.dimension,
        format: desc.format,
        usage: wgpu::TextureUses::COLOR_TARGET
            | wgpu::TextureUses::RESOURCE
            | wgpu::TextureUses::COPY_SRC,
        memory_flags: wgpu::hal::MemoryFlags::empty(),
        view_formats: Vec::new(),
    };
    // SAFETY: the image was made by the runtime on this device with this size, format, two
    // layers and colour-attachment + sampled + transfer-source usage; the no-op drop callback leaves it to the
    // runtime, which outlives the texture (the session is dropped after the textures).
    let hal_texture = unsafe {
        device.as_hal::<HalVulkan>().map(|d| {
            d.texture_from_raw(
                vk::Image::from_raw(raw),
                &hal_desc,
                Some(Box::new(|| {})),
                wgpu::hal::vulkan::TextureMemory::External,
            )
        })
    };
    match hal_texture {
        // SAFETY: the hal texture was made on this device with `desc`'s properties.
        // The runtime hands images over ready to render to (colour-attachment layout).
        Some(t) => unsafe {
            device.create_texture_from_hal::<HalVulkan>(t, &desc, wgpu::TextureUses::COLOR_TARGET)
        },
        // Not a Vulkan device (cannot happen: the device was made from Vulkan handles).
        None => device.create_texture(&desc),
    }
}

/// Makes the action set and suggests every shipped profile's bindings.
fn controls(instance: &xr::Instance) -> Result<Controls, XrError> {
    let set = call(
        "xrCreateActionSet",
        instance.create_action_set("surgery", "Surgery", 0),
    )?;
    let hands = [
        call("xrStringToPath", instance.string_to_path(Hand::Left.path()))?,
        call(
            "xrStringToPath",
            instance.string_to_path(Hand::Right.path()),
        )?,
    ];
    fn make<T: xr::ActionTy>(
        set: &xr::ActionSet,
        a: Action,
        label: &str,
        hands: &[xr::Path; 2],
    ) -> Result<xr::Action<T>, XrError> {
        call(
            "xrCreateAction",
            set.create_action::<T>(a.name(), label, hands),
        )
    }
    let c = Controls {
        aim: make(&set, Action::AimPose, "Instrument direction", &hands)?,
        grip: make(&set, Action::GripPose, "Instrument handle", &hands)?,
        trigger: make(&set, Action::Trigger, "Cut / close jaws", &hands)?,
        squeeze: make(&set, Action::Squeeze, "Clutch", &hands)?,
        click: make(&set, Action::TrackpadClick, "Mark", &hands)?,
        menu: make(&set, Action::Menu, "Menu", &hands)?,
        trackpad: make(&set, Action::Trackpad, "Trackpad", &hands)?,
        haptic: make(&set, Action::Haptic, "Vibration", &hands)?,
        set,
        hands,
    };
    let profiles = profiles::builtin().map_err(|e| XrError::Profiles(e.to_string()))?;
    for p in &profiles {
        let mut paths = Vec::new();
        for b in &p.bindings {
            paths.push((
                b.action,
                call("xrStringToPath", instance.string_to_path(&b.path))?,
            ));
        }
        let bindings: Vec<xr::Binding> = paths
            .iter()
            .map(|&(a, path)| match a {
                Action::AimPose => xr::Binding::new(&c.aim, path),
                Action::GripPose => xr::Binding::new(&c.grip, path),
                Action::Trigger => xr::Binding::new(&c.trigger, path),
                Action::Squeeze => xr::Binding::new(&c.squeeze, path),
                Action::TrackpadClick => xr::Binding::new(&c.click, path),
                Action::Menu => xr::Binding::new(&c.menu, path),
                Action::Trackpad => xr::Binding::new(&c.trackpad, path),
                Action::Haptic => xr::Binding::new(&c.haptic, path),
            })
            .collect();
        let profile = call("xrStringToPath", instance.string_to_path(&p.path))?;
        // A runtime that does not know a profile refuses it; the others still count.
        if let Err(e) = instance.suggest_interaction_profile_bindings(profile, &bindings)
            && e != xr::sys::Result::ERROR_PATH_UNSUPPORTED
        {
            return Err(XrError::Call {
                call: "xrSuggestInteractionProfileBindings",
                result: e,
            });
        }
    }
    Ok(c)
}

/// One hand's controller as read at a frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HandReading {
    /// The aim pose in STAGE (position metres, orientation x y z w), when tracked.
    pub aim: Option<([f32; 3], [f32; 4])>,
    pub trigger: f32,
    pub squeeze: bool,
    pub click: bool,
    /// The thumb on the trackpad (or the thumbstick), x right and y up, -1 to 1.
    pub pad: [f32; 2],
    /// Some binding of the hand is active (the controller is there).
    pub active: bool,
}

/// A running session's objects. Drop it before the [`XrGpu`] it renders with.
pub struct XrSession {
    swapchain: xr::Swapchain<xr::Vulkan>,
    /// The swapchain's images as wgpu textures (two layers: left eye, right eye).
    pub textures: Vec<wgpu::Texture>,
    aim: [xr::Space; 2],
    pub stage: xr::Space,
    pub session: xr::Session<xr::Vulkan>,
    pub eye_size: (u32, u32),
}

impl XrSession {
    /// Syncs the actions and reads both hands at `time`. When the session is not focused the
    /// runtime gives no input: every hand reads inactive.
    pub fn read_hands(&self, c: &Controls, time: xr::Time) -> Result<[HandReading; 2], XrError> {
        call(
            "xrSyncActions",
            self.session
                .sync_actions(&[xr::ActiveActionSet::new(&c.set)]),
        )?;
        let mut out = [HandReading::default(); 2];
        for (h, r) in out.iter_mut().enumerate() {
            let path = c.hands[h];
            let trigger = call(
                "xrGetActionStateFloat",
                c.trigger.state(&self.session, path),
            )?;
            let squeeze = call(
                "xrGetActionStateBoolean",
                c.squeeze.state(&self.session, path),
            )?;
            let click = call(
                "xrGetActionStateBoolean",
                c.click.state(&self.session, path),
            )?;
            let pad = call(
                "xrGetActionStateVector2f",
                c.trackpad.state(&self.session, path),
            )?;
            let pose_active = call("xrGetActionStatePose", c.aim.is_active(&self.session, path))?;
            r.trigger = trigger.current_state;
            r.squeeze = squeeze.current_state;
            r.click = click.current_state;
            r.pad = [pad.current_state.x, pad.current_state.y];
            r.active = pose_active || trigger.is_active;
            let loc = call("xrLocateSpace", self.aim[h].locate(&self.stage, time))?;
            let f = loc.location_flags;
            if pose_active
                && f.contains(xr::SpaceLocationFlags::POSITION_VALID)
                && f.contains(xr::SpaceLocationFlags::ORIENTATION_VALID)
            {
                let (p, q) = (loc.pose.position, loc.pose.orientation);
                r.aim = Some(([p.x, p.y, p.z], [q.x, q.y, q.z, q.w]));
            }
        }
        Ok(out)
    }

    /// The two eyes' poses (in STAGE) and fields of view at `time`.
    pub fn views(&self, time: xr::Time) -> Result<Vec<xr::View>, XrError> {
        let (_, views) = call(
            "xrLocateViews",
            self.session
                .locate_views(xr::ViewConfigurationType::PRIMARY_STEREO, time, &self.stage),
        )?;
        Ok(views)
    }

    /// Acquires the next image, lets `draw` render into it (and submit), and releases it.
    pub fn draw(&mut self, draw: impl FnOnce(&wgpu::Texture)) -> Result<(), XrError> {
        let k = call("xrAcquireSwapchainImage", self.swapchain.acquire_image())? as usize;
        call(
            "xrWaitSwapchainImage",
            self.swapchain.wait_image(xr::Duration::INFINITE),
        )?;
        if let Some(t) = self.textures.get(k) {
            draw(t);
        }
        call("xrReleaseSwapchainImage", self.swapchain.release_image())
    }

    /// Ends the frame showing the last drawn image, layer 0 to the left eye, 1 to the right.
    pub fn end_frame(
        &self,
        stream: &mut xr::FrameStream<xr::Vulkan>,
        time: xr::Time,
        views: &[xr::View],
    ) -> Result<(), XrError> {
        let rect = xr::Rect2Di {
            offset: xr::Offset2Di { x: 0, y: 0 },
            extent: xr::Extent2Di {
                width: self.eye_size.0 as i32,
                height: self.eye_size.1 as i32,
            },
        };
        let projected: Vec<xr::CompositionLayerProjectionView<xr::Vulkan>> = views
            .iter()
            .take(2)
            .enumerate()
            .map(|(i, v)| {
                xr::CompositionLayerProjectionView::new()
                    .pose(v.pose)
                    .fov(v.fov)
                    .sub_image(
                        xr::SwapchainSubImage::new()
                            .swapchain(&self.swapchain)
                            .image_array_index(i as u32)
                            .image_rect(rect),
                    )
            })
            .collect();
        let layer = xr::CompositionLayerProjection::new()
            .space(&self.stage)
            .views(&projected);
        call(
            "xrEndFrame",
            stream.end(time, xr::EnvironmentBlendMode::OPAQUE, &[&layer]),
        )
    }

    /// Vibrates a hand's controller.
    pub fn vibrate(
        &self,
        c: &Controls,
        hand: usize,
        amplitude: f32,
        frequency_hz: f32,
        duration_s: f64,
    ) -> Result<(), XrError> {
        let v = xr::HapticVibration::new()
            .amplitude(amplitude.clamp(0.0, 1.0))
            .frequency(frequency_hz.max(0.0))
            .duration(xr::Duration::from_nanos((duration_s * 1e9).max(1.0) as i64));
        let r = c.haptic.apply_feedback(&self.session, c.hands[hand], &v);
        call("xrApplyHapticFeedback", r)
    }

    /// Stops a hand's vibration.
    pub fn stop_vibration(&self, c: &Controls, hand: usize) -> Result<(), XrError> {
        call(
            "xrStopHapticFeedback",
            c.haptic.stop_feedback(&self.session, c.hands[hand]),
        )
    }
}
