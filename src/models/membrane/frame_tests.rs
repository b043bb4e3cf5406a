//! Frames of a membrane stepping on a device (lavapipe here): a frame draws the tiles the
//! CPU lags where the device left them, from the readback of a step announced before it
//! (no copy on the device, the tiles left lagging) or copied for it where none was
//! announced, and a device lost before a frame's read loses the frame nothing.

use super::DrawnGrid;
use super::Membrane;
use super::gpu_tests::session_step;
use crate::sim::{ModelOutput, TissueModel};
use glam::Vec3;

/// The sleepy tube twice on one device, with a tile woken far from the tool in both
/// (`checkpoint_tests.rs`), and a drawn grid over it.
fn two_on_one_device() -> (crate::gpu::Gpu, Membrane, Membrane, DrawnGrid) {
    let (gpu, told, untold) = super::checkpoint_tests::two_on_one_device();
    let (rows, cols) = grid_rows_cols();
    (
        gpu,
        told,
        untold,
        DrawnGrid::new(&DRAWN_LAYERS, &rows, &cols),
    )
}

/// The drawn grid's layers, and its rows and columns.
const DRAWN_LAYERS: [usize; 3] = [1, 2, 3];
fn grid_rows_cols() -> (Vec<usize>, Vec<usize>) {
    let rows: Vec<usize> = (0..48).step_by(3).chain([47]).collect();
    let cols: Vec<usize> = (0..64).step_by(2).collect();
    (rows, cols)
}

/// The drawn grid's nodes in the tiles `m` lags.
fn drawn_lagging(m: &Membrane) -> u64 {
    let (rows, cols) = grid_rows_cols();
    let cells = rows
        .iter()
        .flat_map(|&i| cols.iter().map(move |&j| (i, j)))
        .filter(|&(i, j)| m.gpu_tile_behind(m.tile_of(i, j)) == Some(true))
        .count();
    (cells * DRAWN_LAYERS.len()) as u64
}

/// The first node where `a` and `b` differ in a bit, with both values (none: the same).
fn first_difference(a: &[Vec3], b: &[Vec3]) -> Option<(usize, Vec3, Vec3)> {
    let bits = |p: &Vec3| p.to_array().map(f32::to_bits);
    if a.len() != b.len() {
        return Some((a.len().min(b.len()), Vec3::NAN, Vec3::NAN));
    }
    (0..a.len())
        .find(|&k| bits(&a[k]) != bits(&b[k]))
        .map(|k| (k, a[k], b[k]))
}

#[test]
fn a_frame_draws_the_lagging_tiles_where_the_device_left_them() {
    // Both run the same session; one announces its frames (every 5 steps) before their
    // steps, as a session's window does. Each frame of both must be what the whole newest
    // state draws, to the bit; the announced ones read the lagging tiles from their step's
    // readback, with no copy on the device, and leave them lagging. From its second frame
    // on, the announced one's step brings back only the drawn nodes of the lagging tiles
    // beside the runs both bring back (three floats a node), not every run.
    let (_gpu, mut told, mut untold, grid) = two_on_one_device();
    let (mut g_told, mut g_untold, mut g_whole) = (grid.clone(), grid.clone(), grid);
    let mut out = ModelOutput::default();
    let (mut lagging_at_frames, mut frames, mut gathered) = (0, 0, 0);
    for k in 0..40 {
        let frame = k % 5 == 4;
        if frame {
            told.read_whole_after_step();
        }
        session_step(&mut told, k, &mut out);
        session_step(&mut untold, k, &mut out);
        if !frame {
            continue;
        }
        let lagging = told.gpu_tiles_behind().unwrap_or(0);
        assert_eq!(untold.gpu_tiles_behind(), Some(lagging), "step {k}");
        let bytes = |m: &Membrane| m.gpu_last_readback_bytes().unwrap_or(0);
        if frames > 0 {
            let nodes = drawn_lagging(&told);
            assert_eq!(
                bytes(&told),
                bytes(&untold) + 12 * nodes,
                "step {k}: {nodes} drawn nodes lag"
            );
            gathered += nodes;
        } else {
            assert!(
                lagging == 0 || bytes(&told) > bytes(&untold),
                "step {k}: the first frame's step brings every run back"
            );
        }
        let copies = (told.gpu_frame_copies(), untold.gpu_frame_copies());
        let (a, b) = (
            told.place_drawn(&mut g_told),
            untold.place_drawn(&mut g_untold),
        );
        assert_eq!(
            told.gpu_frame_copies(),
            copies.0,
            "step {k}: a copy for the frame"
        );
        let copied = untold.gpu_frame_copies().unwrap_or(0) - copies.1.unwrap_or(0);
        assert_eq!(copied, u64::from(lagging > 0), "step {k}");
        assert_eq!(
            told.gpu_tiles_behind(),
            Some(lagging),
            "step {k}: caught up"
        );
        // The whole newest state, on the CPU, draws the same.
        untold.catch_up();
        let whole = untold.place_drawn(&mut g_whole);
        assert_eq!(first_difference(&a, &whole), None, "step {k}: announced");
        assert_eq!(first_difference(&b, &whole), None, "step {k}: copied");
        lagging_at_frames += lagging;
        frames += 1;
    }
    assert_eq!(frames, 8);
    assert!(lagging_at_frames > 0, "no tile lagged at a frame");
    assert!(gathered > 0, "no drawn node was gathered");
    // A catch-up after a step that gathered for a frame copies the lagging runs (the
    // readback holds only the drawn nodes), and the bytes agree.
    told.read_whole_after_step();
    session_step(&mut told, 40, &mut out);
    session_step(&mut untold, 40, &mut out);
    let lagging = told.gpu_tiles_behind().unwrap_or(0);
    let before = told.gpu_readback_counts().map_or(0, |(_, c)| c);
    told.catch_up();
    let after = told.gpu_readback_counts().map_or(0, |(_, c)| c);
    assert_eq!(after - before, u64::from(lagging > 0));
    assert_eq!(told.gpu_tiles_behind(), Some(0));
    assert!(told.gpu_adapter().is_some() && untold.gpu_adapter().is_some());
    assert_eq!(told.state_hash(), untold.state_hash());
}

