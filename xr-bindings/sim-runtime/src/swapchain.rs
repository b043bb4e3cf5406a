//! Swapchains whose images live on the app's Vulkan device (made with the app's own driver
//! through the `vkGetInstanceProcAddr` it gave `xrCreateVulkanInstanceKHR`), and the frame
//! dumps: at every Nth `xrEndFrame` the runtime copies each projection view's sub-image back
//! on the session's queue and writes it as `frames/NNNN_left.png` / `NNNN_right.png`.

use super::session::{live, result, with_session};
use super::{Runtime, arg, arg_mut, sys, two_call};
use ash::vk;
use ash::vk::Handle as _;
use std::path::Path;
use sys::Handle as _;

/// Colour formats offered, preferred first (sRGB: the app writes display-ready colour), then
/// a depth format.
pub(crate) const FORMATS: [vk::Format; 5] = [
    vk::Format::R8G8B8A8_SRGB,
    vk::Format::B8G8R8A8_SRGB,
    vk::Format::R8G8B8A8_UNORM,
    vk::Format::B8G8R8A8_UNORM,
    vk::Format::D32_SFLOAT,
];
/// Images per swapchain.
const IMAGES: usize = 3;
const TAG: u64 = 4 << 32;

/// The app's Vulkan device as the session binding gave it, with the functions the runtime
/// calls on it.
pub(crate) struct Device {
    instance: ash::Instance,
    device: ash::Device,
    physical: vk::PhysicalDevice,
    queue: vk::Queue,
    family: u32,
}

impl Device {
    /// Loads the device's functions through the app's `vkGetInstanceProcAddr`.
    ///
    /// # Safety
    /// The handles must be live and made from that function's instance.
    pub(crate) unsafe fn load(
        gipa: sys::platform::VkGetInstanceProcAddr,
        binding: &sys::GraphicsBindingVulkanKHR,
    ) -> Device {
        // SAFETY: both are `vkGetInstanceProcAddr`'s signature (handles as pointer-sized
        // values, a C string in, an optional function pointer out).
        let gipa = unsafe {
            std::mem::transmute::<sys::platform::VkGetInstanceProcAddr, vk::PFN_vkGetInstanceProcAddr>(
                gipa,
            )
        };
        let static_fn = ash::StaticFn {
            get_instance_proc_addr: gipa,
        };
        let raw_instance = vk::Instance::from_raw(binding.instance as u64);
        // SAFETY: a live instance made through this loader entry (caller's contract).
        let instance = unsafe { ash::Instance::load(&static_fn, raw_instance) };
        let raw_device = vk::Device::from_raw(binding.device as u64);
        // SAFETY: a live device of that instance (caller's contract).
        let device = unsafe { ash::Device::load(instance.fp_v1_0(), raw_device) };
        // SAFETY: the binding names a queue the app created on this device.
        let queue =
            unsafe { device.get_device_queue(binding.queue_family_index, binding.queue_index) };
        Device {
            instance,
            device,
            physical: vk::PhysicalDevice::from_raw(binding.physical_device as u64),
            queue,
            family: binding.queue_family_index,
        }
    }

    fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> Option<u32> {
        // SAFETY: the physical device belongs to the live instance.
        let props = unsafe {
            self.instance
                .get_physical_device_memory_properties(self.physical)
        };
        (0..props.memory_type_count).find(|&i| {
            bits & (1 << i) != 0
                && props.memory_types[i as usize]
                    .property_flags
                    .contains(flags)
        })
    }

    /// Records commands, submits them on the session's queue (after everything the app has
    /// submitted there) and waits for them.
    fn run(&self, record: impl FnOnce(vk::CommandBuffer)) -> Result<(), vk::Result> {
        let d = &self.device;
        // SAFETY: all objects are created and destroyed here, on the live device; the queue is
        // externally synchronized by the app during the OpenXR call that runs this.
        unsafe {
            let pool = d.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(self.family)
                    .flags(vk::CommandPoolCreateFlags::TRANSIENT),
                None,
            )?;
            let done = (|| {
                let cb = d.allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .command_buffer_count(1),
                )?[0];
                d.begin_command_buffer(
                    cb,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )?;
                record(cb);
                d.end_command_buffer(cb)?;
                let fence = d.create_fence(&vk::FenceCreateInfo::default(), None)?;
                let cbs = [cb];
                let submitted = d
                    .queue_submit(
                        self.queue,
                        &[vk::SubmitInfo::default().command_buffers(&cbs)],
                        fence,
                    )
                    .and_then(|()| d.wait_for_fences(&[fence], true, u64::MAX));
                d.destroy_fence(fence, None);
                submitted
            })();
            d.destroy_command_pool(pool, None);
            done
        }
    }
}

