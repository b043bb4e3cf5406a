//! The active set's tiles between the CPU's row blocks and the packed records the device
//! unpacks and packs (`shaders/membrane_sync.wgsl`): the tiles going up tile by tile, the
//! awake tiles coming back by runs of tiles side by side, and the pass that sends them up.

use super::super::active::{Activity, TILE_COLS, TILE_ROWS};
use super::super::{LAYERS, Membrane, field};
use super::{ATTACH_PER_TILE, OnDevice, SPRINGS_PER_TILE, STATE_PER_TILE, TILE, carry};
use crate::gpu::RenderError;
use crate::gpu::compute::LastWrite;

/// A tile to pack, and its records where they go up: its attachments, state and springs.
type PackJob<'a> = (
    usize,
    Option<&'a mut [f32]>,
    Option<&'a mut [f32]>,
    Option<&'a mut [f32]>,
);

/// The tiles `sync` packed for the device, each into its own records (in parallel where
/// the tiles are many; each value is written once, so the bytes are the same): the state of
/// the first `state_tiles` into `state`, the springs of the first `springs_tiles` into
/// `springs`, layer 0's attachments of all into `attach` where they go up (each sized for
/// them).
pub(super) fn pack(
    m: &Membrane,
    a: &Activity,
    (sync, state_tiles, springs_tiles): (&[u32], usize, usize),
    (state, attach, springs): (&mut [f32], Option<&mut [f32]>, &mut [f32]),
) {
    use rayon::prelude::*;
    let (rows, cols) = (m.rows, m.cols);
    let mut state = state.chunks_mut(STATE_PER_TILE);
    let mut springs = springs.chunks_mut(SPRINGS_PER_TILE);
    let mut attach = attach.map(|at| at.chunks_mut(ATTACH_PER_TILE));
    let jobs: Vec<_> = sync
        .iter()
        .enumerate()
        .map(|(r, &t)| {
            let at = attach.as_mut().and_then(Iterator::next);
            let st = if r < state_tiles { state.next() } else { None };
            let sp = if r < springs_tiles {
                springs.next()
            } else {
                None
            };
            (t as usize, at, st, sp)
        })
        .filter(|(_, at, st, sp)| at.is_some() || st.is_some() || sp.is_some())
        .collect();
    let one = |(t, mut at, mut st, mut sp): PackJob| {
        let (ti, tj) = (t / a.tiles_c, t % a.tiles_c);
        for di in 0..TILE_ROWS {
            let i = ti * TILE_ROWS + di;
            if i >= rows {
                break;
            }
            let j0 = tj * TILE_COLS;
            let w = TILE_COLS.min(cols.saturating_sub(j0));
            for dj in 0..w {
                let (j, n) = (j0 + dj, di * TILE_COLS + dj);
                if let Some(at) = at.as_deref_mut() {
                    for c in 0..4 {
                        at[n * 4 + c] = m.attach[(i * 4 + c) * cols + j];
                    }
                }
            }
            for l in 0..LAYERS {
                let b = l * rows + i;
                if let Some(st) = st.as_deref_mut() {
                    for c in 0..6 {
                        let row = &m.state.data[(b * 6 + c) * cols + j0..][..w];
                        for (dj, &v) in row.iter().enumerate() {
                            st[((l * TILE) + di * TILE_COLS + dj) * 6 + c] = v;
                        }
                    }
                }
                if let Some(sp) = sp.as_deref_mut() {
                    for f in 0..field::COUNT {
                        let row = &m.rows_data[(b * field::COUNT + f) * cols + j0..][..w];
                        for (dj, &v) in row.iter().enumerate() {
                            sp[((l * TILE) + di * TILE_COLS + dj) * field::COUNT + f] = v;
                        }
                    }
                }
            }
        }
    };
    if super::super::active::worth_threads(sync.len() * LAYERS * TILE) {
        jobs.into_par_iter().for_each(one);
    } else {
        jobs.into_iter().for_each(one);
    }
}

/// Awake tiles side by side in a row of tiles, packed together coming back: the row of tiles,
/// the columns `[c0, c1)`, where its values start in the packed buffer, and whether it comes
/// back with the step (a tile in it is wanted on the CPU next: see `device_lazy.rs`).
#[derive(Debug, Clone, Copy)]
pub(super) struct Run {
    tile_row: usize,
    cols: [usize; 2],
    pub base: usize,
    pub wanted: bool,
}

impl Run {
    /// The values the run packs: layer by layer, `TILE_ROWS` rows a layer (beyond the grid's
    /// last row too), six values a node.
    pub fn floats(&self) -> usize {
        LAYERS * TILE_ROWS * 6 * (self.cols[1] - self.cols[0])
    }

    /// Where value `c` (0-2 position, 3-5 velocity) of node `(l, i, j)` lies in the packed
    /// copy (the node in the run: row `i` in its row of tiles, column `j` in its columns).
    pub fn at(&self, [l, i, j]: [usize; 3], c: usize) -> usize {
        let w = self.cols[1] - self.cols[0];
        self.base + ((l * TILE_ROWS + i % TILE_ROWS) * 6 + c) * w + (j - self.cols[0])
    }

