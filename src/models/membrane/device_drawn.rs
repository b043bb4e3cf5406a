//! A frame's drawn nodes gathered on the device. A frame draws the nodes of a
//! [`DrawnGrid`]; those of a tile the CPU lags it takes as the device left them
//! ([`Membrane::lagging_positions`]). Once a grid has been drawn, a step announced before a
//! frame ([`super::Slot::read_whole_next`]) gathers the positions of the grid's nodes in the
//! tiles it leaves lagging (`gather` in `shaders/membrane_sync.wgsl`) into a buffer of their
//! own, and only those come back with the step: three floats a drawn node, where copying the
//! lagging tiles' runs for the frame moves six floats for every node of those tiles. At the
//! rectum's drawing (every fourth row and column of three of the four layers) that is about
//! one byte in thirty-two.
//!
//! The gathered positions are the state buffer's own floats, so a frame draws the same bits
//! either way (tested). They hold for the tiles lagging after that step only: the next step,
//! or a catch-up of a tile, leaves the frame to read the runs again.

use super::super::{DrawnGrid, LAYERS, Membrane};
use super::{OnDevice, SyncParams};
use crate::gpu::compute::{self, LastWrite, bind};
use crate::gpu::{Gpu, RenderError};
use bytemuck::Zeroable;
use glam::Vec3;

/// Invocations of a gather workgroup (the kernel's `@workgroup_size`).
const GROUP: u32 = 64;
/// Most workgroups a dispatch takes along one axis (wgpu's default limit).
const MOST_GROUPS: u32 = 65_535;

/// A drawn grid's nodes on the device and what the last step gathered of them.
pub(super) struct Gather {
    /// The grid it is laid out for: its layers, rows and columns.
    key: [Vec<usize>; 3],
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    bind: wgpu::BindGroup,
    /// Where the gathered positions are read (mappable, three floats a listed place).
    readback: wgpu::Buffer,
    /// The gather's output on the device, copied to `readback` in the step's submission.
    out: wgpu::Buffer,
    list: wgpu::Buffer,
    /// Per tile `t`, its drawn places: `places[start[t]..start[t + 1]]`.
    start: Vec<u32>,
    places: Vec<u32>,
    /// The places the last gather listed, in order, and per place its entry in that list
    /// (`u32::MAX`: not listed).
    listed: Vec<u32>,
    entry: Vec<u32>,
    /// The last step gathered (`listed` holds what came back); false once a step did not.
    fresh: bool,
    written: LastWrite,
}

impl Gather {
    /// The kernel and buffers for `g`'s nodes of `m` on `d`'s device.
    fn new(d: &OnDevice, m: &Membrane, g: &DrawnGrid) -> Result<Gather, RenderError> {
        let gpu = d.k.gpu();
        let [layers, rows, cols] = g.parts();
        let (nr, nc) = (rows.len(), cols.len());
        let tiles = m.activity.as_ref().map_or(0, |a| a.awake.len());
        // Each place's row block and column (zeros outside the membrane: never listed), and
        // each tile's places.
        let mut nodes = vec![[0u32; 2]; g.len()];
        let mut of_tile: Vec<Vec<u32>> = vec![Vec::new(); tiles];
        for (k, &l) in layers.iter().enumerate() {
            for (r, &i) in rows.iter().enumerate() {
                for (q, &j) in cols.iter().enumerate() {
                    if l >= LAYERS || i >= m.rows || j >= m.cols {
                        continue;
                    }
                    let place = k * nr * nc + r * nc + q;
                    nodes[place] = [(l * m.rows + i) as u32, j as u32];
                    if let Some(list) = of_tile.get_mut(m.tile_of(i, j)) {
                        list.push(place as u32);
                    }
                }
            }
        }
        let mut start = Vec::with_capacity(tiles + 1);
        start.push(0u32);
        let mut places = Vec::with_capacity(g.len());
        for list in of_tile {
            places.extend(list);
            start.push(places.len() as u32);
        }
        let n = places.len().max(1);
        let module = compute::compile(
            &gpu.device,
            "shaders/membrane_sync.wgsl",
            super::SYNC_SHADER,
        )?;
        let pipeline = compute::pipeline(gpu, &module, "gather")?;
        let params = compute::uniform(
            gpu,
            "membrane gather params",
            bytemuck::bytes_of(&SyncParams::zeroed()),
        );
        let node_buffer =
            compute::storage(gpu, "membrane drawn nodes", bytemuck::cast_slice(&nodes))?;
        let list = compute::storage(gpu, "membrane gather list", &vec![0u8; 4 * n])?;
        let out = compute::storage(gpu, "membrane gathered", &vec![0u8; 12 * n])?;
        let readback = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("membrane gathered readback"),
            size: 12 * n as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let [a, b] = &d.k.state;
        let bind = bind(
            gpu,
            &pipeline,
            "membrane gather",
            &[
                (0, &params),
                (1, a),
                (2, b),
                (10, &node_buffer),
                (11, &list),
                (12, &out),
            ],
        );
        gpu.check()?;
        Ok(Gather {
            key: [layers.to_vec(), rows.to_vec(), cols.to_vec()],
            pipeline,
            params,
            bind,
            readback,
            out,
            list,
            start,
            places,
            listed: Vec::new(),
            entry: vec![u32::MAX; g.len()],
            fresh: false,
            written: LastWrite::default(),
        })
    }

