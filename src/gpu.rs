//! The one wgpu device (Vulkan; Mesa's lavapipe where there is no GPU), shared by the
//! renderer, the window, the headset and tissue models' compute, and eye textures that can be
//! read back to PNG. A leaf: it names no model and no renderer.

pub mod compute;

use crate::profiler::{Category, Ledger, Tracked};
use std::path::Path;
use std::sync::Arc;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(
        "no Vulkan adapter: {0} (install a Vulkan driver; without a GPU, Mesa's lavapipe: apt-get install mesa-vulkan-drivers libvulkan1)"
    )]
    NoAdapter(String),
    #[error("the Vulkan device could not be created: {0}")]
    Device(String),
    #[error("reading the frame back from the GPU failed: {0}")]
    Readback(String),
    #[error("{path}: {message}")]
    Write { path: String, message: String },
    #[error("shader {file} does not compile: {message}")]
    Shader { file: String, message: String },
    #[error("the GPU rejected a command: {0}")]
    Validation(String),
    #[error("the GPU device was lost: {0}")]
    Lost(String),
    #[error("eye size {0}x{1} is beyond this GPU's largest texture ({2} pixels a side)")]
    TooLarge(u32, u32, u32),
    #[error("the GPU compute path does not take this model: {0}")]
    Unsupported(String),
}

/// Devices opened so far ([`Gpu::devices_opened`]).
static DEVICES_OPENED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

thread_local! {
    /// The device [`Gpu::for_compute`] hands out on this thread instead of opening one (see
    /// [`Gpu::sharing_for_compute`]).
    static SHARED_FOR_COMPUTE: std::cell::RefCell<Option<Gpu>> = const { std::cell::RefCell::new(None) };
}

/// A wgpu device and queue with what we learned about the adapter. Clones share the device
/// (the desktop mirror draws with the XR session's device).
#[derive(Clone)]
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Whether one render pass can draw both eyes.
    pub multiview: bool,
    pub info: wgpu::AdapterInfo,
    pub ledger: Arc<Ledger>,
    /// Errors wgpu reported outside an error scope (validation, out of memory, device loss):
    /// collected here instead of wgpu's default panic, and returned by [`Gpu::check`].
    errors: Arc<std::sync::Mutex<Vec<RenderError>>>,
}

impl Gpu {
    /// Opens the first Vulkan adapter (a real GPU if there is one, else lavapipe). With
    /// `allow_multiview` false the device is made without multiview, to exercise the
    /// two-pass path.
    pub fn headless(allow_multiview: bool) -> Result<Gpu, RenderError> {
        let (instance, adapter) = Self::first_adapter()?;
        Self::open(instance, adapter, allow_multiview)
    }

    /// The device the models with a GPU path step on for `choice`: none for `cpu`, and for
    /// `auto` where the adapter is a software one (lavapipe), there is none or its device
    /// cannot be opened; `gpu` takes whatever adapter there is and is an error without one.
    ///
    /// Inside [`Gpu::sharing_for_compute`] it opens nothing: `gpu` takes the shared device,
    /// and `auto` takes it where it is a real GPU.
    pub fn for_compute(choice: crate::scenario::Compute) -> Result<Option<Gpu>, RenderError> {
        use crate::scenario::Compute;
        if let Some(shared) = SHARED_FOR_COMPUTE.with(|s| s.borrow().clone()) {
            let real = shared.info.device_type != wgpu::DeviceType::Cpu;
            return Ok(match choice {
                Compute::Cpu => None,
                Compute::Gpu => Some(shared),
                Compute::Auto => real.then_some(shared),
            });
        }
        match choice {
            Compute::Cpu => Ok(None),
            Compute::Gpu => Self::headless(false).map(Some),
            Compute::Auto => match Self::first_adapter() {
                Ok((instance, adapter))
                    if adapter.get_info().device_type != wgpu::DeviceType::Cpu =>
                {
                    Ok(Self::open(instance, adapter, false)
                        .inspect_err(|e| tracing::warn!("compute auto: on the CPU ({e})"))
                        .ok())
                }
                _ => Ok(None),
            },
        }
    }

    /// Runs `make` with this device as the one the models made meanwhile on this thread step
    /// on ([`Gpu::for_compute`] hands out a clone of it rather than opening a device of
    /// their own): frames and steps then share one device and its one queue, and its error
    /// list. The device before, if any, is put back afterwards.
    pub fn sharing_for_compute<R>(&self, make: impl FnOnce() -> R) -> R {
        /// Puts the device before back, however `make` ends.
        struct Restore(Option<Gpu>);
        impl Drop for Restore {
            fn drop(&mut self) {
                let before = self.0.take();
                SHARED_FOR_COMPUTE.with(|s| *s.borrow_mut() = before);
            }
        }
        let _restore = Restore(SHARED_FOR_COMPUTE.with(|s| s.replace(Some(self.clone()))));
        make()
    }

    /// Whether this machine has a real GPU: the first Vulkan adapter is not a software one
    /// (lavapipe), as `auto` in [`Gpu::for_compute`] judges it. Opens no device.
    pub fn real_gpu_present() -> bool {
        Self::first_adapter().is_ok_and(|(_, a)| a.get_info().device_type != wgpu::DeviceType::Cpu)
    }

