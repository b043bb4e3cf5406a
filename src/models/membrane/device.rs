//! The membrane stepped on a GPU inside a world: the CPU keeps the model (the active set,
//! the couplings' reads and writes, checkpoints, the hash) and the device runs the explicit
//! substeps of the awake tiles (`substep_tiles` in `shaders/membrane.wgsl`).
//!
//! Each step: layer 0's targets of the awake tiles and the sleeping tiles beside them (the
//! halo) are placed on the device from the chain's pose where the membrane has one
//! (`device_chain.rs`), else go up packed; the state (into both of the device's state
//! buffers) and springs of those tiles go up where the device lacks them: tiles that woke
//! since, and tiles whose springs a cut changed (the device places the halo at its anchors
//! itself: `device_watch.rs`); an awake tile's state came back from the device last step and
//! is not sent again (the bytes are the same: tested). The
//! substeps run; the awake tiles come back packed (`shaders/membrane_sync.wgsl`). All of it
//! is one submission and one readback into a buffer kept for it. A tile outside that set is
//! read by no awake node, so what the device holds for it may lag the CPU until it joins the
//! set. Anything else that rewrites the model (a rollback, a detached layer) sends everything
//! up at the next step.
//!
//! Should the device fail (lost, out of memory, a command refused), the step runs on the
//! CPU from the state the CPU holds, which the failed step has not touched, the device is
//! dropped and the failure is reported once as an event: the session goes on.

use super::active::{Activity, TILE_COLS, TILE_ROWS, Watch};
use super::gpu::MembraneGpu;
use super::{LAYERS, Membrane, field};
use crate::gpu::compute::{self, bind};
use crate::gpu::{Gpu, RenderError};
use bytemuck::Zeroable;

#[path = "device_chain.rs"]
mod carry;
#[path = "device_drawn.rs"]
mod drawn;
#[path = "device_lazy.rs"]
mod lazy;
#[path = "device_pack.rs"]
mod pack;
#[path = "device_sums.rs"]
mod sums;
#[cfg(test)]
#[path = "device_switches.rs"]
mod switches;
#[path = "device_watch.rs"]
mod watch;

use pack::{Run, SyncParams, Written, as_floats, one_pass, run_places, unpack};

const SYNC_SHADER: &str = include_str!("../../../shaders/membrane_sync.wgsl");
/// Nodes of a tile in one layer (the kernels' workgroup).
const TILE: usize = TILE_ROWS * TILE_COLS;
const _: () = assert!(TILE == 128, "the kernels' workgroups are 8 x 16 nodes");
/// Floats a tile packs: state (6 a node), springs (9), layer 0's attachments (4).
const STATE_PER_TILE: usize = LAYERS * TILE * 6;
const SPRINGS_PER_TILE: usize = LAYERS * TILE * field::COUNT;
const ATTACH_PER_TILE: usize = TILE * 4;

/// The membrane's place on a device, or none: what a [`Membrane`] holds. A clone runs on
/// the CPU (two models must not share one device's buffers) from the CPU's copy: bring it
/// up to date first ([`Membrane::catch_up`]).
#[derive(Default)]
pub(super) struct Slot {
    on: Option<Box<OnDevice>>,
    /// Why the device was given up, until the model reports it.
    pub note: Option<String>,
}

impl Clone for Slot {
    fn clone(&self) -> Self {
        Slot::default()
    }
}

impl std::fmt::Debug for Slot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.on {
            Some(d) => write!(f, "on {}", d.k.gpu().describe()),
            None => f.write_str("on the CPU"),
        }
    }
}

impl Slot {
    /// A cut changed springs: with the whole membrane on the device, all of them go up with
    /// the next step; with the active set, those of the tiles the cut marked
    /// ([`Slot::tile_springs_changed`]).
    pub fn springs_changed(&mut self) {
        if let Some(d) = &mut self.on {
            d.springs_changed = true;
        }
    }

    /// The groups whose loads are summed changed: their buffers are made anew at the next
    /// step.
    pub fn groups_changed(&mut self) {
        if let Some(d) = &mut self.on {
            d.sums = None;
            d.sums_tried = false;
        }
    }

    /// Tile `t`'s offsets or last offsets changed on the CPU (it woke, or fell asleep):
    /// they go up when the device next needs them.
    pub fn offsets_changed(&mut self, t: usize) {
        if let Some(w) = self.on.as_mut().and_then(|d| d.watcher.as_mut()) {
            w.changed(t);
        }
    }