    /// Whether this is laid out for `g`.
    fn is_for(&self, g: &DrawnGrid) -> bool {
        let [layers, rows, cols] = g.parts();
        self.key[0] == layers && self.key[1] == rows && self.key[2] == cols
    }

    /// Nothing gathered holds any longer (a step that did not gather).
    pub fn stale(&mut self) {
        self.fresh = false;
    }

    /// Encodes the gather of the drawn places of the awake tiles `awake` that do not come
    /// back with this step (`want` by tile; empty: every one comes back) from state buffer
    /// `current`, and its copy to the readback. The bytes that come back.
    pub fn encode(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        (awake, want): (&[u32], &[bool]),
        (rows, cols, current): (usize, usize, usize),
    ) -> u64 {
        for &p in &self.listed {
            if let Some(e) = self.entry.get_mut(p as usize) {
                *e = u32::MAX;
            }
        }
        self.listed.clear();
        if !want.is_empty() {
            for &t in awake {
                let t = t as usize;
                if want.get(t).copied().unwrap_or(true) {
                    continue;
                }
                if let (Some(&s), Some(&e)) = (self.start.get(t), self.start.get(t + 1)) {
                    self.listed
                        .extend_from_slice(&self.places[s as usize..e as usize]);
                }
            }
        }
        for (k, &p) in self.listed.iter().enumerate() {
            if let Some(e) = self.entry.get_mut(p as usize) {
                *e = k as u32;
            }
        }
        self.fresh = true;
        let n = self.listed.len() as u32;
        if n == 0 {
            return 0;
        }
        gpu.queue
            .write_buffer(&self.list, 0, bytemuck::cast_slice(&self.listed));
        let params = SyncParams {
            rows: rows as u32,
            cols: cols as u32,
            flag: current as u32,
            pad: n,
            ..SyncParams::zeroed()
        };
        self.written
            .write(gpu, &self.params, 0, bytemuck::bytes_of(&params));
        let groups = n.div_ceil(GROUP);
        let (x, y) = (groups.min(MOST_GROUPS), groups.div_ceil(MOST_GROUPS));
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("membrane gather drawn"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        let bytes = 12 * u64::from(n);
        encoder.copy_buffer_to_buffer(&self.out, 0, &self.readback, 0, bytes);
        bytes
    }

    /// The positions of `nodes` (each a node of `g` and its place) from the last gather,
    /// into `out`; none where it does not hold them all (another grid, stale, or a node it
    /// did not list).
    fn read(
        &self,
        gpu: &Gpu,
        g: &DrawnGrid,
        nodes: &[([usize; 3], usize)],
        out: &mut [Vec3],
    ) -> Option<Result<(), RenderError>> {
        if !self.fresh || !self.is_for(g) {
            return None;
        }
        let entries: Option<Vec<usize>> = nodes
            .iter()
            .map(|&(_, place)| {
                let e = *self.entry.get(place)?;
                (e != u32::MAX).then_some(e as usize)
            })
            .collect();
        let entries = entries?;
        let _span = tracing::debug_span!("membrane_gpu_gathered", nodes = nodes.len()).entered();
        let bytes = 12 * self.listed.len() as u64;
        Some(compute::with_mapped(
            gpu,
            &self.readback,
            bytes.max(4),
            |raw| {
                let raw = &raw[..bytes as usize];
                super::as_floats(raw, |v| {
                    for (&(_, place), &e) in nodes.iter().zip(&entries) {
                        let p = std::array::from_fn(|c| v.get(3 * e + c).copied().unwrap_or(0.0));
                        if let Some(o) = out.get_mut(place) {
                            *o = Vec3::from_array(p);
                        }
                    }
                })
            },
        ))
    }
}

impl Membrane {
    /// Frames draw grid `g` (where the membrane steps on a device with an active set): the
    /// device lays it out to gather its lagging nodes with the steps announced before frames.
    /// Nothing where it already does, or on the CPU; should the device refuse the kernel,
    /// frames read the runs as before, with a warning.
    pub(in crate::models::membrane) fn gather_drawn(&mut self, g: &DrawnGrid) {
        let Some(d) = self.device.on.as_deref() else {
            return;
        };
        if self.activity.is_none()
            || d.gather_refused
            || d.gather.as_ref().is_some_and(|x| x.is_for(g))
        {
            return;
        }
        let made = Gather::new(d, self, g);
        if let Some(d) = self.device.on.as_deref_mut() {
            d.gather_refused = made.is_err();
            d.gather = made
                .inspect_err(|e| {
                    tracing::warn!("frames read the membrane's lagging tiles whole: {e}");
                })
                .ok();
        }
    }

    /// [`Gather::read`] of the membrane's device: none where it has none or the last gather
    /// does not hold `nodes`.
    pub(in crate::models::membrane) fn gathered_positions(
        &self,
        g: &DrawnGrid,
        nodes: &[([usize; 3], usize)],
        out: &mut [Vec3],
    ) -> Option<Result<(), RenderError>> {
        let d = self.device.on.as_deref()?;
        d.gather.as_ref()?.read(d.k.gpu(), g, nodes, out)
    }
}