    /// The tiles the run covers, with `tiles_c` tiles a row of tiles.
    pub fn tiles(&self, tiles_c: usize) -> std::ops::Range<usize> {
        let first = self.tile_row * tiles_c + self.cols[0] / TILE_COLS;
        first..self.tile_row * tiles_c + self.cols[1].div_ceil(TILE_COLS)
    }
}

/// The runs of the awake tiles `a.list` (ascending), into `runs`, each tile's run into
/// `run_of` (by tile), and each tile's place as the pack kernel reads it (the run's first
/// value, its width, the tile's first column in it), into `places`. The tiles that `want`
/// marks (every tile where `want` is empty) make wanted runs, the others other runs (a run
/// ends where the mark changes); the wanted runs are packed first, in their order, then the
/// others. Returns the values all the runs take and the values the
/// wanted ones take (see [`Run::floats`]).
pub(super) fn run_places(
    m: &Membrane,
    a: &Activity,
    want: &[bool],
    (runs, places, run_of): (&mut Vec<Run>, &mut Vec<[u32; 4]>, &mut Vec<u32>),
) -> (usize, usize) {
    let (rows, cols) = (m.rows, m.cols);
    runs.clear();
    run_of.resize(a.awake.len(), u32::MAX);
    let mut of = Vec::with_capacity(a.list.len());
    for &t in &a.list {
        let t = t as usize;
        let (_, [c0, c1]) = a.span(t, rows, cols);
        let tile_row = t / a.tiles_c;
        let wanted = want.get(t).copied().unwrap_or(want.is_empty());
        match runs.last_mut() {
            Some(r) if r.tile_row == tile_row && r.cols[1] == c0 && r.wanted == wanted => {
                r.cols[1] = c1;
            }
            _ => runs.push(Run {
                tile_row,
                cols: [c0, c1],
                base: 0,
                wanted,
            }),
        }
        run_of[t] = (runs.len() - 1) as u32;
        of.push((runs.len() - 1, c0));
    }
    let mut at = 0;
    for first in [true, false] {
        for r in runs.iter_mut().filter(|r| r.wanted == first) {
            r.base = at;
            at += r.floats();
        }
    }
    let wanted = runs.iter().filter(|r| r.wanted).map(Run::floats).sum();
    places.clear();
    places.extend(of.into_iter().map(|(k, c0)| {
        let r = &runs[k];
        [
            r.base as u32,
            (r.cols[1] - r.cols[0]) as u32,
            (c0 - r.cols[0]) as u32,
            0,
        ]
    }));
    (at, wanted)
}

/// `read` handed the floats of `raw` (read in place where they are aligned, else copied).
pub(super) fn as_floats<R>(raw: &[u8], read: impl FnOnce(&[f32]) -> R) -> R {
    match bytemuck::try_cast_slice::<u8, f32>(raw) {
        Ok(v) => read(v),
        Err(_) => read(&bytemuck::pod_collect_to_vec::<u8, f32>(raw)),
    }
}

/// The runs `runs` (ascending, each `base` a place in `packed`; see [`run_places`]) read
/// back into the state `data` of a grid of `rows` x `cols`: each stretch copied whole into
/// its row, row by row of the grid (in parallel where the runs are large; every value is
/// written once, so the bytes are the same).
pub(super) fn unpack((rows, cols): (usize, usize), data: &mut [f32], runs: &[Run], packed: &[f32]) {
    use rayon::prelude::*;
    // Row `di` of layer `l` in the tile row of `runs` (all of one tile row) into its stretch
    // `x` of the state.
    let copy = |x: &mut [f32], (l, di): (usize, usize), runs: &[Run]| {
        for r in runs {
            let [c0, c1] = r.cols;
            let w = c1 - c0;
            for c in 0..6 {
                let from = r.base + ((l * TILE_ROWS + di) * 6 + c) * w;
                let Some(v) = packed.get(from..from + w) else {
                    return;
                };
                x[c * cols + c0..c * cols + c1].copy_from_slice(v);
            }
        }
    };
    let nodes = runs.iter().map(Run::floats).sum::<usize>() / 6;
    if super::super::active::worth_threads(nodes) {
        data.par_chunks_mut(6 * cols)
            .enumerate()
            .for_each(|(b, x)| {
                let (l, i) = (b / rows, b % rows);
                let ti = i / TILE_ROWS;
                let first = runs.partition_point(|r| r.tile_row < ti);
                let last = first + runs[first..].partition_point(|r| r.tile_row == ti);
                copy(x, (l, i % TILE_ROWS), &runs[first..last]);
            });
        return;
    }
    // A few runs: only the rows they cover are visited.
    let layers = data.len() / (6 * cols * rows).max(1);
    let mut rest = runs;
    while let Some(ti) = rest.first().map(|r| r.tile_row) {
        let n = rest.partition_point(|r| r.tile_row == ti);
        let (these, after) = rest.split_at(n);
        for l in 0..layers {
            for i in ti * TILE_ROWS..((ti + 1) * TILE_ROWS).min(rows) {
                let b = l * rows + i;
                if let Some(x) = data.get_mut(b * 6 * cols..(b + 1) * 6 * cols) {
                    copy(x, (l, i % TILE_ROWS), these);
                }
            }
        }
        rest = after;
    }
}

