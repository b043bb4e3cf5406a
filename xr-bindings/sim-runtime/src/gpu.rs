//! Swapchain images on the app's Vulkan device (made with the app's own driver through the
//! `vkGetInstanceProcAddr` it gave `xrCreateVulkanInstanceKHR`), and reading one back into a
//! PNG. The objects here know nothing of the runtime's state; `swapchain.rs` hands them out.

use ash::vk;
use ash::vk::Handle as _;
use openxr_sys as sys;
use std::path::Path;

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

/// Why a frame dump was not written (the message follows the PNG's path on stderr).
#[derive(Debug, thiserror::Error)]
pub(crate) enum DumpError {
    #[error("no such image ({0})")]
    NoSuchImage(usize),
    #[error("not a colour layer (layer {0})")]
    NotColour(u32),
    #[error("empty image rectangle")]
    EmptyRect,
    #[error("no host-visible memory")]
    NoHostMemory,
    /// A Vulkan call of the read-back failed: which step (buffer, memory, bind, copy, map).
    #[error("{step}: {source}")]
    Vulkan {
        step: &'static str,
        source: vk::Result,
    },
    #[error("{}: {source}", path.display())]
    Write {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {source}", path.display())]
    Encode {
        path: std::path::PathBuf,
        source: png::EncodingError,
    },
}

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

pub(crate) struct Image {
    pub(crate) image: vk::Image,
    memory: vk::DeviceMemory,
}

pub(crate) struct Swapchain {
    format: vk::Format,
    size: (u32, u32),
    pub(crate) layers: u32,
    pub(crate) images: Vec<Image>,
    /// Acquired and not yet released, oldest first.
    pub(crate) acquired: std::collections::VecDeque<usize>,
    /// The image waited on (the one the app writes now).
    pub(crate) waited: Option<usize>,
    pub(crate) next: usize,
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
    pub(crate) fn create(
        dev: &Device,
        info: &sys::SwapchainCreateInfo,
    ) -> Result<Swapchain, sys::Result> {
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
    pub(crate) fn dump(
        &self,
        dev: &Device,
        image: usize,
        layer: u32,
        rect: sys::Rect2Di,
        path: &Path,
    ) -> Result<(), DumpError> {
        let Some(img) = self.images.get(image) else {
            return Err(DumpError::NoSuchImage(image));
        };
        if aspect(self.format) != vk::ImageAspectFlags::COLOR || layer >= self.layers {
            return Err(DumpError::NotColour(layer));
        }
        let (x, y) = (rect.offset.x.max(0) as u32, rect.offset.y.max(0) as u32);
        let w = (rect.extent.width.max(0) as u32).min(self.size.0.saturating_sub(x));
        let h = (rect.extent.height.max(0) as u32).min(self.size.1.saturating_sub(y));
        if w == 0 || h == 0 {
            return Err(DumpError::EmptyRect);
        }
        let bytes = u64::from(w) * u64::from(h) * 4;
        let d = &dev.device;
        let fail = |step: &'static str, source: vk::Result| DumpError::Vulkan { step, source };
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
                return Err(DumpError::NoHostMemory);
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
fn write_png(path: &Path, w: u32, h: u32, rgba: &[u8]) -> Result<(), DumpError> {
    let tmp = path.with_extension("png.partial");
    let file = std::fs::File::create(&tmp).map_err(|source| DumpError::Write {
        path: tmp.clone(),
        source,
    })?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
    enc.set_color(png::ColorType::Rgba);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    enc.write_header()
        .and_then(|mut wr| wr.write_image_data(rgba))
        .map_err(|source| DumpError::Encode {
            path: tmp.clone(),
            source,
        })?;
    std::fs::rename(&tmp, path).map_err(|source| DumpError::Write {
        path: path.to_path_buf(),
        source,
    })
}