    /// The chain that places layer 0's targets changed: its bindings go up anew.
    pub fn chain_changed(&mut self) {
        if let Some(d) = &mut self.on {
            d.carrier = None;
            d.carrier_tried = false;
        }
    }

    /// Whether the device places layer 0's targets from the chain's pose itself (the CPU
    /// places them only where it reads them: see `chain.rs`).
    pub fn places_targets(&self) -> bool {
        self.on.as_ref().is_some_and(|d| d.carries())
    }

    /// Whether the device places the halo itself (the CPU then leaves it be unless the
    /// device fails).
    pub fn places_halo(&self) -> bool {
        self.on
            .as_ref()
            .is_some_and(|d| d.watcher.is_some() && !d.cpu_places_halo)
    }

    /// The CPU rewrote the model: everything goes up with the next step (the CPU's copy is
    /// the model: a caller that keeps what the device holds brings it up to date first, see
    /// [`Membrane::catch_up`]).
    pub fn stale(&mut self) {
        if let Some(d) = &mut self.on {
            d.whole_stale = true;
            d.books.none_behind();
        }
    }

    /// The CPU wrote tile `t`'s state (placed it at its anchors): it goes up when the tile
    /// next joins the active set.
    pub fn tile_changed(&mut self, t: usize) {
        if let Some(d) = &mut self.on {
            if let Some(h) = d.held.get_mut(t) {
                *h = false;
            }
            d.all_held = false;
        }
    }

    /// A cut changed springs of tile `t`: they go up, with its state, when the tile next joins
    /// the active set.
    pub fn tile_springs_changed(&mut self, t: usize) {
        self.tile_changed(t);
        if let Some(h) = self.on.as_mut().and_then(|d| d.springs_held.get_mut(t)) {
            *h = false;
        }
    }

    /// The adapter, where the model runs on one.
    pub fn adapter(&self) -> Option<String> {
        self.on.as_ref().map(|d| d.k.gpu().describe())
    }

    /// The device given up for `e`, to be reported.
    fn give_up(&mut self, e: &RenderError) {
        self.on = None;
        self.note = Some(e.to_string());
    }
}

/// The kernels and buffers of a membrane on a device.
struct OnDevice {
    k: MembraneGpu,
    tiles_pipeline: wgpu::ComputePipeline,
    /// Bind group `k` reads state buffer `k` (as the flat kernel's do) and the awake list.
    tiles_bind: [wgpu::BindGroup; 2],
    unpack: wgpu::ComputePipeline,
    pack: wgpu::ComputePipeline,
    /// The unpack's and the pack's parameters (one submission holds both passes).
    sync_params: wgpu::Buffer,
    pack_params: wgpu::Buffer,
    /// Where the packed awake tiles are copied to be read (mappable, reused every step),
    /// after the anchor sums where there are any.
    readback: wgpu::Buffer,
    /// Layer 0's loads summed by group (`device_sums.rs`), once tried; the bytes they take
    /// at the start of the readback.
    sums: Option<sums::Sums>,
    sums_tried: bool,
    sums_bytes: u64,
    /// The active set's sleep and wake checks (`device_watch.rs`), with an active set.
    watcher: Option<watch::Watcher>,
    awake_list: wgpu::Buffer,
    sync_list: wgpu::Buffer,
    packed_state: wgpu::Buffer,
    packed_springs: wgpu::Buffer,
    packed_attach: wgpu::Buffer,
    /// Each awake tile's place in the packed state coming back (`device_pack.rs`), and the
    /// runs of tiles it packs by (made each step, the buffers reused).
    pack_places: wgpu::Buffer,
    places: Vec<[u32; 4]>,
    runs: Vec<Run>,
    /// Which awake tiles the CPU's copy lags, and which it read (`device_lazy.rs`).
    books: lazy::Books,
    /// The drawn grid whose lagging nodes a step before a frame gathers (`device_drawn.rs`),
    /// once a frame drew one; whether the device refused its kernel.
    gather: Option<drawn::Gather>,
    gather_refused: bool,
    unpack_bind: wgpu::BindGroup,
    pack_bind: wgpu::BindGroup,
    tiles_c: u32,
    springs_changed: bool,
    whole_stale: bool,
    /// Per tile of the active set: the device holds the CPU's state for it (it came back
    /// from the device, or went up, and the CPU has not written it since); such a tile's
    /// state does not go up again.
    held: Vec<bool>,
    /// Per tile: the device holds the CPU's springs for it (a tile a cut changed does not;
    /// such a tile is not `held` either, so its springs go up with its state).
    springs_held: Vec<bool>,
    /// The device holds the CPU's whole state (after a whole step's download).
    all_held: bool,
    /// Send every synced tile's state up each step, held or not (to compare; tests).
    resend: bool,
    /// Leave the halo to the CPU, as before the device placed it (to compare; tests).
    cpu_places_halo: bool,
    /// Layer 0's targets placed from the chain's pose on the device (`device_chain.rs`),
    /// once tried; or left to the CPU, as before the device placed them (to compare; tests).
    carrier: Option<carry::Carrier>,
    carrier_tried: bool,
    cpu_places_targets: bool,
    /// Tiles whose state went up, and tiles whose attachments went up, over the device's
    /// life (tests' counts).
    tiles_sent: u64,
    attach_sent: u64,
    /// CPU-side packing buffers, reused.
    up_state: Vec<f32>,
    up_springs: Vec<f32>,
    up_attach: Vec<f32>,
    /// What the small buffers the CPU writes every step last held (not written again
    /// unchanged).
    written: Written,
}