struct Image {
    image: vk::Image,
    memory: vk::DeviceMemory,
}

pub(crate) struct Swapchain {
    format: vk::Format,
    size: (u32, u32),
    layers: u32,
    images: Vec<Image>,
    /// Acquired and not yet released, oldest first.
    acquired: std::collections::VecDeque<usize>,
    /// The image waited on (the one the app writes now).
    waited: Option<usize>,
    next: usize,
    /// The image released last: what the compositor would show.
    pub(crate) released: Option<usize>,
}

fn aspect(format: vk::Format) -> vk::ImageAspectFlags {
    if format == vk::Format::D32_SFLOAT {
        vk::ImageAspectFlags::DEPTH
    } else {
        vk::ImageAspectFlags::COLOR
    }
}

fn ready_layout(format: vk::Format) -> vk::ImageLayout {
    if format == vk::Format::D32_SFLOAT {
        vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL
    } else {
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL
    }
}

fn usage(flags: sys::SwapchainUsageFlags) -> vk::ImageUsageFlags {
    let pairs = [
        (
            sys::SwapchainUsageFlags::COLOR_ATTACHMENT,
            vk::ImageUsageFlags::COLOR_ATTACHMENT,
        ),
        (
            sys::SwapchainUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
        ),
        (
            sys::SwapchainUsageFlags::UNORDERED_ACCESS,
            vk::ImageUsageFlags::STORAGE,
        ),
        (
            sys::SwapchainUsageFlags::TRANSFER_SRC,
            vk::ImageUsageFlags::TRANSFER_SRC,
        ),
        (
            sys::SwapchainUsageFlags::TRANSFER_DST,
            vk::ImageUsageFlags::TRANSFER_DST,
        ),
        (
            sys::SwapchainUsageFlags::SAMPLED,
            vk::ImageUsageFlags::SAMPLED,
        ),
    ];
    // The runtime reads images back for the frame dumps.
    pairs
        .iter()
        .filter(|(x, _)| flags.contains(*x))
        .fold(vk::ImageUsageFlags::TRANSFER_SRC, |u, (_, v)| u | *v)
}

fn barrier(
    image: vk::Image,
    format: vk::Format,
    layer: u32,
    layers: u32,
    from: vk::ImageLayout,
    to: vk::ImageLayout,
) -> vk::ImageMemoryBarrier<'static> {
    vk::ImageMemoryBarrier::default()
        .image(image)
        .old_layout(from)
        .new_layout(to)
        .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
        .dst_access_mask(vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: aspect(format),
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: layer,
            layer_count: layers,
        })
}

