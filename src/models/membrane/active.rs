//! The membrane's active set: the grid is cut into tiles of [`ActivityParams::tile_rows`] x
//! [`ActivityParams::tile_cols`] nodes (all four layers; [`TILE_ROWS`] x [`TILE_COLS`] by
//! default); only awake tiles step. A sleeping tile is carried by its
//! anchors: each node sits at its anchor plus the offset it had when the tile fell asleep,
//! the anchor being the node's rest position moved by its column's layer-0 target, in
//! proportion to how far the node lies from layer 3 (layer 0 moves with the target, layer 3
//! not at all, layers 1 and 2 by their rest fractions between them). So the tissue far from
//! every tool follows the rectum quasi-statically, and where a tool works the full dynamics
//! run at the explicit step.
//!
//! A tile wakes when a tool's box comes near it, or when the nodes on its border with an
//! awake tile move faster (relative to their anchors) than the wake speed; it falls asleep
//! when every node has moved slower than the sleep speed for the sleep time and no tool is
//! near. Awake tiles side by side in a row of tiles step as one run (and runs in successive
//! rows of tiles with the same columns as one); each run steps as one block
//! ([`super::block`]) into its own buffer, and the buffers are copied back in run order, so
//! the bytes do not depend on the thread count (a small awake set steps on one thread);
//! before the step's last substep, only the nodes another block reads go back (`share`).

use super::block::{Block, BlockPass};
use super::{LAYERS, Membrane};
use glam::Vec3;
use rayon::prelude::*;

/// Rows of a tile (along the bowel) by default, and on the GPU.
pub const TILE_ROWS: usize = 8;
/// Columns of a tile (around the bowel) by default, and on the GPU.
pub const TILE_COLS: usize = 16;

/// When tiles sleep and wake.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActivityParams {
    /// A tile sleeps once every node has moved slower than this, relative to its anchor, m/s.
    pub sleep_speed_m_per_s: f32,
    /// ... for this long, s.
    pub sleep_after_s: f32,
    /// A sleeping tile wakes when a border node of an awake neighbour has moved this far from
    /// where its anchor and its offset put it when its own tile woke, m.
    pub wake_distance_m: f32,
    /// A tile wakes when a tool's box comes within this distance of its box, m.
    pub wake_margin_m: f32,
    /// Rows of a tile (along the bowel).
    pub tile_rows: usize,
    /// Columns of a tile (around the bowel).
    pub tile_cols: usize,
}

impl Default for ActivityParams {
    fn default() -> Self {
        ActivityParams {
            // Sub-millimetre departures from the anchors' linear carriage are tolerated:
            // lifting the rectum moves layer 0 along much of the bowel, and with 30 um and
            // 0.2 mm/s a sixth of the membrane woke for it (docs/rectum.md).
            sleep_speed_m_per_s: 1e-3,
            sleep_after_s: 0.1,
            wake_distance_m: 2e-4,
            wake_margin_m: 3e-3,
            tile_rows: TILE_ROWS,
            tile_cols: TILE_COLS,
        }
    }
}

/// Awake runs stepped as one block: the rectangle round them, and which runs they are.
#[derive(Debug, Clone, Default)]
struct Group {
    span: ([usize; 2], [usize; 2]),
    members: Vec<usize>,
}

