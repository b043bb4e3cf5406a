//! What tissue models' compute kernels share: compiling WGSL with its file named in errors,
//! storage buffers filled from slices, reading a buffer back, and timing a compute pass with
//! timestamp queries where the adapter has them.

use super::{Gpu, RenderError};

/// Compiles the WGSL `source` of file `file`. A compile error is returned naming the file:
/// left to the device's error handler it would surface far from its cause.
pub fn compile(
    device: &wgpu::Device,
    file: &str,
    source: &str,
) -> Result<wgpu::ShaderModule, RenderError> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(file),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    match pollster::block_on(scope.pop()) {
        Some(e) => Err(RenderError::Shader {
            file: file.to_string(),
            message: e.to_string(),
        }),
        None => Ok(module),
    }
}

/// A compute pipeline of `module`'s entry point `entry`, with the layout the shader declares.
/// A pipeline the device refuses is returned as an error.
pub fn pipeline(
    gpu: &Gpu,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> Result<wgpu::ComputePipeline, RenderError> {
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let p = gpu
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: None,
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
    match pollster::block_on(scope.pop()) {
        Some(e) => Err(RenderError::Validation(e.to_string())),
        None => Ok(p),
    }
}

/// The bytes last written into a buffer from the CPU, so that a write of the same bytes
/// again is left out: each `write_buffer` stages its bytes in a buffer of its own, made and
/// freed by the driver, which costs more than comparing a few kilobytes. Only for buffers
/// that no kernel writes.
#[derive(Debug, Default)]
pub(crate) struct LastWrite {
    at: u64,
    bytes: Vec<u8>,
    written: bool,
}

impl LastWrite {
    /// `bytes` into `buffer` at `at`, unless the last write through here was the same.
    pub(crate) fn write(&mut self, gpu: &Gpu, buffer: &wgpu::Buffer, at: u64, bytes: &[u8]) {
        if self.written && self.at == at && self.bytes == bytes {
            return;
        }
        gpu.queue.write_buffer(buffer, at, bytes);
        self.at = at;
        self.bytes.clear();
        self.bytes.extend_from_slice(bytes);
        self.written = true;
    }
}

/// A storage buffer holding `data` (at least 16 bytes, so an empty list still binds), that
/// can be copied to and from. Refused with a clear error where it is larger than the device
/// binds.
pub fn storage(gpu: &Gpu, label: &str, data: &[u8]) -> Result<wgpu::Buffer, RenderError> {
    let most = gpu.device.limits().max_storage_buffer_binding_size;
    if data.len() as u64 > most {
        return Err(RenderError::Device(format!(
            "{label} needs {} MB; this device binds at most {} MB a buffer",
            data.len() >> 20,
            most >> 20
        )));
    }
    let buffer = filled(
        gpu,
        label,
        data,
        16,
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
    );
    gpu.check()?;
    Ok(buffer)
}

/// A buffer of `data` (padded with zeros to a multiple of 4 bytes and to at least `least`),
/// written through the queue. Not mapped at its creation: on a lost device a mapped buffer's
/// range panics inside wgpu, where a written one reports the loss through [`Gpu::check`].
fn filled(
    gpu: &Gpu,
    label: &str,
    data: &[u8],
    least: usize,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let size = data.len().max(least).next_multiple_of(4);
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size as u64,
        usage,
        mapped_at_creation: false,
    });
    if size == data.len() {
        gpu.queue.write_buffer(&buffer, 0, data);
    } else {
        let mut padded = data.to_vec();
        padded.resize(size, 0);
        gpu.queue.write_buffer(&buffer, 0, &padded);
    }
    buffer
}

/// A uniform buffer of `data`, written again with `queue.write_buffer`.
pub fn uniform(gpu: &Gpu, label: &str, data: &[u8]) -> wgpu::Buffer {
    filled(
        gpu,
        label,
        data,
        4,
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    )
}

/// Copies `bytes` bytes of `buffer` from its start into a mappable buffer and reads them
/// (waiting for everything submitted before).
pub fn read(gpu: &Gpu, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>, RenderError> {
    let mut all = read_all(gpu, &[(buffer, bytes)])?;
    Ok(all.pop().unwrap_or_default())
}

/// A bind group of `pipeline`'s own layout (group 0, as the shader declares it) over
/// `entries`: each a binding and the whole of a buffer.
pub fn bind(
    gpu: &Gpu,
    pipeline: &wgpu::ComputePipeline,
    label: &str,
    entries: &[(u32, &wgpu::Buffer)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry<'_>> = entries
        .iter()
        .map(|&(binding, buffer)| wgpu::BindGroupEntry {
            binding,
            resource: buffer.as_entire_binding(),
        })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    })
}

/// Copies the first bytes of each `(buffer, bytes)` into one mappable buffer in one
/// submission and reads them (waiting for everything submitted before): one round trip for
/// all.
pub fn read_all(gpu: &Gpu, parts: &[(&wgpu::Buffer, u64)]) -> Result<Vec<Vec<u8>>, RenderError> {
    let total: u64 = parts.iter().map(|p| p.1).sum();
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("compute readback"),
        size: total.max(4),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("compute readback"),
        });
    let mut at = 0;
    for &(buffer, bytes) in parts {
        if bytes > 0 {
            encoder.copy_buffer_to_buffer(buffer, 0, &staging, at, bytes);
        }
        at += bytes;
    }
    gpu.queue.submit([encoder.finish()]);
    let all = map_read(gpu, &staging, total.max(4))?;
    gpu.check()?;
    let mut out = Vec::with_capacity(parts.len());
    let mut at = 0usize;
    for &(_, bytes) in parts {
        out.push(all[at..at + bytes as usize].to_vec());
        at += bytes as usize;
    }
    Ok(out)
}