impl Swapchain {
    fn create(dev: &Device, info: &sys::SwapchainCreateInfo) -> Result<Swapchain, sys::Result> {
        let format = vk::Format::from_raw(info.format as i32);
        let mut chain = Swapchain {
            format,
            size: (info.width, info.height),
            layers: info.array_size,
            images: Vec::new(),
            acquired: Default::default(),
            waited: None,
            next: 0,
            released: None,
        };
        let ci = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: info.width,
                height: info.height,
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(info.array_size)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage(info.usage_flags))
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let d = &dev.device;
        for _ in 0..IMAGES {
            // SAFETY: a valid create info on the app's live device; on failure what was made
            // so far is destroyed below.
            let made = unsafe {
                d.create_image(&ci, None).and_then(|image| {
                    let req = d.get_image_memory_requirements(image);
                    let Some(kind) = dev
                        .memory_type(req.memory_type_bits, vk::MemoryPropertyFlags::DEVICE_LOCAL)
                    else {
                        d.destroy_image(image, None);
                        return Err(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY);
                    };
                    let memory = d
                        .allocate_memory(
                            &vk::MemoryAllocateInfo::default()
                                .allocation_size(req.size)
                                .memory_type_index(kind),
                            None,
                        )
                        .inspect_err(|_| d.destroy_image(image, None))?;
                    d.bind_image_memory(image, memory, 0).inspect_err(|_| {
                        d.destroy_image(image, None);
                        d.free_memory(memory, None);
                    })?;
                    Ok(Image { image, memory })
                })
            };
            match made {
                Ok(img) => chain.images.push(img),
                Err(e) => {
                    eprintln!("vesalius-sim-runtime: swapchain image: {e}");
                    chain.destroy(dev);
                    return Err(sys::Result::ERROR_RUNTIME_FAILURE);
                }
            }
        }
        // Images start ready to render to, as the extension promises.
        let (fmt, layers) = (format, info.array_size);
        let barriers: Vec<_> = chain
            .images
            .iter()
            .map(|i| {
                barrier(
                    i.image,
                    fmt,
                    0,
                    layers,
                    vk::ImageLayout::UNDEFINED,
                    ready_layout(fmt),
                )
            })
            .collect();
        let ran = dev.run(|cb| {
            // SAFETY: a command buffer being recorded, on the device the images live on.
            unsafe {
                d.cmd_pipeline_barrier(
                    cb,
                    vk::PipelineStageFlags::TOP_OF_PIPE,
                    vk::PipelineStageFlags::ALL_COMMANDS,
                    vk::DependencyFlags::empty(),
                    &[],
                    &[],
                    &barriers,
                )
            }
        });
        if let Err(e) = ran {
            eprintln!("vesalius-sim-runtime: swapchain layout: {e}");
            chain.destroy(dev);
            return Err(sys::Result::ERROR_RUNTIME_FAILURE);
        }
        Ok(chain)
    }

    pub(crate) fn destroy(&mut self, dev: &Device) {
        // SAFETY: the app has finished with the images (it destroys the swapchain, or the
        // session, only when its work is done); the queue idles first to be sure.
        unsafe {
            let _ = dev.device.queue_wait_idle(dev.queue);
            for img in self.images.drain(..) {
                dev.device.destroy_image(img.image, None);
                dev.device.free_memory(img.memory, None);
            }
        }
    }

    /// Copies one layer's rectangle back and writes it as an RGBA PNG.
    fn dump(
        &self,
        dev: &Device,
        image: usize,
        layer: u32,
        rect: sys::Rect2Di,
        path: &Path,
    ) -> Result<(), String> {
        let Some(img) = self.images.get(image) else {
            return Err("no such image".into());
        };
        if aspect(self.format) != vk::ImageAspectFlags::COLOR || layer >= self.layers {
            return Err("not a colour layer".into());
        }
        let (x, y) = (rect.offset.x.max(0) as u32, rect.offset.y.max(0) as u32);
        let w = (rect.extent.width.max(0) as u32).min(self.size.0.saturating_sub(x));
        let h = (rect.extent.height.max(0) as u32).min(self.size.1.saturating_sub(y));
        if w == 0 || h == 0 {
            return Err("empty image rectangle".into());
        }
        let bytes = u64::from(w) * u64::from(h) * 4;
        let d = &dev.device;
        let fail = |what: &str, e: vk::Result| format!("{what}: {e}");
        // SAFETY: a host-visible buffer made, used and destroyed here on the live device; the
        // copy waits on the queue before the memory is read.
        unsafe {
            let buffer = d
                .create_buffer(
                    &vk::BufferCreateInfo::default()
                        .size(bytes)
                        .usage(vk::BufferUsageFlags::TRANSFER_DST),
                    None,
                )
                .map_err(|e| fail("buffer", e))?;
            let req = d.get_buffer_memory_requirements(buffer);
            let host =
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
            let Some(kind) = dev.memory_type(req.memory_type_bits, host) else {
                d.destroy_buffer(buffer, None);
                return Err("no host-visible memory".into());
            };
            let memory = match d.allocate_memory(
                &vk::MemoryAllocateInfo::default()
                    .allocation_size(req.size)
                    .memory_type_index(kind),
                None,
            ) {
                Ok(m) => m,
                Err(e) => {
                    d.destroy_buffer(buffer, None);
                    return Err(fail("memory", e));
                }
            };
            let out = (|| {
                d.bind_buffer_memory(buffer, memory, 0)
                    .map_err(|e| fail("bind", e))?;
                let (fmt, ready) = (self.format, ready_layout(self.format));
                dev.run(|cb| {
                    let src = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
                    d.cmd_pipeline_barrier(
                        cb,
                        vk::PipelineStageFlags::ALL_COMMANDS,
                        vk::PipelineStageFlags::TRANSFER,
                        vk::DependencyFlags::empty(),
                        &[],
                        &[],
                        &[barrier(img.image, fmt, layer, 1, ready, src)],
                    );
                    let region = vk::BufferImageCopy::default()
                        .image_subresource(vk::ImageSubresourceLayers {
                            aspect_mask: vk::ImageAspectFlags::COLOR,
                            mip_level: 0,
                            base_array_layer: layer,
                            layer_count: 1,
                        })
                        .image_offset(vk::Offset3D {
                            x: x as i32,
                            y: y as i32,
                            z: 0,
                        })
                        .image_extent(vk::Extent3D {
                            width: w,
                            height: h,
                            depth: 1,
                        });
                    d.cmd_copy_image_to_buffer(cb, img.image, src, buffer, &[region]);
                    d.cmd_pipeline_barrier(
                        cb,
                        vk::PipelineStageFlags::TRANSFER,
                        vk::PipelineStageFlags::ALL_COMMANDS,
                        vk::DependencyFlags::empty(),
                        &[],
                        &[],
                        &[barrier(img.image, fmt, layer, 1, src, ready)],
                    );
                })
                .map_err(|e| fail("copy", e))?;
                let ptr = d
                    .map_memory(memory, 0, bytes, vk::MemoryMapFlags::empty())
                    .map_err(|e| fail("map", e))?;
                let mut pixels =
                    std::slice::from_raw_parts(ptr.cast::<u8>(), bytes as usize).to_vec();
                d.unmap_memory(memory);
                if matches!(
                    self.format,
                    vk::Format::B8G8R8A8_SRGB | vk::Format::B8G8R8A8_UNORM
                ) {
                    pixels.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
                }
                write_png(path, w, h, &pixels)
            })();
            d.destroy_buffer(buffer, None);
            d.free_memory(memory, None);
            out
        }
    }
}