/// The tiles' state.
#[derive(Debug, Clone, Default)]
pub(super) struct Activity {
    pub params: ActivityParams,
    pub tiles_r: usize,
    pub tiles_c: usize,
    pub awake: Vec<bool>,
    /// Time each awake tile has been still, s.
    still_s: Vec<f32>,
    /// Every tile steps (benchmarks).
    pub all_awake: bool,
    /// Each tile's box (all layers) when last refreshed, m.
    boxes: Vec<(Vec3, Vec3)>,
    /// Positions at rest, in the state's row blocks but positions only: `[b][3][cols]`.
    pub(super) rest: Vec<f32>,
    /// Each node's rest fraction from layer 0 (0) to layer 3 (1): `[b][cols]`.
    pub(super) weight: Vec<f32>,
    /// Offsets of nodes from their anchors when their tile fell asleep: `[b][3][cols]`.
    pub(super) offset: Vec<f32>,
    /// Per tile: the [`stamp`] of the last write of its offsets.
    pub(super) slept: Vec<u64>,
    /// Offsets of awake tiles' nodes at the last check (their speed is measured from it;
    /// where a device measures them, only the device's are current).
    pub(super) last: Vec<f32>,
    /// The last check was a device's: the CPU's last offsets are not current (the device
    /// was lost, or this is a copy on the CPU of a model on a device), so a check on the CPU
    /// starts afresh.
    last_on_device: bool,
    /// Whether every awake tile's positions were finite at the last sleep check (none
    /// where the model changed since, or has not been checked): the quarantine's check reads
    /// it rather than the positions.
    pub(super) measured_finite: Option<bool>,
    /// Per run of awake tiles, its block (kept from step to step: nothing is allocated per
    /// substep).
    buffers: Vec<super::block::Block>,
    /// Awake tiles this step, ascending.
    pub list: Vec<u32>,
    /// This step's runs of awake tiles side by side in one row of tiles: (rows, columns).
    runs: Vec<([usize; 2], [usize; 2])>,
    /// This step's blocks: runs in successive rows of tiles whose columns overlap.
    groups: Vec<Group>,
    /// Sum of awake node shares over steps, and steps (for the mean awake fraction).
    pub awake_share: f64,
    pub steps: u64,
}

impl Activity {
    pub fn new(m: &Membrane, params: ActivityParams) -> Activity {
        let (rows, cols) = (m.rows, m.cols);
        let params = ActivityParams {
            tile_rows: params.tile_rows.max(1),
            tile_cols: params.tile_cols.max(1),
            ..params
        };
        let tiles_r = rows.div_ceil(params.tile_rows);
        let tiles_c = cols.div_ceil(params.tile_cols);
        let mut rest = vec![0.0; LAYERS * rows * 3 * cols];
        for b in 0..LAYERS * rows {
            for c in 0..3 {
                let from = (b * 6 + c) * cols;
                rest[(b * 3 + c) * cols..(b * 3 + c + 1) * cols]
                    .copy_from_slice(&m.state.data[from..from + cols]);
            }
        }
        let mut weight = vec![0.0; LAYERS * rows * cols];
        let per = rows * cols;
        for i in 0..rows {
            for j in 0..cols {
                let p: [Vec3; LAYERS] =
                    std::array::from_fn(|l| m.position((l * rows + i) * cols + j));
                let span = p[0].distance(p[LAYERS - 1]).max(f32::EPSILON);
                for l in 0..LAYERS {
                    let w = (p[l].distance(p[0]) / span).clamp(0.0, 1.0);
                    weight[l * per + i * cols + j] = if l == 0 { 0.0 } else { w };
                }
            }
        }
        let mut a = Activity {
            params,
            tiles_r,
            tiles_c,
            awake: vec![false; tiles_r * tiles_c],
            still_s: vec![0.0; tiles_r * tiles_c],
            all_awake: false,
            boxes: vec![(Vec3::ZERO, Vec3::ZERO); tiles_r * tiles_c],
            rest,
            weight,
            offset: vec![0.0; LAYERS * rows * 3 * cols],
            slept: vec![stamp(); tiles_r * tiles_c],
            last: vec![0.0; LAYERS * rows * 3 * cols],
            last_on_device: false,
            measured_finite: None,
            buffers: Vec::new(),
            list: Vec::new(),
            runs: Vec::new(),
            groups: Vec::new(),
            awake_share: 0.0,
            steps: 0,
        };
        for t in 0..a.awake.len() {
            a.boxes[t] = tile_box(m, &a, t);
        }
        a
    }

