//! The active set's tiles between the CPU's row blocks and the packed records the device
//! unpacks and packs (`shaders/membrane_sync.wgsl`).

use super::super::active::{Activity, TILE_COLS, TILE_ROWS};
use super::super::{LAYERS, Membrane, field};
use super::{ATTACH_PER_TILE, SPRINGS_PER_TILE, STATE_PER_TILE, TILE};

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

/// The awake tiles' state read back (`packed`: each awake tile of `a.list` in turn, by layer,
/// node and value) into `m`'s rows: row by row of the grid, each on its own (in parallel
/// where the tiles are many; every value is written once, so the bytes are the same).
pub(super) fn unpack(m: &mut Membrane, a: &Activity, packed: &[f32]) {
    use rayon::prelude::*;
    let (rows, cols) = (m.rows, m.cols);
    // The device takes only tiles of TILE_ROWS x TILE_COLS (`OnDevice::new`).
    let by_row = a.by_tile_row(a.list.iter().map(|&t| t as usize));
    let one = |(b, x): (usize, &mut [f32])| {
        let (l, i) = (b / rows, b % rows);
        let di = i % TILE_ROWS;
        for &(r, t) in by_row.of(i) {
            let j0 = (t % a.tiles_c) * TILE_COLS;
            for j in j0..(j0 + TILE_COLS).min(cols) {
                let from = ((r * LAYERS + l) * TILE + di * TILE_COLS + (j - j0)) * 6;
                let Some(v) = packed.get(from..from + 6) else {
                    return;
                };
                for (c, &v) in v.iter().enumerate() {
                    x[c * cols + j] = v;
                }
            }
        }
    };
    let nodes = a.list.len() * LAYERS * TILE;
    let data = &mut m.state.data;
    if super::super::active::worth_threads(nodes) {
        data.par_chunks_mut(6 * cols).enumerate().for_each(one);
    } else {
        data.chunks_mut(6 * cols).enumerate().for_each(one);
    }
}