#[test]
fn a_device_lost_before_a_frame_reads_it_leaves_a_whole_frame_on_the_cpu() {
    // The device goes after an announced step while a tile lags: the frame's read fails,
    // the membrane gives the device up (back to its last checkpoint, as any read that
    // fails), and the frame draws that state, every node finite, on the CPU.
    let (_gpu, mut m, _, mut grid) = two_on_one_device();
    let mut out = ModelOutput::default();
    for k in 0..10 {
        if k == 9 {
            m.read_whole_after_step();
        }
        session_step(&mut m, k, &mut out);
    }
    assert!(m.gpu_tiles_behind().is_some_and(|n| n > 0), "none lags");
    assert!(m.inject_device_loss());
    let drawn = m.place_drawn(&mut grid);
    assert!(m.gpu_adapter().is_none(), "on the CPU from the loss on");
    assert!(m.take_device_note().is_some_and(|n| !n.is_empty()));
    let again = m.place_drawn(&mut grid.clone());
    assert_eq!(first_difference(&drawn, &again), None);
    assert!(drawn.iter().all(|p| p.is_finite()));
    assert!(drawn.iter().filter(|p| **p != Vec3::ZERO).count() > drawn.len() / 2);
}

#[test]
fn a_device_lost_before_a_frame_reads_its_gathered_nodes_leaves_a_whole_frame_on_the_cpu() {
    // As above, with the grid laid out on the device by an earlier frame, so that the
    // announced step gathers the lagging tiles' drawn nodes: the lost device's read fails
    // the same way, and the frame draws the state the membrane goes on from.
    let (_gpu, mut m, _, mut grid) = two_on_one_device();
    let mut out = ModelOutput::default();
    for k in 0..10 {
        if k == 4 || k == 9 {
            m.read_whole_after_step();
        }
        session_step(&mut m, k, &mut out);
        if k == 4 {
            m.place_drawn(&mut grid);
        }
    }
    let before = m.gpu_frame_copies();
    assert!(m.gpu_tiles_behind().is_some_and(|n| n > 0), "none lags");
    assert!(m.gpu_last_readback_bytes().is_some_and(|b| b > 0));
    assert!(m.inject_device_loss());
    let drawn = m.place_drawn(&mut grid);
    assert!(
        before.is_some() && m.gpu_adapter().is_none(),
        "on the CPU from the loss on"
    );
    assert!(m.take_device_note().is_some_and(|n| !n.is_empty()));
    let again = m.place_drawn(&mut grid.clone());
    assert_eq!(first_difference(&drawn, &again), None);
    assert!(drawn.iter().all(|p| p.is_finite()));
    assert!(drawn.iter().filter(|p| **p != Vec3::ZERO).count() > drawn.len() / 2);
}
