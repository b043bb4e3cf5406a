//! The active set's sleep and wake checks on the device (`shaders/membrane_watch.wgsl`):
//! after the substeps, in the same submission, each awake tile's measures (its fastest node
//! relative to its anchor, its edge's departure, its box, whether its positions are all
//! finite) are taken on the device and read back, 36 bytes a tile, so the CPU decides which
//! tiles sleep and wake, and the quarantine whether the state is finite, without a pass over
//! the awake nodes. The device keeps each node's offset from its anchor at the last check
//! (`last`, which only the device writes while it steps the tile) and the offsets its tile
//! fell asleep with (`offset`); both go up from the CPU when they change there (a tile woke,
//! or fell asleep) and the device next needs them. Before the substeps the device also
//! places the halo (the sleeping tiles beside awake ones) at its anchors, so the halo's state
//! neither is placed on the CPU nor goes up: the CPU's copy of a sleeping tile lags until the
//! tile wakes (the frames draw it where its anchors carry it: `Membrane::carried_position`).

use super::super::active::{Activity, TILE_COLS, TILE_ROWS, Watch};
use super::super::{LAYERS, Membrane};
use super::one_pass;
use crate::gpu::compute::{self, LastWrite, bind};
use crate::gpu::{Gpu, RenderError};
use glam::Vec3;

const SHADER: &str = include_str!("../../../shaders/membrane_watch.wgsl");
/// Nodes of a tile in one layer.
const TILE: usize = TILE_ROWS * TILE_COLS;
/// Floats a tile's measures take, and a tile's watch start (offset and last, all layers).
const MEASURES: usize = 9;
const START_PER_TILE: usize = LAYERS * TILE * 6;

/// The shader's `Watch` (16 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    rows: u32,
    cols: u32,
    tiles_c: u32,
    dt: f32,
}

/// The checks' kernels and buffers.
pub(super) struct Watcher {
    watch: wgpu::ComputePipeline,
    start: wgpu::ComputePipeline,
    place: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    /// Bind group `s` reads state buffer `s`.
    watch_bind: [wgpu::BindGroup; 2],
    start_bind: wgpu::BindGroup,
    place_bind: wgpu::BindGroup,
    start_list: wgpu::Buffer,
    place_list: wgpu::Buffer,
    measures: wgpu::Buffer,
    packed: wgpu::Buffer,
    /// Per tile: the device holds its offsets and last offsets.
    held: Vec<bool>,
    up: Vec<f32>,
    tiles_c: u32,
    /// The step's length in the parameters (only the watch reads it), and what went into
    /// the parameters and the halo's list last (not written again unchanged).
    dt: f32,
    params_written: LastWrite,
    place_written: LastWrite,
}