/// The mappable buffer the step's results are read from: `sums` bytes of anchor sums, then
/// up to `tiles` tiles' measures, then up to `tiles` tiles' packed state.
fn readback_buffer(gpu: &Gpu, sums: u64, tiles: usize) -> wgpu::Buffer {
    let tiles = tiles.max(1);
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("membrane readback"),
        size: sums + watch::Watcher::bytes(tiles) + (tiles * STATE_PER_TILE * 4) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    })
}

impl OnDevice {
    fn new(gpu: &Gpu, m: &Membrane) -> Result<OnDevice, RenderError> {
        if let Some(a) = &m.activity
            && (a.params.tile_rows, a.params.tile_cols) != (TILE_ROWS, TILE_COLS)
        {
            return Err(RenderError::Unsupported(format!(
                "its kernels step tiles of {TILE_ROWS} x {TILE_COLS} nodes, this membrane's \
                 active set has tiles of {} x {}",
                a.params.tile_rows, a.params.tile_cols
            )));
        }
        let k = MembraneGpu::new(gpu, m)?;
        let tiles = m.activity.as_ref().map_or(1, |a| a.awake.len()).max(1);
        let module = compute::compile(&gpu.device, "shaders/membrane.wgsl", super::gpu::SHADER)?;
        let tiles_pipeline = compute::pipeline(gpu, &module, "substep_tiles")?;
        let sync = compute::compile(&gpu.device, "shaders/membrane_sync.wgsl", SYNC_SHADER)?;
        let unpack = compute::pipeline(gpu, &sync, "unpack")?;
        let pack = compute::pipeline(gpu, &sync, "pack")?;
        let zeros = |n: usize| vec![0u8; 4 * n];
        let awake_list = compute::storage(gpu, "membrane awake tiles", &zeros(tiles))?;
        let sync_list = compute::storage(gpu, "membrane synced tiles", &zeros(tiles))?;
        let packed_state =
            compute::storage(gpu, "membrane packed state", &zeros(tiles * STATE_PER_TILE))?;
        let packed_springs = compute::storage(
            gpu,
            "membrane packed springs",
            &zeros(tiles * SPRINGS_PER_TILE),
        )?;
        let packed_attach = compute::storage(
            gpu,
            "membrane packed attachments",
            &zeros(tiles * ATTACH_PER_TILE),
        )?;
        let pack_places = compute::storage(gpu, "membrane packed places", &zeros(tiles * 4))?;
        let zero = SyncParams::zeroed();
        let sync_params =
            compute::uniform(gpu, "membrane unpack params", bytemuck::bytes_of(&zero));
        let pack_params = compute::uniform(gpu, "membrane pack params", bytemuck::bytes_of(&zero));
        let readback = readback_buffer(gpu, 0, tiles);
        let watcher = match &m.activity {
            Some(a) => Some(watch::Watcher::new(
                gpu,
                a,
                &k.state,
                (&k.attach, &awake_list),
            )?),
            None => None,
        };
        let [a, b] = &k.state;
        let tiles_bind = Self::tiles_bind(gpu, &tiles_pipeline, &k, &awake_list);
        let unpack_bind = bind(
            gpu,
            &unpack,
            "membrane unpack",
            &[
                (0, &sync_params),
                (1, a),
                (2, b),
                (3, &k.springs),
                (4, &k.attach),
                (5, &sync_list),
                (6, &packed_state),
                (7, &packed_springs),
                (8, &packed_attach),
            ],
        );
        let pack_bind = bind(
            gpu,
            &pack,
            "membrane pack",
            &[
                (0, &pack_params),
                (1, a),
                (2, b),
                (5, &awake_list),
                (6, &packed_state),
                (9, &pack_places),
            ],
        );
        gpu.check()?;
        Ok(OnDevice {
            tiles_c: m.activity.as_ref().map_or(1, |a| a.tiles_c) as u32,
            k,
            tiles_pipeline,
            tiles_bind,
            unpack,
            pack,
            sync_params,
            pack_params,
            readback,
            sums: None,
            sums_tried: false,
            sums_bytes: 0,
            watcher,
            awake_list,
            sync_list,
            packed_state,
            packed_springs,
            packed_attach,
            pack_places,
            places: Vec::new(),
            runs: Vec::new(),
            books: lazy::Books::new(m.activity.as_ref().map_or(1, |a| a.awake.len())),
            gather: None,
            gather_refused: false,
            unpack_bind,
            pack_bind,
            springs_changed: false,
            whole_stale: true,
            held: vec![false; m.activity.as_ref().map_or(0, |a| a.awake.len())],
            springs_held: vec![false; m.activity.as_ref().map_or(0, |a| a.awake.len())],
            all_held: false,
            resend: false,
            cpu_places_halo: false,
            carrier: None,
            carrier_tried: false,
            cpu_places_targets: false,
            tiles_sent: 0,
            attach_sent: 0,
            up_state: Vec::new(),
            up_springs: Vec::new(),
            up_attach: Vec::new(),
            written: Written::default(),
        })
    }