/// Maps a `MAP_READ` buffer once what was submitted before has run, and copies out its first
/// `bytes` bytes.
pub(crate) fn map_read(
    gpu: &Gpu,
    staging: &wgpu::Buffer,
    bytes: u64,
) -> Result<Vec<u8>, RenderError> {
    with_mapped(gpu, staging, bytes, <[u8]>::to_vec)
}

/// Nanoseconds this process's threads have spent in [`with_mapped`]'s waits, summed (an
/// integer, so the sum does not depend on the order the waits end in).
static WAITED_NS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Nanoseconds spent waiting for devices so far (all threads): what a bench takes off a
/// step's time to give the CPU's part of it. A wait counts from the map's request to its
/// answer, so it holds the device's work and what wgpu does once it is done (freeing the
/// submission's command buffers and staging buffers).
pub fn waited_ns() -> u64 {
    WAITED_NS.load(std::sync::atomic::Ordering::Relaxed)
}

/// Maps a `MAP_READ` buffer once what was submitted before has run, hands its first `bytes`
/// bytes to `read` (no copy) and unmaps it. An error the device reported meanwhile is
/// returned instead, before anything is read.
pub(crate) fn with_mapped<R>(
    gpu: &Gpu,
    staging: &wgpu::Buffer,
    bytes: u64,
    read: impl FnOnce(&[u8]) -> R,
) -> Result<R, RenderError> {
    let started = std::time::Instant::now();
    let waited = || {
        let ns = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
        WAITED_NS.fetch_add(ns, std::sync::atomic::Ordering::Relaxed);
    };
    let wait = tracing::debug_span!("gpu_map_wait").entered();
    let (tx, rx) = std::sync::mpsc::channel();
    staging
        .slice(..bytes)
        .map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
    let answered = gpu
        .device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))
        .and_then(|_| rx.recv().map_err(|e| RenderError::Readback(e.to_string())))
        .and_then(|r| r.map_err(|e| RenderError::Readback(e.to_string())));
    waited();
    drop(wait);
    answered?;
    if let Err(e) = gpu.check() {
        staging.unmap();
        return Err(e);
    }
    let out = {
        let view = staging
            .slice(..bytes)
            .get_mapped_range()
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        read(&view)
    };
    staging.unmap();
    Ok(out)
}

/// Times compute passes on the GPU's own clock: a pass's start and end timestamps, resolved
/// and read back. Only where the device was made with timestamp queries.
pub struct PassTimer {
    queries: wgpu::QuerySet,
    resolved: wgpu::Buffer,
    staging: wgpu::Buffer,
    /// Nanoseconds a tick.
    period_ns: f64,
}

impl PassTimer {
    /// A timer, if the device can write timestamps in compute passes.
    pub fn new(gpu: &Gpu) -> Option<PassTimer> {
        if !gpu
            .device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
        {
            return None;
        }
        let queries = gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("pass timer"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let buffer = |usage| {
            gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pass timer"),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(PassTimer {
            queries,
            resolved: buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC),
            staging: buffer(wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ),
            period_ns: f64::from(gpu.queue.get_timestamp_period()),
        })
    }

    /// The pass descriptor's timestamp writes: the pass's start and end.
    pub fn writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// The timestamp writes of one of a run of passes timed as one: its start where
    /// `timed.0`, its end where `timed.1` (none where neither).
    pub fn writes_part(&self, timed: (bool, bool)) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        (timed.0 || timed.1).then_some(wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: timed.0.then_some(0),
            end_of_pass_write_index: timed.1.then_some(1),
        })
    }

    /// After the pass, in the same encoder: the timestamps into the readable buffer.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.queries, 0..2, &self.resolved, 0);
        encoder.copy_buffer_to_buffer(&self.resolved, 0, &self.staging, 0, 16);
    }

    /// After [`PassTimer::resolve`], in the same encoder: the timestamps (16 bytes) also into
    /// `to` at `offset`, to be read with other results ([`PassTimer::seconds_of`]).
    pub fn copy_into(&self, encoder: &mut wgpu::CommandEncoder, to: &wgpu::Buffer, offset: u64) {
        encoder.copy_buffer_to_buffer(&self.resolved, 0, to, offset, 16);
    }

    /// The last timed pass's length, seconds (waits for it).
    pub fn seconds(&self, gpu: &Gpu) -> Result<f64, RenderError> {
        with_mapped(gpu, &self.staging, 16, |b| self.seconds_of(b))
    }

    /// The pass's length, seconds, from its 16 bytes of timestamps.
    pub fn seconds_of(&self, bytes: &[u8]) -> f64 {
        let tick = |k: usize| {
            let mut b = [0u8; 8];
            if let Some(s) = bytes.get(8 * k..8 * k + 8) {
                b.copy_from_slice(s);
            }
            u64::from_le_bytes(b)
        };
        tick(1).saturating_sub(tick(0)) as f64 * self.period_ns * 1e-9
    }
}