impl Watcher {
    /// The kernels over a membrane's state buffers `state` and attachments `attach`, with
    /// the rest shape and weights of its active set `a`.
    pub fn new(
        gpu: &Gpu,
        a: &Activity,
        state: &[wgpu::Buffer; 2],
        (attach, list): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> Result<Watcher, RenderError> {
        let module = compute::compile(&gpu.device, "shaders/membrane_watch.wgsl", SHADER)?;
        let watch = compute::pipeline(gpu, &module, "watch")?;
        let start = compute::pipeline(gpu, &module, "start")?;
        let place = compute::pipeline(gpu, &module, "place")?;
        let tiles = a.awake.len().max(1);
        let zeros = |n: usize| vec![0u8; 4 * n.max(1)];
        let rest = compute::storage(gpu, "membrane rest", bytemuck::cast_slice(&a.rest))?;
        let weight = compute::storage(gpu, "membrane weights", bytemuck::cast_slice(&a.weight))?;
        // The CPU's offsets and last offsets now: the device holds every tile's.
        let offset = compute::storage(gpu, "membrane offsets", bytemuck::cast_slice(&a.offset))?;
        let last = compute::storage(gpu, "membrane last offsets", bytemuck::cast_slice(&a.last))?;
        let start_list = compute::storage(gpu, "membrane started tiles", &zeros(tiles))?;
        let place_list = compute::storage(gpu, "membrane placed tiles", &zeros(tiles))?;
        let measures = compute::storage(gpu, "membrane measures", &zeros(tiles * MEASURES))?;
        let packed =
            compute::storage(gpu, "membrane watch starts", &zeros(tiles * START_PER_TILE))?;
        let params = compute::uniform(gpu, "membrane watch params", &[0u8; 16]);
        let watch_bind = [0usize, 1].map(|s| {
            bind(
                gpu,
                &watch,
                "membrane watch",
                &[
                    (0, &params),
                    (1, &state[s]),
                    (2, attach),
                    (3, &rest),
                    (4, &weight),
                    (5, &offset),
                    (6, &last),
                    (7, list),
                    (8, &measures),
                ],
            )
        });
        let start_bind = bind(
            gpu,
            &start,
            "membrane watch start",
            &[
                (0, &params),
                (5, &offset),
                (6, &last),
                (7, &start_list),
                (8, &packed),
            ],
        );
        let place_bind = bind(
            gpu,
            &place,
            "membrane halo placing",
            &[
                (0, &params),
                (2, attach),
                (3, &rest),
                (4, &weight),
                (5, &offset),
                (7, &place_list),
                (9, &state[0]),
                (10, &state[1]),
            ],
        );
        gpu.check()?;
        Ok(Watcher {
            watch,
            start,
            place,
            params,
            watch_bind,
            start_bind,
            place_bind,
            start_list,
            place_list,
            measures,
            packed,
            held: vec![true; a.awake.len()],
            up: Vec::new(),
            tiles_c: a.tiles_c as u32,
            dt: 0.0,
            params_written: LastWrite::default(),
            place_written: LastWrite::default(),
        })
    }

    /// Tile `t`'s offsets or last offsets changed on the CPU (it woke, or fell asleep): they
    /// go up when the device next needs them.
    pub fn changed(&mut self, t: usize) {
        if let Some(h) = self.held.get_mut(t) {
            *h = false;
        }
    }

    fn write_params(&mut self, gpu: &Gpu, m: &Membrane) {
        let params = Params {
            rows: m.rows as u32,
            cols: m.cols as u32,
            tiles_c: self.tiles_c,
            dt: self.dt,
        };
        let bytes = bytemuck::bytes_of(&params);
        self.params_written.write(gpu, &self.params, 0, bytes);
    }

    /// Before a step's substeps, into `encoder`: the offsets of the awake tiles `awake` and
    /// the halo `halo` the device lacks go up from `a`, and the halo is placed at its
    /// anchors.
    pub fn encode_before(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        (m, a): (&Membrane, &Activity),
        (awake, halo): (&[u32], &[usize]),
    ) {
        self.write_params(gpu, m);
        let halo: Vec<u32> = halo.iter().map(|&t| t as u32).collect();
        let starting: Vec<u32> = awake
            .iter()
            .chain(&halo)
            .copied()
            .filter(|&t| !self.held.get(t as usize).copied().unwrap_or(true))
            .collect();
        if !starting.is_empty() {
            self.pack_starts(m, a, &starting);
            gpu.queue
                .write_buffer(&self.start_list, 0, bytemuck::cast_slice(&starting));
            gpu.queue
                .write_buffer(&self.packed, 0, bytemuck::cast_slice(&self.up));
            let groups = [starting.len() as u32, 1, 1];
            one_pass(
                encoder,
                "membrane offsets up",
                (&self.start, &self.start_bind),
                groups,
            );
            for &t in &starting {
                self.held[t as usize] = true;
            }
        }
        if !halo.is_empty() {
            let list = bytemuck::cast_slice(&halo);
            self.place_written.write(gpu, &self.place_list, 0, list);
            let groups = [halo.len() as u32, 1, 1];
            one_pass(
                encoder,
                "membrane halo placing",
                (&self.place, &self.place_bind),
                groups,
            );
        }
    }

    /// After a step of `dt` whose newest state is in state buffer `current`, into
    /// `encoder`: the awake tiles `awake` measured. The list of them is the one the
    /// substeps read, written for this step.
    pub fn encode_watch(
        &mut self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        m: &Membrane,
        (awake, current, dt): (&[u32], usize, f32),
    ) {
        self.dt = dt;
        self.write_params(gpu, m);
        let bind = &self.watch_bind[current.min(1)];
        one_pass(
            encoder,
            "membrane watch",
            (&self.watch, bind),
            [awake.len() as u32, 1, 1],
        );
    }

    /// The CPU's offsets and last offsets of tiles `tiles`, packed as the start kernel reads
    /// them.
    fn pack_starts(&mut self, m: &Membrane, a: &Activity, tiles: &[u32]) {
        let (rows, cols) = (m.rows, m.cols);
        self.up.clear();
        self.up.resize(tiles.len() * START_PER_TILE, 0.0);
        for (r, &t) in tiles.iter().enumerate() {
            let ([r0, r1], [c0, c1]) = a.span(t as usize, rows, cols);
            for l in 0..LAYERS {
                for i in r0..r1 {
                    let b = l * rows + i;
                    for j in c0..c1 {
                        let n = ((r * LAYERS + l) * TILE + (i - r0) * TILE_COLS + (j - c0)) * 6;
                        for c in 0..3 {
                            let at = (b * 3 + c) * cols + j;
                            self.up[n + c] = a.offset[at];
                            self.up[n + 3 + c] = a.last[at];
                        }
                    }
                }
            }
        }
    }

    /// Bytes the measures of `tiles` tiles take.
    pub fn bytes(tiles: usize) -> u64 {
        (tiles * MEASURES * 4) as u64
    }

    /// The measures of the first `tiles` tiles copied into `to` at `at`.
    pub fn copy(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        to: &wgpu::Buffer,
        at: u64,
        tiles: usize,
    ) {
        if tiles > 0 {
            encoder.copy_buffer_to_buffer(&self.measures, 0, to, at, Self::bytes(tiles));
        }
    }

    /// The measures read back (`raw`), a tile each.
    pub fn read(raw: &[u8]) -> Vec<Watch> {
        super::pack::as_floats(raw, |v| {
            v.chunks_exact(MEASURES)
                .map(|s| Watch {
                    fastest: s[0],
                    edge: s[1],
                    lo: Vec3::new(s[2], s[3], s[4]),
                    hi: Vec3::new(s[5], s[6], s[7]),
                    finite: s[8] == 0.0,
                })
                .collect()
        })
    }
}