    /// Heap bytes of the tiles' data and buffers.
    pub fn heap_bytes(&self) -> usize {
        let f = std::mem::size_of::<f32>();
        (self.rest.capacity()
            + self.weight.capacity()
            + self.offset.capacity()
            + self.last.capacity()
            + self.buffers.iter().map(|b| b.heap_bytes()).sum::<usize>() / f)
            * f
            + self.awake.capacity()
            + self.still_s.capacity() * f
    }

    /// The tiles `tiles` by row of tiles, for the passes that go row block by row block of the
    /// grid ([`TileRows::of`]).
    pub fn by_tile_row(&self, tiles: impl Iterator<Item = usize>) -> TileRows {
        let mut rows: Vec<Vec<(usize, usize)>> = vec![Vec::new(); self.tiles_r];
        for (k, t) in tiles.enumerate() {
            if let Some(row) = rows.get_mut(t / self.tiles_c) {
                row.push((k, t));
            }
        }
        TileRows {
            rows,
            tile_rows: self.params.tile_rows,
        }
    }

    /// Whether awake tile `t` may fall asleep at the check after a step of `dt` (its still
    /// time reaches the sleep time with it, as the check adds it).
    pub fn may_sleep(&self, t: usize, dt: f32) -> bool {
        !self.all_awake
            && self
                .still_s
                .get(t)
                .is_some_and(|s| s + dt >= self.params.sleep_after_s)
    }

    /// Each tile's box (all layers) when last refreshed, m.
    pub fn tile_box(&self, t: usize) -> Option<(Vec3, Vec3)> {
        self.boxes.get(t).copied()
    }

    /// Rows and columns of tile `t`.
    pub fn span(&self, t: usize, rows: usize, cols: usize) -> ([usize; 2], [usize; 2]) {
        let (ti, tj) = (t / self.tiles_c, t % self.tiles_c);
        let (tr, tc) = (self.params.tile_rows, self.params.tile_cols);
        let (r0, c0) = (ti * tr, tj * tc);
        ([r0, (r0 + tr).min(rows)], [c0, (c0 + tc).min(cols)])
    }

    /// The tiles beside `t` (eight-connected; around the ring when `periodic`).
    pub fn neighbours(&self, t: usize, periodic: bool) -> impl Iterator<Item = usize> + '_ {
        let (ti, tj) = ((t / self.tiles_c) as isize, (t % self.tiles_c) as isize);
        let (nr, nc) = (self.tiles_r as isize, self.tiles_c as isize);
        (-1..=1isize)
            .flat_map(move |di| (-1..=1isize).map(move |dj| (di, dj)))
            .filter(|&(di, dj)| di != 0 || dj != 0)
            .filter_map(move |(di, dj)| {
                let i = ti + di;
                let mut j = tj + dj;
                if !(0..nr).contains(&i) {
                    return None;
                }
                if periodic {
                    j = j.rem_euclid(nc);
                } else if !(0..nc).contains(&j) {
                    return None;
                }
                Some((i * nc + j) as usize)
            })
    }
}