    /// The first Vulkan adapter, a real GPU before a software one.
    fn first_adapter() -> Result<(wgpu::Instance, wgpu::Adapter), RenderError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::VULKAN;
        let instance = wgpu::Instance::new(desc);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        Ok((instance, adapter))
    }

    /// A device on `adapter` (with multiview where asked for and there).
    fn open(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        allow_multiview: bool,
    ) -> Result<Gpu, RenderError> {
        let multiview = allow_multiview && adapter.features().contains(wgpu::Features::MULTIVIEW);
        let mut required_features = wgpu::Features::empty();
        if multiview {
            required_features |= wgpu::Features::MULTIVIEW;
        }
        // Timestamps time the compute kernels where the adapter has them.
        if adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            required_features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let mut required_limits = wgpu::Limits::default().using_resolution(adapter.limits());
        // Tissue models' state buffers may pass the default 128 MiB a binding.
        let most = adapter.limits();
        required_limits.max_storage_buffer_binding_size = most
            .max_storage_buffer_binding_size
            .max(required_limits.max_storage_buffer_binding_size);
        required_limits.max_buffer_size = most.max_buffer_size.max(required_limits.max_buffer_size);
        if multiview {
            required_limits.max_multiview_view_count = 2;
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("vesalius"),
            required_features,
            required_limits,
            ..Default::default()
        }))
        .map_err(|e| RenderError::Device(e.to_string()))?;
        DEVICES_OPENED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        Ok(Gpu::from_parts(instance, adapter, device, queue, multiview))
    }

    /// Devices this process has opened so far (each [`Gpu::headless`] and each device a
    /// model opened for its compute; not the clones that share one).
    pub fn devices_opened() -> usize {
        DEVICES_OPENED.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Wraps a device made elsewhere (the XR runtime's Vulkan device), collecting its errors.
    pub fn from_parts(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
        multiview: bool,
    ) -> Gpu {
        let info = adapter.get_info();
        let errors: Arc<std::sync::Mutex<Vec<RenderError>>> = Arc::default();
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            if let Ok(mut v) = sink.lock() {
                v.push(RenderError::Validation(e.to_string()));
            }
        }));
        let sink = errors.clone();
        device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut v) = sink.lock() {
                v.push(RenderError::Lost(format!("{reason:?}: {message}")));
            }
        });
        Gpu {
            instance,
            adapter,
            device,
            queue,
            multiview,
            info,
            ledger: Ledger::new(),
            errors,
        }
    }

    /// The first error wgpu reported since the last check, if any.
    pub fn check(&self) -> Result<(), RenderError> {
        let mut v = match self.errors.lock() {
            Ok(v) => v,
            Err(poisoned) => poisoned.into_inner(),
        };
        if v.is_empty() {
            return Ok(());
        }
        let first = v.remove(0);
        v.clear();
        Err(first)
    }

    /// Whether this device can hold a 2-layer eye texture of `size`.
    pub fn check_eye_size(&self, size: (u32, u32)) -> Result<(), RenderError> {
        let max = self.device.limits().max_texture_dimension_2d;
        if size.0 > max || size.1 > max {
            return Err(RenderError::TooLarge(size.0, size.1, max));
        }
        Ok(())
    }

    /// "name (backend, device type)" for reports.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?}, driver {})",
            self.info.name, self.info.backend, self.info.device_type, self.info.driver_info
        )
    }
}