impl OnDevice {
    /// Tiles `sync` packed from the CPU and unpacked on the device: the state of the first
    /// `state_tiles`, the springs of the first `springs_tiles`; layer 0's targets of all,
    /// placed on the device from the chain's pose where it has one, else their attachments
    /// from the CPU; encoded into `encoder`.
    pub(super) fn encode_up(
        &mut self,
        m: &Membrane,
        a: &Activity,
        (sync, state_tiles, springs_tiles): (&[u32], usize, usize),
        encoder: &mut wgpu::CommandEncoder,
    ) -> Result<(), RenderError> {
        let (rows, cols) = (m.rows, m.cols);
        let chain = m.chain.as_deref().filter(|c| c.pose > 0 && self.carries());
        let carry = chain.is_some();
        self.up_state.clear();
        self.up_state
            .resize(state_tiles.max(1) * STATE_PER_TILE, 0.0);
        self.up_attach.clear();
        if !carry {
            self.up_attach.resize(sync.len() * ATTACH_PER_TILE, 0.0);
            self.attach_sent += sync.len() as u64;
        }
        self.up_springs.clear();
        let springs = springs_tiles > 0;
        if springs {
            self.up_springs
                .resize(springs_tiles * SPRINGS_PER_TILE, 0.0);
        }
        pack(
            m,
            a,
            (sync, state_tiles, springs_tiles),
            (
                &mut self.up_state,
                (!carry).then_some(&mut self.up_attach[..]),
                &mut self.up_springs,
            ),
        );
        let gpu = self.k.gpu().clone();
        let q = &gpu.queue;
        let list = bytemuck::cast_slice(sync);
        self.written.sync.write(&gpu, &self.sync_list, 0, list);
        if state_tiles > 0 {
            q.write_buffer(&self.packed_state, 0, bytemuck::cast_slice(&self.up_state));
        }
        if !carry {
            q.write_buffer(
                &self.packed_attach,
                0,
                bytemuck::cast_slice(&self.up_attach),
            );
        }
        if springs {
            q.write_buffer(
                &self.packed_springs,
                0,
                bytemuck::cast_slice(&self.up_springs),
            );
        }
        let params = SyncParams {
            rows: rows as u32,
            cols: cols as u32,
            tiles_c: self.tiles_c,
            flag: 0,
            state_tiles: state_tiles as u32,
            springs_tiles: springs_tiles as u32,
            attach_sent: u32::from(!carry),
            pad: 0,
        };
        let bytes = bytemuck::bytes_of(&params);
        self.written
            .sync_params
            .write(&gpu, &self.sync_params, 0, bytes);
        let groups = [sync.len() as u32, LAYERS as u32, 1];
        let unpack = (&self.unpack, &self.unpack_bind);
        one_pass(encoder, "membrane unpack", unpack, groups);
        // The targets after the unpack, before anything reads them (the halo's placing, the
        // sums, the substeps).
        if let Some(c) = chain {
            if !self.carrier_tried {
                self.carrier_tried = true;
                let at = (rows, cols, self.tiles_c);
                let carrier = carry::Carrier::new(&gpu, c, at, (&self.k.attach, &self.sync_list))?;
                self.carrier = Some(carrier);
            }
            if let Some(k) = &mut self.carrier {
                k.encode(&gpu, encoder, c, sync.len());
            }
        }
        Ok(())
    }
}

/// What went last into the buffers the CPU writes every step (none of them is written by a
/// kernel): the awake list, the synced list, the unpack's and the pack's parameters, the
/// packed places.
#[derive(Default)]
pub(super) struct Written {
    pub awake: LastWrite,
    pub sync: LastWrite,
    pub sync_params: LastWrite,
    pub pack_params: LastWrite,
    pub places: LastWrite,
}

/// The shader's `Sync` (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct SyncParams {
    pub rows: u32,
    pub cols: u32,
    pub tiles_c: u32,
    pub flag: u32,
    /// The unpack's first tiles whose state goes up (the rest take their attachments
    /// alone).
    pub state_tiles: u32,
    /// The unpack's first tiles whose springs go up (as many as the state's or fewer).
    pub springs_tiles: u32,
    /// Whether layer 0's attachments went up (1), or the device places the targets (0).
    pub attach_sent: u32,
    pub pad: u32,
}

/// One pass of `pipeline` bound to `bind` over `groups` workgroups (a sync kernel's: the
/// first tiles of its list by every layer).
pub(super) fn one_pass(
    encoder: &mut wgpu::CommandEncoder,
    label: &str,
    (pipeline, bind): (&wgpu::ComputePipeline, &wgpu::BindGroup),
    groups: [u32; 3],
) {
    let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
        label: Some(label),
        timestamp_writes: None,
    });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, bind, &[]);
    pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
}
