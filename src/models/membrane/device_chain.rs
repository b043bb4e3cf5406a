//! Layer 0's targets placed on the device from the chain's pose (`shaders/membrane_chain.wgsl`;
//! the chain: `chain.rs`). The bindings go up once; each step the pose (a few hundred bytes)
//! goes up and the targets of the tiles the step reads (the awake ones and the halo) are
//! placed before anything reads them, so no target is placed on the CPU or sent up for
//! them.

use super::super::chain::Chain;
use super::one_pass;
use crate::gpu::compute::{self, bind};
use crate::gpu::{Gpu, RenderError};

const SHADER: &str = include_str!("../../../shaders/membrane_chain.wgsl");

/// The shader's `Chain` (16 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    rows: u32,
    cols: u32,
    tiles_c: u32,
    frames_at: u32,
}

/// The shader's `Bound` (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Bound {
    segment: u32,
    t: f32,
    pair: u32,
    w: f32,
    offset: [f32; 3],
    pad: f32,
}

/// The kernel, the bindings on the device and the pose's buffer.
pub(super) struct Carrier {
    pipeline: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    pose: wgpu::Buffer,
    up: Vec<[f32; 4]>,
}

impl Carrier {
    /// The kernel over the attachments `attach` of a membrane of `rows` x `cols` with
    /// `tiles_c` tiles a row, for the tiles of `list`, with `chain`'s bindings up.
    pub fn new(
        gpu: &Gpu,
        chain: &Chain,
        (rows, cols, tiles_c): (usize, usize, u32),
        (attach, list): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Result<Carrier, RenderError> {
        let module = compute::compile(&gpu.device, "shaders/membrane_chain.wgsl", SHADER)?;
        let pipeline = compute::pipeline(gpu, &module, "carry")?;
        let bound: Vec<Bound> = chain
            .bound
            .iter()
            .map(|b| Bound {
                segment: b.segment,
                t: b.t,
                pair: b.pair,
                w: b.w,
                offset: b.offset.to_array(),
                pad: 0.0,
            })
            .collect();
        let bound = compute::storage(gpu, "membrane chain bindings", bytemuck::cast_slice(&bound))?;
        let frames_at = chain.segments as u32 + 1;
        let len = frames_at as usize + super::super::chain::frames(chain.segments);
        let pose = compute::storage(gpu, "membrane chain pose", &vec![0u8; len * 16])?;
        let p = Params {
            rows: rows as u32,
            cols: cols as u32,
            tiles_c,
            frames_at,
        };
        let params = compute::uniform(gpu, "membrane chain params", bytemuck::bytes_of(&p));
        let bind = bind(
            gpu,
            &pipeline,
            "membrane chain",
            &[
                (0, &params),
                (1, attach),
                (2, &bound),
                (3, &pose),
                (4, list),
            ],
        );
        gpu.check()?;
        Ok(Carrier {
            pipeline,
            bind,
            pose,
            up: Vec::with_capacity(len),
        })
    }

    /// Into `encoder`: `chain`'s pose up, and the targets of the first `tiles` tiles of the
    /// list placed.
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        chain: &Chain,
        tiles: usize,
    ) {
        if tiles == 0 {
            return;
        }
        self.up.clear();
        let points = chain.points.iter().map(|p| {
            let p = p.as_vec3();
            [p.x, p.y, p.z, 0.0]
        });
        self.up.extend(points);
        self.up.extend(chain.quats.iter().map(|q| q.to_array()));
        gpu.queue
            .write_buffer(&self.pose, 0, bytemuck::cast_slice(&self.up));
        one_pass(
            encoder,
            "membrane targets",
            (&self.pipeline, &self.bind),
            [tiles as u32, 1, 1],
        );
    }
}