/// The box around tile `t`'s nodes (all layers) as they are in the state.
fn tile_box(m: &Membrane, a: &Activity, t: usize) -> (Vec3, Vec3) {
    let ([r0, r1], [c0, c1]) = a.span(t, m.rows, m.cols);
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for l in 0..LAYERS {
        for i in r0..r1 {
            for j in c0..c1 {
                let p = m.position((l * m.rows + i) * m.cols + j);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
    }
    (lo, hi)
}

impl Membrane {
    /// Whether the active set is on (the membrane was built with it, see
    /// [`Membrane::use_active_set`]).
    pub fn has_active_set(&self) -> bool {
        self.activity.is_some()
    }

    /// Turns on the active set: every tile asleep at its anchors until a tool comes near.
    pub fn use_active_set(&mut self, params: ActivityParams) {
        self.activity = Some(Activity::new(self, params));
        self.all_changed();
    }

    /// Keeps every tile stepping from now on (benchmarks).
    pub fn stay_awake(&mut self) {
        self.catch_up();
        if let Some(a) = &mut self.activity {
            a.all_awake = true;
            a.awake.fill(true);
        }
    }

    /// The mean share of nodes stepped per step so far (1 without the active set).
    pub fn awake_fraction(&self) -> f64 {
        match &self.activity {
            Some(a) if a.steps > 0 => a.awake_share / a.steps as f64,
            Some(_) => 0.0,
            None => 1.0,
        }
    }

    /// Whether tile `t` is awake (all are without an active set).
    pub fn tile_awake(&self, t: usize) -> bool {
        self.activity
            .as_ref()
            .is_none_or(|a| a.awake.get(t).copied().unwrap_or(false))
    }

    /// Tiles: (rows of tiles, columns of tiles).
    pub fn tiles(&self) -> (usize, usize) {
        self.activity
            .as_ref()
            .map_or((1, 1), |a| (a.tiles_r, a.tiles_c))
    }

    /// The tile holding row `i`, column `j`.
    pub fn tile_of(&self, i: usize, j: usize) -> usize {
        let (tr, tc, tiles_c) = self.tile_grid();
        (i / tr) * tiles_c + j / tc
    }

    /// The tiles' grid: a tile's rows and columns, and tiles a row of tiles (the active set's,
    /// or the default tiles' where it has none or is out for its step).
    pub(super) fn tile_grid(&self) -> (usize, usize, usize) {
        let p = self
            .activity
            .as_ref()
            .map_or_else(ActivityParams::default, |a| a.params);
        (p.tile_rows, p.tile_cols, self.cols.div_ceil(p.tile_cols))
    }

    /// Where node `node` is drawn: its position, or for a node of a sleeping tile where its
    /// anchor (on the targets last set for its column) and its offset carry it, which its
    /// state may not show yet (a device places the halo on its own copy; see
    /// `device_watch.rs`). Reads nothing a step writes, so drawing changes no bytes.
    pub fn carried_position(&self, node: usize) -> Vec3 {
        let Some(a) = self.activity.as_ref().filter(|a| !a.all_awake) else {
            return self.position(node);
        };
        let (l, i, j) = self.coords(node);
        let tile = self.tile_of(i, j);
        if a.awake.get(tile).is_none_or(|&w| w) {
            return self.position(node);
        }
        self.carried_asleep(a, [l, i, j], self.target_now(i, j, tile))
    }

    /// Wakes every tile whose box comes within the wake margin of a box `(min, max)`.
    pub fn wake_near(&mut self, boxes: &[(Vec3, Vec3)]) {
        let rows = self.rows;
        let cols = self.cols;
        let periodic = self.periodic;
        let Some(a) = &mut self.activity else {
            return;
        };
        let margin = Vec3::splat(a.params.wake_margin_m);
        let mut woken = Vec::new();
        for t in 0..a.awake.len() {
            let (lo, hi) = a.boxes[t];
            let near = boxes.iter().any(|(blo, bhi)| {
                (lo - margin).cmple(*bhi).all() && (hi + margin).cmpge(*blo).all()
            });
            if near {
                a.still_s[t] = 0.0;
                if !a.awake[t] {
                    woken.push(t);
                }
            }
        }
        let _ = (rows, cols, periodic);
        for t in woken {
            self.wake(t);
        }
    }

    /// Every tile's box from its nodes now.
    pub(super) fn refresh_boxes(&mut self) {
        let Some(mut a) = self.activity.take() else {
            return;
        };
        for t in 0..a.awake.len() {
            a.boxes[t] = tile_box(self, &a, t);
        }
        self.activity = Some(a);
    }

    /// Wakes tile `t`: its nodes start where their anchors carry them.
    pub(super) fn wake(&mut self, t: usize) {
        let Some(mut a) = self.activity.take() else {
            return;
        };
        if !a.awake[t] {
            place_asleep(self, &a, t);
            a.boxes[t] = tile_box(self, &a, t);
            start_watch(self, &mut a, t);
            a.awake[t] = true;
            a.still_s[t] = 0.0;
        }
        self.activity = Some(a);
    }

    /// Puts every sleeping node where its anchor carries it (call after setting all the
    /// targets, before drawing).
    pub fn place_sleeping(&mut self) {
        let Some(mut a) = self.activity.take() else {
            return;
        };
        for t in 0..a.awake.len() {
            if !a.awake[t] {
                place_asleep(self, &a, t);
                a.boxes[t] = tile_box(self, &a, t);
            }
        }
        self.activity = Some(a);
    }

    /// The layer-0 rows and columns whose targets the next step needs: those of awake tiles
    /// and of the sleeping tiles beside them (every one with `all`).
    pub fn tiles_needing_targets(&self, all: bool) -> Vec<usize> {
        let Some(a) = &self.activity else {
            return vec![0];
        };
        let mut need = vec![all; a.awake.len()];
        for t in 0..a.awake.len() {
            if a.awake[t] {
                need[t] = true;
                for n in a.neighbours(t, self.periodic) {
                    need[n] = true;
                }
            }
        }
        (0..need.len()).filter(|&t| need[t]).collect()
    }

    /// Rows `[r0, r1)` and columns `[c0, c1)` of tile `t` (the whole grid without an active
    /// set).
    pub fn tile_span(&self, t: usize) -> ([usize; 2], [usize; 2]) {
        match &self.activity {
            Some(a) => a.span(t, self.rows, self.cols),
            None => ([0, self.rows], [0, self.cols]),
        }
    }
}

/// Starts the speed measure of tile `t`, waking: its nodes are at their offsets.
fn start_watch(m: &mut Membrane, a: &mut Activity, t: usize) {
    m.device.offsets_changed(t);
    let ([r0, r1], [c0, c1]) = a.span(t, m.rows, m.cols);
    let (rows, cols) = (m.rows, m.cols);
    for b in (0..LAYERS).flat_map(|l| (r0..r1).map(move |i| l * rows + i)) {
        for c in 0..3 {
            let r = (b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1;
            let (last, off) = (&mut a.last[r.clone()], &a.offset[r]);
            last.copy_from_slice(off);
        }
    }
}

/// Places tile `t`'s nodes at anchor + offset, at rest relative to it.
fn place_asleep(m: &mut Membrane, a: &Activity, t: usize) {
    super::chain::place(m, Some(a), &[t]);
    m.device.tile_changed(t);
    m.nodes_changed(t);
    let ([r0, r1], [c0, c1]) = a.span(t, m.rows, m.cols);
    let cols = m.cols;
    let mut anchor = vec![0.0; c1 - c0];
    for l in 0..LAYERS {
        for i in r0..r1 {
            let b = l * m.rows + i;
            for c in 0..3 {
                anchors_into(m, a, l, i, [c0, c1], c, &mut anchor);
                let off = &a.offset[(b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1];
                let x = &mut m.state.data[(b * 6 + c) * cols + c0..(b * 6 + c) * cols + c1];
                for ((x, p), o) in x.iter_mut().zip(&anchor).zip(off) {
                    *x = p + o;
                }
                m.state.data[(b * 6 + 3 + c) * cols + c0..(b * 6 + 3 + c) * cols + c1].fill(0.0);
            }
        }
    }
}

/// Component `c` of the anchors of layer `l`'s row `i`, columns `c0..c1`, into `out`: each
/// node's rest position moved by its column's layer-0 target (its displacement from rest)
/// times `1 - weight`.
#[inline]
fn anchors_into(
    m: &Membrane,
    a: &Activity,
    l: usize,
    i: usize,
    [c0, c1]: [usize; 2],
    c: usize,
    out: &mut [f32],
) {
    let cols = m.cols;
    let b = l * m.rows + i;
    let rest = &a.rest[(b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1];
    let rest0 = &a.rest[(i * 3 + c) * cols + c0..(i * 3 + c) * cols + c1];
    let target = &m.attach[(i * 4 + 1 + c) * cols + c0..(i * 4 + 1 + c) * cols + c1];
    let w = &a.weight[b * cols + c0..b * cols + c1];
    for ((((o, r), r0), t), w) in out.iter_mut().zip(rest).zip(rest0).zip(target).zip(w) {
        *o = r + (t - r0) * (1.0 - w);
    }
}

/// One step of `dt` over the awake tiles: the sleeping tiles beside them placed at their
/// anchors, then explicit substeps, then the sleep and wake checks.
pub(super) fn step(m: &mut Membrane, dt: f32, substeps: usize) {
    let Some(mut a) = m.activity.take() else {
        return;
    };
    // The halo: sleeping tiles beside awake ones, where their anchors are now.
    let mut beside = vec![false; a.awake.len()];
    for t in (0..a.awake.len()).filter(|&t| a.awake[t]) {
        for n in a.neighbours(t, m.periodic) {
            beside[n] = !a.awake[n];
        }
    }
    let halo: Vec<usize> = (0..a.awake.len()).filter(|&t| beside[t]).collect();
    // A device that places the halo itself leaves the CPU's copy of it be (see
    // `device_watch.rs`), unless it fails below.
    let device_places = m.device.places_halo();
    if !device_places {
        let _span = tracing::debug_span!("membrane_halo", tiles = halo.len()).entered();
        place_all_asleep(m, &a, &halo);
    }
    a.list.clear();
    a.list
        .extend((0..a.awake.len() as u32).filter(|&t| a.awake[t as usize]));
    // The awake tiles step (here or on a device): the checkpoint takes them.
    for &t in &a.list {
        m.nodes_changed(t as usize);
    }
    // On the membrane's GPU where it has one, else (or should it fail) here.
    // Layer 0's loads by group are summed where the step runs, from the state it starts
    // from; the device measures the awake tiles for the checks below where it can.
    let measured = super::device::active_substeps(m, &a, &halo, dt, substeps);
    if measured.is_none() {
        if device_places {
            let _span = tracing::debug_span!("membrane_halo", tiles = halo.len()).entered();
            place_all_asleep(m, &a, &halo);
        }
        // The targets this step reads, where the CPU's lag the chain's pose.
        let tiles: Vec<usize> = a
            .list
            .iter()
            .map(|&t| t as usize)
            .chain(halo.iter().copied())
            .collect();
        super::chain::place(m, Some(&a), &tiles);
        group_runs(m, &mut a);
        let h = dt / substeps as f32;
        let mut buffers = std::mem::take(&mut a.buffers);
        buffers.resize_with(a.groups.len(), Default::default);
        let mut members = Vec::new();
        let whole = share::whole_exchange();
        let loads = super::anchor_sums::wanted(m) && !whole;
        if whole {
            super::anchor_sums::on_cpu(m, &a.runs);
        }
        for (b, g) in buffers.iter_mut().zip(&a.groups) {
            members.clear();
            members.extend(g.members.iter().map(|&r| a.runs[r]));
            b.prepare(m, g.span, &members);
            if loads {
                b.keep_loads();
            }
        }
        if !whole {
            share::mark(m, &mut a, &mut buffers);
        }
        for k in 0..substeps {
            substep(m, &a, &mut buffers, h, whole || k + 1 == substeps);
            // Layer 0's loads by group, from the forces the first substep found at the
            // step's start: what `anchor_sums::on_cpu` would find there, bit for bit.
            if k == 0 && loads {
                share::sum_block_loads(m, &a, &buffers);
            }
        }
        a.buffers = buffers;
    }
    // Sleep and wake checks, once per step.
    let nodes_awake: usize = a
        .list
        .iter()
        .map(|&t| {
            let ([r0, r1], [c0, c1]) = a.span(t as usize, m.rows, m.cols);
            LAYERS * (r1 - r0) * (c1 - c0)
        })
        .sum();
    a.awake_share += nodes_awake as f64 / m.len().max(1) as f64;
    a.steps += 1;
    if !a.all_awake {
        let _span = tracing::debug_span!("membrane_settle", tiles = a.list.len()).entered();
        settle(m, &mut a, dt, measured.flatten());
    }
    m.activity = Some(a);
}

/// The CPU's blocks of the awake tiles: tiles side by side make one run; runs in successive
/// rows of tiles whose columns overlap step as one block, a rectangle round them (the
/// sleeping nodes inside it are stepped too but never written back): fewer, larger blocks,
/// whose loops run long. A device steps by tile and needs none of this.
fn group_runs(m: &Membrane, a: &mut Activity) {
    a.runs.clear();
    a.groups.clear();
    for ti in 0..a.tiles_r {
        let mut tj = 0;
        while tj < a.tiles_c {
            if !a.awake[ti * a.tiles_c + tj] {
                tj += 1;
                continue;
            }
            let first = tj;
            while tj < a.tiles_c && a.awake[ti * a.tiles_c + tj] {
                tj += 1;
            }
            let (rs, [c0, _]) = a.span(ti * a.tiles_c + first, m.rows, m.cols);
            let (_, [_, c1]) = a.span(ti * a.tiles_c + tj - 1, m.rows, m.cols);
            let run = a.runs.len();
            a.runs.push((rs, [c0, c1]));
            let joins = a.groups.iter_mut().find(|g| {
                (g.span.0[1] == rs[0] || g.span.0[1] == rs[1])
                    && g.span.1[0] < c1
                    && c0 < g.span.1[1]
            });
            match joins {
                Some(g) => {
                    g.span.0[1] = rs[1];
                    g.span.1 = [g.span.1[0].min(c0), g.span.1[1].max(c1)];
                    g.members.push(run);
                }
                None => a.groups.push(Group {
                    span: (rs, [c0, c1]),
                    members: vec![run],
                }),
            }
        }
    }
}

/// Tiles grouped by the row of tiles they lie in ([`Activity::by_tile_row`]).
pub(super) struct TileRows {
    rows: Vec<Vec<(usize, usize)>>,
    tile_rows: usize,
}

impl TileRows {
    /// The tiles that grid row `i` crosses: each one's place in the tiles grouped, and the
    /// tile, in their order there.
    pub fn of(&self, i: usize) -> &[(usize, usize)] {
        self.rows
            .get(i / self.tile_rows)
            .map_or(&[][..], Vec::as_slice)
    }
}

/// Awake nodes (all layers) below which a substep's runs step on one thread.
const PARALLEL_NODES: usize = 32_768;
/// Nodes a parallel task takes at least.
const TASK_NODES: usize = 8_192;

/// Whether a pass over `nodes` awake nodes is worth handing to the pool: on a small set,
/// waking a second thread (and its spinning beside this one on a shared core) costs more
/// than it saves.
pub(super) fn worth_threads(nodes: usize) -> bool {
    #[cfg(test)]
    if ALWAYS_THREADS.with(std::cell::Cell::get) {
        return true;
    }
    nodes >= PARALLEL_NODES && rayon::current_num_threads() > 1
}

#[cfg(test)]
thread_local! {
    /// Every pass that can go to the pool goes there, however few its nodes (set on the
    /// thread that steps the model: the tests' small grids then take the parallel paths).
    pub(crate) static ALWAYS_THREADS: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// One explicit substep of the awake runs, each in its block, then copied back in order.
fn substep(m: &mut Membrane, a: &Activity, blocks: &mut [Block], h: f32, last: bool) {
    {
        let mm = &*m;
        let pass = |block: &mut Block| mm.vectorized(BlockPass { m: mm, block, h });
        // Each run writes only its own block, so the order they run in does not matter: a
        // small awake set steps on this thread (waking a second one for a few thousand
        // nodes costs more than it saves), a large one in tasks of about `TASK_NODES`.
        let nodes: usize = a
            .runs
            .iter()
            .map(|([r0, r1], [c0, c1])| LAYERS * (r1 - r0) * (c1 - c0))
            .sum();
        if !worth_threads(nodes) {
            blocks.iter_mut().for_each(pass);
        } else {
            let per_run = nodes / blocks.len().max(1);
            blocks
                .par_iter_mut()
                .with_min_len((TASK_NODES / per_run.max(1)).max(1))
                .for_each(pass);
        }
    }
    // Before the step's last substep, a block writes back only the nodes that blocks read
    // from the membrane (`share`).
    for b in blocks.iter() {
        if last {
            b.scatter(m);
        } else {
            b.scatter_exports(m);
        }
    }
}

/// After a step: each awake tile's fastest node relative to its anchor (`measured` where a
/// device took the measures, else here); still tiles with no tool near fall asleep, and fast
/// border nodes wake the sleeping tiles beside them. Measured here after a device measured
/// the last check (the device was lost, or this is a copy on the CPU), this check only
/// starts the watch again: no tile counts as still.
fn settle(m: &mut Membrane, a: &mut Activity, dt: f32, measured: Option<Vec<Watch>>) {
    let (rows, cols) = (m.rows, m.cols);
    let p = a.params;
    let mut to_wake = Vec::new();
    let list = a.list.clone();
    let on_device = measured.is_some();
    let mut watch = measured.unwrap_or_else(|| watch_all(m, a, dt));
    if !on_device && std::mem::replace(&mut a.last_on_device, false) {
        watch.iter_mut().for_each(|w| w.fastest = f32::INFINITY);
    }
    a.last_on_device |= on_device;
    a.measured_finite = Some(watch.iter().all(|w| w.finite));
    for (&t, w) in list.iter().zip(watch) {
        let t = t as usize;
        let Watch {
            fastest,
            edge,
            lo,
            hi,
            ..
        } = w;
        if edge > p.wake_distance_m {
            to_wake.extend(a.neighbours(t, m.periodic).filter(|&n| !a.awake[n]));
        }
        if fastest < p.sleep_speed_m_per_s {
            a.still_s[t] += dt;
        } else {
            a.still_s[t] = 0.0;
        }
        a.boxes[t] = (lo, hi);
        if a.still_s[t] >= p.sleep_after_s {
            // Asleep where it is: its offsets now hold it there (the last measure's, which
            // only the device holds where it took them: the tile came back with the step,
            // being likely to fall asleep, else it is brought up to date now).
            if on_device {
                m.catch_up_tiles(&[t]);
                super::chain::place(m, Some(a), &[t]);
                offsets_now(m, a, t);
            } else {
                let ([r0, r1], [c0, c1]) = a.span(t, rows, cols);
                for b in (0..LAYERS).flat_map(|l| (r0..r1).map(move |i| l * rows + i)) {
                    for c in 0..3 {
                        let r = (b * 3 + c) * cols + c0..(b * 3 + c) * cols + c1;
                        let (off, last) = (&mut a.offset[r.clone()], &a.last[r]);
                        off.copy_from_slice(last);
                    }
                }
            }
            a.awake[t] = false;
            a.still_s[t] = 0.0;
            a.slept[t] = stamp();
            m.device.offsets_changed(t);
        }
    }
    to_wake.sort_unstable();
    to_wake.dedup();
    for t in to_wake {
        if !a.awake[t] {
            place_asleep(m, a, t);
            a.boxes[t] = tile_box(m, a, t);
            start_watch(m, a, t);
            a.awake[t] = true;
            a.still_s[t] = 0.0;
        }
    }
}

#[path = "active_drawn.rs"]
mod drawn;
pub use drawn::DrawnGrid;
pub(super) use drawn::stamp;
#[path = "active_near.rs"]
mod near;
pub use near::AHEAD_M;
#[path = "active_rows.rs"]
mod rows;
#[path = "active_share.rs"]
mod share;
pub(super) use rows::Watch;
use rows::{offsets_now, place_all_asleep, watch_all};