/// A 2-layer texture (one layer per eye), entered in the ledger, with its views.
pub fn eye_texture(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    label: &str,
    size: (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> (
    Tracked<wgpu::Texture>,
    wgpu::TextureView,
    [wgpu::TextureView; 2],
) {
    let texture = tracked_texture(device, ledger, label, size, 2, format, usage);
    let (array, layers) = eye_views(&texture);
    (texture, array, layers)
}

/// A colour texture of `layers` layers (one mip level, one sample).
pub fn colour_texture(
    device: &wgpu::Device,
    label: &str,
    size: (u32, u32),
    layers: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// [`colour_texture`], entered in the ledger as a texture.
pub fn tracked_texture(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    label: &str,
    size: (u32, u32),
    layers: u32,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> Tracked<wgpu::Texture> {
    let texture = colour_texture(device, label, size, layers, format, usage);
    let texel = format.block_copy_size(None).unwrap_or(4) as u64;
    let bytes = size.0 as u64 * size.1 as u64 * texel * layers as u64;
    Tracked::new(texture, bytes, Category::Texture, ledger)
}

/// Views of a 2-layer texture: the whole array (multiview) and each eye's layer (two passes).
pub fn eye_views(texture: &wgpu::Texture) -> (wgpu::TextureView, [wgpu::TextureView; 2]) {
    let array = texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    let layer = |l: u32| {
        texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2),
            base_array_layer: l,
            array_layer_count: Some(1),
            ..Default::default()
        })
    };
    (array, [layer(0), layer(1)])
}

/// The colour format of headless eye images (sRGB, as PNG stores them).
pub const EYE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// A 2-layer colour texture standing in for an XR swapchain image, with the views the renderer
/// takes and a way to read it back.
pub struct EyeTarget {
    pub size: (u32, u32),
    texture: Tracked<wgpu::Texture>,
    pub array: wgpu::TextureView,
    pub layers: [wgpu::TextureView; 2],
}

impl EyeTarget {
    pub fn new(gpu: &Gpu, size: (u32, u32)) -> Self {
        let (texture, array, layers) = eye_texture(
            &gpu.device,
            &gpu.ledger,
            "eyes",
            size,
            EYE_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        EyeTarget {
            size,
            texture,
            array,
            layers,
        }
    }

    /// The target as the renderer takes it: the array for multiview, else one view per eye.
    pub fn target(&self, multiview: bool) -> RenderTarget<'_> {
        if multiview {
            RenderTarget::Array(&self.array)
        } else {
            RenderTarget::PerEye([&self.layers[0], &self.layers[1]])
        }
    }

    /// Both eyes' pixels, tightly packed RGBA8 rows, top row first.
    pub fn read(&self, gpu: &Gpu) -> Result<[Vec<u8>; 2], RenderError> {
        let mut layers = read_texture(gpu, &self.texture, self.size, 2)?.into_iter();
        let mut next = || layers.next().unwrap_or_default();
        Ok([next(), next()])
    }
}

/// The first `layers` layers of a 4-byte-per-pixel colour texture of `size` (made with
/// `COPY_SRC`), each as tightly packed rows, top row first.
pub fn read_texture(
    gpu: &Gpu,
    texture: &wgpu::Texture,
    size: (u32, u32),
    layers: u32,
) -> Result<Vec<Vec<u8>>, RenderError> {
    let (w, h) = size;
    let row = w * 4;
    let padded = row.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let layer_bytes = padded as u64 * h as u64;
    let buffer = Tracked::new(
        gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: layer_bytes * layers as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        }),
        layer_bytes * layers as u64,
        Category::Staging,
        &gpu.ledger,
    );
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
    for layer in 0..layers {
        encoder.copy_texture_to_buffer(
            texture_layer(texture, layer),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: layer as u64 * layer_bytes,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }
    gpu.queue.submit([encoder.finish()]);
    let data = compute::map_read(gpu, &buffer, layer_bytes * layers as u64)?;
    let mut out = vec![Vec::new(); layers as usize];
    for (layer, img) in out.iter_mut().enumerate() {
        img.reserve_exact((row * h) as usize);
        for y in 0..h as usize {
            let start = layer * layer_bytes as usize + y * padded as usize;
            img.extend_from_slice(&data[start..start + row as usize]);
        }
    }
    Ok(out)
}

/// Writes tightly packed RGBA8 pixels as a PNG (via a temporary file and a rename, so a reader
/// never sees half a picture).
pub fn write_png(path: &Path, size: (u32, u32), rgba: &[u8]) -> Result<(), RenderError> {
    let err = |message: String| RenderError::Write {
        path: path.display().to_string(),
        message,
    };
    let tmp = path.with_extension("png.partial");
    {
        let file = std::fs::File::create(&tmp).map_err(|e| err(e.to_string()))?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), size.0, size.1);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(|e| err(e.to_string()))?;
        w.write_image_data(rgba).map_err(|e| err(e.to_string()))?;
        w.finish().map_err(|e| err(e.to_string()))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| err(e.to_string()))
}

/// Reads a PNG back as tightly packed RGBA8 (for tests and reference comparisons).
pub fn read_png(path: &Path) -> Result<((u32, u32), Vec<u8>), RenderError> {
    let err = |message: String| RenderError::Write {
        path: path.display().to_string(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| err(e.to_string()))?;
    let mut dec = png::Decoder::new(std::io::BufReader::new(file));
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(|e| err(e.to_string()))?;
    let mut buf = vec![0; reader.output_buffer_size().unwrap_or(0)];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| err(e.to_string()))?;
    buf.truncate(info.buffer_size());
    let rgba = match info.color_type {
        png::ColorType::Rgba => buf,
        png::ColorType::Rgb => buf
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect(),
        other => return Err(err(format!("expected an RGB or RGBA PNG, got {other:?}"))),
    };
    Ok(((info.width, info.height), rgba))
}

/// Where to draw: both eyes' layers of one array texture (multiview), one view per eye, or
/// one view seen by the first eye only (a desktop window; not with a multiview renderer).
pub enum RenderTarget<'a> {
    Array(&'a wgpu::TextureView),
    PerEye([&'a wgpu::TextureView; 2]),
    Single(&'a wgpu::TextureView),
}

/// Layer `layer` of `texture` (mip 0, from its corner), as a copy's source or destination.
pub fn texture_layer(texture: &wgpu::Texture, layer: u32) -> wgpu::TexelCopyTextureInfo<'_> {
    wgpu::TexelCopyTextureInfo {
        texture,
        mip_level: 0,
        origin: wgpu::Origin3d {
            x: 0,
            y: 0,
            z: layer,
        },
        aspect: wgpu::TextureAspect::All,
    }
}