    /// The tile kernel's two bind groups: bind group `s` reads state buffer `s`, as the flat
    /// kernel's do, and the awake list.
    fn tiles_bind(
        gpu: &Gpu,
        pipeline: &wgpu::ComputePipeline,
        k: &MembraneGpu,
        awake_list: &wgpu::Buffer,
    ) -> [wgpu::BindGroup; 2] {
        [0usize, 1].map(|s| {
            bind(
                gpu,
                pipeline,
                "membrane tile substep",
                &[
                    (0, &k.params),
                    (1, &k.state[s]),
                    (2, &k.state[1 - s]),
                    (3, &k.springs),
                    (4, &k.attach),
                    (5, &k.beta),
                    (6, &k.externals),
                    (7, awake_list),
                ],
            )
        })
    }

    /// Everything up: the state into both buffers, the springs, the damping, the
    /// attachments.
    fn upload_whole(&mut self, m: &Membrane) {
        let q = &self.k.gpu().queue;
        for s in &self.k.state {
            q.write_buffer(s, 0, bytemuck::cast_slice(&m.state.data));
        }
        self.k.upload_springs(m);
        self.k.upload_attachments(m);
        self.whole_stale = false;
        self.springs_changed = false;
        self.held.iter_mut().for_each(|h| *h = true);
        self.springs_held.iter_mut().for_each(|h| *h = true);
        self.all_held = true;
    }

    /// Whether this device places layer 0's targets from a chain's pose.
    fn carries(&self) -> bool {
        self.watcher.is_some() && !self.cpu_places_targets
    }