/// Writes RGBA8 pixels as a PNG, whole or not at all.
fn write_png(path: &Path, w: u32, h: u32, rgba: &[u8]) -> Result<(), String> {
    let tmp = path.with_extension("png.partial");
    let file = std::fs::File::create(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    enc.write_header()
        .and_then(|mut wr| wr.write_image_data(rgba))
        .map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
}

fn index(h: sys::Swapchain) -> Option<usize> {
    let raw = h.into_raw();
    (raw & !0xffff_ffff == TAG && raw & 0xffff_ffff != 0).then(|| (raw & 0xffff_ffff) as usize - 1)
}

/// The session's swapchain behind a handle.
fn chain(rt: &mut Runtime, h: sys::Swapchain) -> Result<&mut Swapchain, sys::Result> {
    let s = live(rt)?;
    index(h)
        .and_then(|k| s.swapchains.get_mut(k))
        .and_then(Option::as_mut)
        .ok_or(sys::Result::ERROR_HANDLE_INVALID)
}

pub(crate) fn lookup(name: &str) -> Option<sys::pfn::VoidFunction> {
    // SAFETY (all transmutes): each turns a function pointer of the exact pfn type OpenXR
    // declares for that name into PFN_xrVoidFunction; the caller casts it back before calling.
    unsafe {
        use std::mem::transmute;
        use sys::pfn::VoidFunction as V;
        match name {
            "xrEnumerateSwapchainFormats" => {
                Some(transmute::<sys::pfn::EnumerateSwapchainFormats, V>(formats))
            }
            "xrCreateSwapchain" => Some(transmute::<sys::pfn::CreateSwapchain, V>(create)),
            "xrDestroySwapchain" => Some(transmute::<sys::pfn::DestroySwapchain, V>(destroy)),
            "xrEnumerateSwapchainImages" => {
                Some(transmute::<sys::pfn::EnumerateSwapchainImages, V>(images))
            }
            "xrAcquireSwapchainImage" => {
                Some(transmute::<sys::pfn::AcquireSwapchainImage, V>(acquire))
            }
            "xrWaitSwapchainImage" => Some(transmute::<sys::pfn::WaitSwapchainImage, V>(wait)),
            "xrReleaseSwapchainImage" => {
                Some(transmute::<sys::pfn::ReleaseSwapchainImage, V>(release))
            }
            _ => None,
        }
    }
}

unsafe extern "system" fn formats(
    session: sys::Session,
    capacity: u32,
    count: *mut u32,
    out: *mut i64,
) -> sys::Result {
    xr_try!(with_session(session, |rt| live(rt).map(|_| ())));
    let list: Vec<i64> = FORMATS.iter().map(|f| i64::from(f.as_raw())).collect();
    // SAFETY: the pointers come from the caller under the two-call idiom's contract.
    unsafe { two_call(capacity, count, out, &list, |a, b| *b = *a) }
}

unsafe extern "system" fn create(
    session: sys::Session,
    info: *const sys::SwapchainCreateInfo,
    out: *mut sys::Swapchain,
) -> sys::Result {
    // SAFETY: the caller passes a valid create info or null (rejected).
    let info = xr_try!(unsafe { arg(info) });
    // SAFETY: the caller passes a writable handle or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    if !FORMATS.iter().any(|f| i64::from(f.as_raw()) == info.format) {
        return sys::Result::ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED;
    }
    let sizes_ok = (1..=4096).contains(&info.width)
        && (1..=4096).contains(&info.height)
        && (1..=16).contains(&info.array_size)
        && info.face_count == 1
        && info.mip_count == 1
        && info.sample_count == 1;
    if !sizes_ok {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    let h = xr_try!(with_session(session, |rt| {
        let s = live(rt)?;
        let dev = s
            .device
            .as_ref()
            .ok_or(sys::Result::ERROR_RUNTIME_FAILURE)?;
        let made = Swapchain::create(dev, info)?;
        s.swapchains.push(Some(made));
        Ok(TAG | s.swapchains.len() as u64)
    }));
    *out = sys::Swapchain::from_raw(h);
    sys::Result::SUCCESS
}

unsafe extern "system" fn destroy(h: sys::Swapchain) -> sys::Result {
    result(with_session(
        sys::Session::from_raw(super::session::SESSION),
        |rt| {
            let s = live(rt)?;
            let slot = index(h)
                .and_then(|k| s.swapchains.get_mut(k))
                .filter(|c| c.is_some())
                .ok_or(sys::Result::ERROR_HANDLE_INVALID)?;
            if let (Some(mut c), Some(dev)) = (slot.take(), s.device.as_ref()) {
                c.destroy(dev);
            }
            Ok(())
        },
    ))
}

unsafe extern "system" fn images(
    h: sys::Swapchain,
    capacity: u32,
    count: *mut u32,
    out: *mut sys::SwapchainImageBaseHeader,
) -> sys::Result {
    let list = xr_try!(with_session(
        sys::Session::from_raw(super::session::SESSION),
        |rt| Ok(chain(rt, h)?
            .images
            .iter()
            .map(|i| i.image.as_raw())
            .collect::<Vec<u64>>())
    ));
    if count.is_null() {
        return sys::Result::ERROR_VALIDATION_FAILURE;
    }
    // SAFETY: `count` is non-null and writable.
    unsafe { *count = list.len() as u32 };
    if capacity == 0 {
        return sys::Result::SUCCESS;
    }
    if (capacity as usize) < list.len() || out.is_null() {
        return sys::Result::ERROR_SIZE_INSUFFICIENT;
    }
    let out = out.cast::<sys::SwapchainImageVulkanKHR>();
    for (k, image) in list.into_iter().enumerate() {
        // SAFETY: for a Vulkan session the app passes an array of `capacity` (>= count)
        // XrSwapchainImageVulkanKHR structures.
        let slot = unsafe { &mut *out.add(k) };
        if slot.ty != sys::SwapchainImageVulkanKHR::TYPE {
            return sys::Result::ERROR_VALIDATION_FAILURE;
        }
        slot.image = image;
    }
    sys::Result::SUCCESS
}

unsafe extern "system" fn acquire(
    h: sys::Swapchain,
    _info: *const sys::SwapchainImageAcquireInfo,
    out: *mut u32,
) -> sys::Result {
    // SAFETY: the caller passes a writable index or null (rejected).
    let out = xr_try!(unsafe { arg_mut(out) });
    let k = xr_try!(with_session(
        sys::Session::from_raw(super::session::SESSION),
        |rt| {
            let c = chain(rt, h)?;
            if c.acquired.len() >= c.images.len() {
                return Err(sys::Result::ERROR_CALL_ORDER_INVALID);
            }
            let k = c.next;
            c.next = (c.next + 1) % c.images.len();
            c.acquired.push_back(k);
            Ok(k)
        }
    ));
    *out = k as u32;
    sys::Result::SUCCESS
}

unsafe extern "system" fn wait(
    h: sys::Swapchain,
    _info: *const sys::SwapchainImageWaitInfo,
) -> sys::Result {
    result(with_session(
        sys::Session::from_raw(super::session::SESSION),
        |rt| {
            let c = chain(rt, h)?;
            if c.waited.is_some() {
                return Err(sys::Result::ERROR_CALL_ORDER_INVALID);
            }
            c.waited = Some(
                *c.acquired
                    .front()
                    .ok_or(sys::Result::ERROR_CALL_ORDER_INVALID)?,
            );
            Ok(())
        },
    ))
}

unsafe extern "system" fn release(
    h: sys::Swapchain,
    _info: *const sys::SwapchainImageReleaseInfo,
) -> sys::Result {
    result(with_session(
        sys::Session::from_raw(super::session::SESSION),
        |rt| {
            let c = chain(rt, h)?;
            let k = c
                .waited
                .take()
                .ok_or(sys::Result::ERROR_CALL_ORDER_INVALID)?;
            c.acquired.pop_front();
            c.released = Some(k);
            Ok(())
        },
    ))
}

/// A projection view to dump: which swapchain, layer and rectangle.
pub(crate) struct ViewImage {
    pub(crate) swapchain: sys::Swapchain,
    pub(crate) layer: u32,
    pub(crate) rect: sys::Rect2Di,
}

/// Checks the views' swapchains are the session's and have released an image.
pub(crate) fn check_views(rt: &mut Runtime, views: &[ViewImage]) -> Result<(), sys::Result> {
    for v in views {
        let c = chain(rt, v.swapchain).map_err(|_| sys::Result::ERROR_LAYER_INVALID)?;
        if c.released.is_none() || v.layer >= c.layers {
            return Err(sys::Result::ERROR_LAYER_INVALID);
        }
    }
    Ok(())
}

/// Writes `frames/NNNN_left.png` and `NNNN_right.png` from a frame's two views.
pub(crate) fn dump_views(rt: &mut Runtime, frame: u64, views: &[ViewImage]) {
    let Some(dir) = rt.config.as_ref().and_then(|c| c.out_dir.clone()) else {
        return;
    };
    let Some(s) = rt.session.as_ref() else {
        return;
    };
    let Some(dev) = s.device.as_ref() else {
        return;
    };
    for (v, eye) in views.iter().zip(["left", "right"]) {
        let Some(Some(c)) = index(v.swapchain).and_then(|k| s.swapchains.get(k)) else {
            continue;
        };
        let Some(image) = c.released else {
            continue;
        };
        let path = dir.join("frames").join(format!("{frame:04}_{eye}.png"));
        if let Err(e) = c.dump(dev, image, v.layer, v.rect, &path) {
            eprintln!("vesalius-sim-runtime: {}: {e}", path.display());
        }
    }
}
