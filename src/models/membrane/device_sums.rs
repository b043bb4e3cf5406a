//! Layer 0's loads summed by group on the device (`anchor_sums` in `shaders/membrane.wgsl`,
//! `anchor_sums.rs` for what the sums are): in the active step's submission, after the
//! targets and the external forces have gone up and before the substeps, from the state they
//! start from; read back with the awake tiles, a few hundred bytes.

use super::super::anchor_sums::{AnchorGroups, AnchorSum};
use super::super::gpu::MembraneGpu;
use crate::gpu::compute::{self, LastWrite, bind};
use crate::gpu::{Gpu, RenderError};
use glam::DVec3;

/// Floats a group's sums take on the device (the shader's `SUM_TERMS`).
const TERMS: usize = 12;

/// The sums' kernel and buffers.
pub(super) struct Sums {
    pipeline: wgpu::ComputePipeline,
    /// Bind group `s` reads state buffer `s`.
    bind: [wgpu::BindGroup; 2],
    /// The groups' starts, then the awake tiles' flags (the shader's `group_index`).
    index: wgpu::Buffer,
    /// The groups' points, then the members (`items`).
    items: wgpu::Buffer,
    out: wgpu::Buffer,
    groups: usize,
    /// Per tile, 1 where awake (written each step).
    mask: Vec<u32>,
    /// What the mask held when last written (not written again unchanged).
    mask_written: LastWrite,
}

impl Sums {
    /// The kernel over `g`'s groups for `k`'s buffers, with a mask for `tiles` tiles. None
    /// without a group.
    pub fn new(
        gpu: &Gpu,
        k: &MembraneGpu,
        g: &AnchorGroups,
        tiles: usize,
    ) -> Result<Option<Sums>, RenderError> {
        let groups = g.about.len();
        if groups == 0 {
            return Ok(None);
        }
        let module = compute::compile(
            &gpu.device,
            "shaders/membrane.wgsl",
            super::super::gpu::SHADER,
        )?;
        let pipeline = compute::pipeline(gpu, &module, "anchor_sums")?;
        let mut index = g.starts.clone();
        index.resize(g.starts.len() + tiles.max(1), 0);
        let mut items: Vec<[u32; 4]> = g
            .about
            .iter()
            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits(), 0])
            .collect();
        items.extend(
            g.members
                .iter()
                .map(|m| [m.cell, m.u.to_bits(), m.k.to_bits(), m.group]),
        );
        let index = compute::storage(gpu, "anchor groups' index", bytemuck::cast_slice(&index))?;
        let items = compute::storage(gpu, "anchor groups' items", bytemuck::cast_slice(&items))?;
        let out = compute::storage(gpu, "anchor sums", &vec![0u8; 4 * TERMS * groups])?;
        let bind = Self::binds(gpu, &pipeline, k, [&index, &items, &out]);
        gpu.check()?;
        Ok(Some(Sums {
            pipeline,
            bind,
            index,
            items,
            out,
            groups,
            mask: vec![0; tiles.max(1)],
            mask_written: LastWrite::default(),
        }))
    }

    fn binds(
        gpu: &Gpu,
        pipeline: &wgpu::ComputePipeline,
        k: &MembraneGpu,
        [index, items, out]: [&wgpu::Buffer; 3],
    ) -> [wgpu::BindGroup; 2] {
        [0usize, 1].map(|s| {
            bind(
                gpu,
                pipeline,
                "membrane anchor sums",
                &[
                    (0, &k.params),
                    (1, &k.state[s]),
                    (3, &k.springs),
                    (4, &k.attach),
                    (5, &k.beta),
                    (6, &k.externals),
                    (8, index),
                    (9, items),
                    (12, out),
                ],
            )
        })
    }

    /// Binds `k`'s buffers anew (its external forces' buffer grew).
    pub fn rebind(&mut self, gpu: &Gpu, k: &MembraneGpu) {
        self.bind = Self::binds(
            gpu,
            &self.pipeline,
            k,
            [&self.index, &self.items, &self.out],
        );
    }

    /// Bytes the sums take in the readback.
    pub fn bytes(&self) -> u64 {
        (4 * TERMS * self.groups) as u64
    }

    /// The sums' pass into `encoder`, over the tiles of `awake`, reading state buffer
    /// `current`.
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        current: usize,
        awake: &[u32],
    ) {
        self.mask.fill(0);
        for &t in awake {
            if let Some(m) = self.mask.get_mut(t as usize) {
                *m = 1;
            }
        }
        let at = (4 * (self.groups + 1)) as u64;
        let mask = bytemuck::cast_slice(&self.mask);
        self.mask_written.write(gpu, &self.index, at, mask);
        let kernel = (&self.pipeline, &self.bind[current.min(1)]);
        super::one_pass(
            encoder,
            "membrane anchor sums",
            kernel,
            [self.groups as u32, 1, 1],
        );
    }

    /// The sums copied to the start of `to`.
    pub fn copy(&self, encoder: &mut wgpu::CommandEncoder, to: &wgpu::Buffer) {
        encoder.copy_buffer_to_buffer(&self.out, 0, to, 0, self.bytes());
    }

    /// The sums read back (`raw`: this pass's bytes), per group, into `out` (its allocation
    /// kept from step to step).
    pub fn read_into(&self, raw: &[u8], out: &mut Vec<AnchorSum>) {
        let d = |s: &[f32], c: usize| DVec3::new(s[c].into(), s[c + 1].into(), s[c + 2].into());
        out.clear();
        super::pack::as_floats(raw, |v| {
            out.extend(v.chunks_exact(TERMS).take(self.groups).map(|s| AnchorSum {
                force: d(s, 0),
                weighted_force: d(s, 3),
                moment: d(s, 6),
                stiffness: s[9].into(),
                weighted_stiffness: s[10].into(),
            }));
        });
    }
}