    /// The active set's substeps on the device: the awake tiles of `a` (and the halo
    /// `halo`, sleeping beside them) up, `substeps` substeps of `dt / substeps` under `m`'s
    /// external forces, the awake tiles back into `m`.
    fn active_step(
        &mut self,
        m: &mut Membrane,
        a: &Activity,
        halo: &[usize],
        dt: f32,
        substeps: usize,
    ) -> Result<Measured, RenderError> {
        if self.whole_stale {
            self.upload_whole(m);
        }
        // A checkpoint follows: the tiles this step leaves lagging come back too, into the
        // checkpoint's copy (every awake tile into the CPU's where that copy cannot take them
        // by tile, or every tile comes back anyway).
        let books = &mut self.books;
        let to_saved = std::mem::take(&mut books.checkpoint_next);
        let to_saved_ok = !books.once && !books.eager && !self.resend && m.saved_takes_tiles();
        books.once |= to_saved && !to_saved_ok;
        let to_saved = to_saved && to_saved_ok;
        books.lagging_in_saved = false;
        // A frame follows: the drawn nodes of the tiles left lagging are gathered for it
        // (`device_drawn.rs`), or where no grid is laid out yet, every run goes to the
        // readback too (the lagging ones stay there). A checkpoint takes every run anyway.
        let frame = std::mem::take(&mut books.frame_next);
        let gathers = frame && !to_saved && self.gather.is_some();
        let copy_all = to_saved || (frame && !gathers);
        books.in_readback = None;
        if let Some(g) = &mut self.gather {
            g.stale();
        }
        self.make_sums(m, a)?;
        let awake: &[u32] = &a.list;
        let _span = tracing::debug_span!(
            "membrane_on_gpu",
            awake_tiles = awake.len(),
            halo_tiles = halo.len(),
            substeps
        )
        .entered();
        // The tiles whose springs the device lacks first, then the rest of those whose state
        // it lacks (a tile whose springs changed is among those): only theirs go up. Where
        // the device places the halo, no halo tile's state goes up for its own sake.
        let placed = self.watcher.is_some() && !self.cpu_places_halo;
        let all = || {
            let awake = awake.iter().map(|&t| (t, false));
            awake.chain(halo.iter().map(|&t| (t as u32, true)))
        };
        let resend = self.resend;
        let lacks = |of: &[bool], t: u32| resend || !of.get(t as usize).copied().unwrap_or(false);
        let (held, springs_held) = (&self.held, &self.springs_held);
        let class = |(t, in_halo): (u32, bool)| {
            if lacks(springs_held, t) {
                0
            } else if lacks(held, t) && !(in_halo && placed) {
                1
            } else {
                2
            }
        };
        let of = |c: u8| all().filter(move |&k| class(k) == c).map(|(t, _)| t);
        let mut sync: Vec<u32> = of(0).collect();
        let springs_tiles = sync.len();
        sync.extend(of(1));
        let state_tiles = sync.len();
        sync.extend(of(2));
        self.tiles_sent += state_tiles as u64;
        let gpu = self.k.gpu().clone();
        // One submission: the tiles up, the substeps, the awake tiles packed and copied to
        // the readback buffer.
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("membrane active step"),
            });
        // The tiles a cut changed were marked (`Slot::tile_springs_changed`): their springs
        // go up with their state, and no other tile's.
        self.springs_changed = false;
        {
            let _up = tracing::debug_span!("membrane_gpu_pack_up", tiles = sync.len()).entered();
            self.encode_up(m, a, (&sync, state_tiles, springs_tiles), &mut encoder)?;
        }
        // From here the device holds every synced tile as the CPU does (the awake ones come
        // back below), and not necessarily anything else.
        for &t in &sync {
            if let Some(h) = self.held.get_mut(t as usize) {
                *h = true;
            }
            if let Some(h) = self.springs_held.get_mut(t as usize) {
                *h = true;
            }
        }
        self.all_held = false;
        // Encoding the rest of the submission, and submitting it.
        let encoding = tracing::debug_span!("membrane_gpu_encode").entered();
        // The offsets the device lacks up, the halo placed at its anchors.
        if let Some(w) = &mut self.watcher {
            let halo = if placed { halo } else { &[] };
            w.encode_before(&gpu, &mut encoder, (m, a), (awake, halo));
        }
        if awake.is_empty() {
            super::anchor_sums::none_awake(m);
            m.external.clear();
            gpu.queue.submit([encoder.finish()]);
            return gpu.check().map(|()| Some(Vec::new()));
        }
        let list = bytemuck::cast_slice(awake);
        self.written.awake.write(&gpu, &self.awake_list, 0, list);
        // A tile's four layers one after another (`substep_tiles`).
        let groups = (LAYERS as u32, awake.len() as u32, 1);
        let (count, grown) = self.k.upload_externals(m)?;
        if grown {
            self.tiles_bind =
                Self::tiles_bind(&gpu, &self.tiles_pipeline, &self.k, &self.awake_list);
            if let Some(s) = &mut self.sums {
                s.rebind(&gpu, &self.k);
            }
        }
        // Layer 0's loads by group, from the state the substeps start from.
        if let Some(s) = &mut self.sums {
            s.encode(&gpu, &mut encoder, self.k.current, awake);
            s.copy(&mut encoder, &self.readback);
        }
        let tiles = super::gpu::TileDispatch {
            pipeline: &self.tiles_pipeline,
            bind: &self.tiles_bind,
            groups,
            tiles_c: self.tiles_c,
        };
        {
            let _s = tracing::debug_span!("membrane_gpu_substeps").entered();
            self.k
                .encode_substeps(&mut encoder, m, dt, substeps, count, Some(tiles));
        }
        // The awake tiles back: packed from the newest state buffer (its own parameters:
        // the unpack's are in the same submission).
        let params = SyncParams {
            rows: m.rows as u32,
            cols: m.cols as u32,
            tiles_c: self.tiles_c,
            flag: self.k.current as u32,
            ..SyncParams::zeroed()
        };
        let bytes = bytemuck::bytes_of(&params);
        self.written
            .pack_params
            .write(&gpu, &self.pack_params, 0, bytes);
        // Every awake tile packed, those the CPU reads next first: only they come back.
        self.books.wanted(a, dt, self.resend);
        let want = std::mem::take(&mut self.books.want);
        let (all_floats, wanted_floats) = run_places(
            m,
            a,
            &want,
            (&mut self.runs, &mut self.places, &mut self.books.run_of),
        );
        let floats = if copy_all { all_floats } else { wanted_floats };
        self.books.want = want;
        let places = bytemuck::cast_slice(&self.places);
        self.written
            .places
            .write(&gpu, &self.pack_places, 0, places);
        let groups = [awake.len() as u32, LAYERS as u32, 1];
        one_pass(
            &mut encoder,
            "membrane pack",
            (&self.pack, &self.pack_bind),
            groups,
        );
        // The sleep and wake checks' measures of the awake tiles, on the newest state.
        let measured = match &mut self.watcher {
            Some(w) => {
                w.encode_watch(&gpu, &mut encoder, m, (awake, self.k.current, dt));
                w.copy(&mut encoder, &self.readback, self.sums_bytes, awake.len());
                Some(watch::Watcher::bytes(awake.len()))
            }
            None => None,
        };
        let bytes = (floats * 4) as u64;
        let at = self.sums_bytes + measured.unwrap_or(0);
        if bytes > 0 {
            encoder.copy_buffer_to_buffer(&self.packed_state, 0, &self.readback, at, bytes);
        }
        let gathered = match self.gather.as_mut().filter(|_| gathers) {
            Some(g) => g.encode(
                &gpu,
                &mut encoder,
                (awake, &self.books.want),
                (m.rows, m.cols, self.k.current),
            ),
            None => 0,
        };
        self.books.last_readback_bytes = bytes + gathered;
        {
            let _s = tracing::debug_span!("membrane_gpu_submit").entered();
            gpu.queue.submit([encoder.finish()]);
        }
        drop(encoding);
        // Read where the device left it (no copy), once the device reported no error.
        let sums_bytes = self.sums_bytes as usize;
        let back: Vec<Run> = self.runs.iter().filter(|r| r.wanted).copied().collect();
        let lagging: Vec<Run> = if to_saved {
            self.runs.iter().filter(|r| !r.wanted).copied().collect()
        } else {
            Vec::new()
        };
        let sums = self.sums.as_ref();
        let wait = tracing::debug_span!("membrane_gpu_readback", bytes).entered();
        let mapped = (at + bytes).max(4);
        let (measures, into_saved) = compute::with_mapped(&gpu, &self.readback, mapped, |raw| {
            let raw = &raw[..(at + bytes) as usize];
            drop(wait);
            let (s, rest) = raw.split_at(sums_bytes);
            let (measures, state) = rest.split_at(measured.unwrap_or(0) as usize);
            if let Some(sums_of) = sums {
                sums_of.read_into(s, &mut m.anchor_sums);
            }
            let measures = measured.map(|_| watch::Watcher::read(measures));
            // The lagging tiles go into the checkpoint's copy only where every awake tile is
            // finite: else the quarantine goes back to that copy as it stands.
            let finite = measures
                .as_ref()
                .is_some_and(|w| w.iter().all(|w| w.finite));
            let into_saved = to_saved && finite;
            let _unpack = tracing::debug_span!("membrane_gpu_unpack", runs = back.len()).entered();
            let dims = (m.rows, m.cols);
            as_floats(state, |v| {
                unpack(dims, &mut m.state.data, &back, v);
                if let Some(saved) = m.saved_nodes().filter(|_| into_saved) {
                    unpack(dims, saved, &lagging, v);
                }
            });
            (measures, into_saved)
        })?;
        self.books.stepped(awake, &self.runs);
        self.books.lagging_in_saved = into_saved;
        self.books.in_readback = copy_all.then_some(at);
        Ok(measures)
    }

    /// The anchor sums' kernel, the first time the membrane has groups (and the readback
    /// grown to hold their sums before the tiles).
    fn make_sums(&mut self, m: &Membrane, a: &Activity) -> Result<(), RenderError> {
        let Some(g) = m.anchor_groups.as_deref().filter(|_| !self.sums_tried) else {
            return Ok(());
        };
        self.sums_tried = true;
        let gpu = self.k.gpu().clone();
        self.sums = sums::Sums::new(&gpu, &self.k, g, a.awake.len())?;
        self.sums_bytes = self.sums.as_ref().map_or(0, sums::Sums::bytes);
        self.readback = readback_buffer(&gpu, self.sums_bytes, a.awake.len());
        Ok(())
    }

    /// Every node's substeps on the device (no active set, or every tile kept awake): the
    /// state and the attachments up, the flat kernel, the state back.
    fn whole_step(
        &mut self,
        m: &mut Membrane,
        dt: f32,
        substeps: usize,
    ) -> Result<(), RenderError> {
        if let Some(g) = &mut self.gather {
            g.stale();
        }
        // Springs a cut changed in a tile the active set has not sent since go up too.
        let springs_lag = self.springs_held.iter().any(|h| !h);
        if self.whole_stale || self.springs_changed || springs_lag {
            self.upload_whole(m);
        } else {
            if self.resend || !self.all_held {
                self.k.upload_state(m);
            }
            self.k.upload_attachments(m);
        }
        self.k.advance(m, dt, substeps)?;
        self.k.download(m)?;
        self.all_held = true;
        self.held.iter_mut().for_each(|h| *h = true);
        Ok(())
    }
}

impl Membrane {
    /// Steps this membrane's substeps on `gpu` from now on (the CPU keeps the model; see
    /// `device.rs`). An error names what the device refused; the membrane stays on the CPU.
    pub fn use_gpu(&mut self, gpu: &Gpu) -> Result<(), RenderError> {
        let d = OnDevice::new(gpu, self)?;
        // A checkpoint to go back to should the device fail while it holds the newest state
        // of some tiles (`device_lazy.rs`).
        if self.saved.is_none() {
            crate::sim::TissueModel::checkpoint(self);
        }
        self.device.on = Some(Box::new(d));
        Ok(())
    }

    /// The adapter the substeps run on; none on the CPU.
    pub fn gpu_adapter(&self) -> Option<String> {
        self.device.adapter()
    }
}

/// The active set's substeps of this step on the membrane's device, with the awake tiles'
/// sleep measures where the device took them; none where it has no device or it failed (see
/// [`on_device`]): the CPU runs them.
pub(super) fn active_substeps(
    m: &mut Membrane,
    a: &Activity,
    halo: &[usize],
    dt: f32,
    substeps: usize,
) -> Option<Measured> {
    // A tile the CPU lags is awake (one falling asleep was brought up to date); should one
    // not be, it is brought up to date before the packed copy is packed anew.
    let stray: Vec<usize> = match m.device.on.as_deref() {
        Some(d) if d.books.any_behind() => (0..a.awake.len())
            .filter(|&t| !a.awake[t] && d.books.is_behind(t))
            .collect(),
        _ => Vec::new(),
    };
    if !stray.is_empty() {
        m.catch_up_tiles(&stray);
    }
    lazy::on_device(m, |d, m| d.active_step(m, a, halo, dt, substeps))
}

/// Every node's substeps on the membrane's device; false where it has none or it failed.
pub(super) fn whole_substeps(m: &mut Membrane, dt: f32, substeps: usize) -> bool {
    m.catch_up();
    lazy::on_device(m, |d, m| d.whole_step(m, dt, substeps)).is_some()
}

/// The awake tiles' sleep measures a device step took, in the order of the awake list (none
/// where the device has no watcher: the CPU measures them).
pub(super) type Measured = Option<Vec<Watch>>;
