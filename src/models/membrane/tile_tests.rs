//! The active set's tile size, layer 0's own forces and the springs' damping across grids.

use super::forces::{RowScratch, Whole, row};
use super::tests::{params, sleepy_tube_with, tube};
use super::*;

/// The active set's tests' tube with tiles of `rows x cols`.
fn tube_with_tiles(rows: usize, cols: usize) -> Membrane {
    sleepy_tube_with(ActivityParams {
        tile_rows: rows,
        tile_cols: cols,
        ..ActivityParams::default()
    })
}

/// Pulls layer 1's node at row 64, column 64 along the tube with 0.2 mN for 60 steps of
/// 1 ms, a tool's box around it; returns how far it moved and the mean share of nodes that
/// stepped.
fn pull(m: &mut Membrane) -> (f32, f64) {
    let node = m.node(1, 64, 64);
    let start = m.position(node);
    for _ in 0..60 {
        let p = m.position(node);
        m.wake_near(&[(p - Vec3::splat(1e-3), p + Vec3::splat(1e-3))]);
        m.add_force(node, Vec3::X * 2e-4);
        m.advance(1e-3, 0.9);
    }
    (m.position(node).distance(start), m.awake_fraction())
}

#[test]
fn smaller_tiles_step_fewer_nodes_and_move_the_tissue_alike() {
    let mut big = tube_with_tiles(TILE_ROWS, TILE_COLS);
    let mut small = tube_with_tiles(4, 4);
    assert_eq!(big.tiles(), (16, 16));
    assert_eq!(small.tiles(), (32, 64));
    // The tile holding a node follows the tile size.
    assert_eq!(small.tile_of(9, 13), 2 * 64 + 3);
    assert_eq!(small.tile_span(2 * 64 + 3), ([8, 12], [12, 16]));
    let (moved_big, share_big) = pull(&mut big);
    let (moved_small, share_small) = pull(&mut small);
    assert!(moved_big > 1e-4, "{moved_big}");
    // The same tissue moves the same: the tiles only choose which nodes step.
    let rel = (moved_small - moved_big).abs() / moved_big;
    assert!(rel < 0.02, "{moved_small} vs {moved_big} ({rel})");
    // ... and fewer of them step with small tiles (measured: 3.9 % of the nodes a step
    // against 5.8 %).
    assert!(
        share_small < 0.8 * share_big,
        "{share_small} vs {share_big}"
    );
}

#[test]
fn layer_zeros_forces_alone_are_the_whole_rows_bit_for_bit() {
    // A displaced, moving tube with external forces on every layer.
    let mut m = Membrane::new(
        tube(24, 32, 0.02, [0.01, 0.012, 0.013, 0.016]),
        params(Integrator::Symplectic),
    )
    .expect("membrane");
    for (k, node) in (0..m.len()).step_by(7).enumerate() {
        let d = Vec3::new(
            (k % 5) as f32 - 2.0,
            (k % 3) as f32 - 1.0,
            (k % 7) as f32 - 3.0,
        );
        m.displace(node, d * 1e-5);
        m.add_force(node, d * 1e-4);
    }
    m.advance(1e-3, 0.9);
    for (k, node) in (0..m.len()).step_by(5).enumerate() {
        m.add_force(node, Vec3::new(1e-4, -(k as f32) * 1e-6, 2e-5));
    }
    forces::sort_external(&mut m.external);
    let (rows, cols) = (m.rows, m.cols);
    let whole = Whole {
        data: &m.state.data,
        rows,
        cols,
    };
    let (mut full, mut only) = (RowScratch::default(), RowScratch::default());
    // Two spans, each from its first row on, as the active set's runs go.
    for span in [0..cols, 5..19] {
        for i in 0..rows {
            row::<_, false>(&m, &whole, i, span.clone(), i == 0, &mut full);
            row::<_, true>(&m, &whole, i, span.clone(), i == 0, &mut only);
            for c in 0..3 {
                let (a, b) = (
                    &full.row(0, c, cols)[span.clone()],
                    &only.row(0, c, cols)[span.clone()],
                );
                let same = a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
                assert!(same, "row {i}, component {c}: {a:?} vs {b:?}");
                assert!(a.iter().any(|&f| f != 0.0));
            }
        }
    }
}

#[test]
fn a_coarser_sheet_with_its_ratio_over_the_spacing_keeps_the_tissues_damping() {
    let sheet_at = |spacing: f32, ratio: f32| {
        let mut p = params(Integrator::Symplectic);
        p.spring_damping_ratio = ratio;
        p.link_damping_ratio = 0.5;
        Membrane::new(MembraneShape::sheet(9, 9, spacing, 1e-3), p).expect("a sheet")
    };
    let fine = sheet_at(5e-4, 0.5);
    let coarse = sheet_at(2e-3, 0.5 / 4.0);
    let same_ratio = sheet_at(2e-3, 0.5);
    let (b_fine, b_coarse, b_same) = (fine.beta[4], coarse.beta[4], same_ratio.beta[4]);
    // In a layer: the same damping time with a quarter of the ratio on a grid 4 times
    // coarser; with the same ratio, 4 times more.
    let rel = |a: f32, b: f32| (a - b).abs() / b;
    assert!(
        rel(b_coarse[AROUND], b_fine[AROUND]) < 1e-5,
        "{b_coarse:?} vs {b_fine:?}"
    );
    assert!(rel(b_coarse[ALONG], b_fine[ALONG]) < 1e-5);
    assert!(rel(b_same[AROUND], 4.0 * b_fine[AROUND]) < 1e-5);
    // Between layers the ratio gives the same damping time at any spacing.
    assert!(
        rel(b_coarse[LINK], b_fine[LINK]) < 1e-5,
        "{b_coarse:?} vs {b_fine:?}"
    );
    assert!(b_fine[LINK] > 0.0 && b_fine[AROUND] > 0.0);
}

#[test]
fn the_capsule_query_keeps_every_tile_a_cylinder_reaches_and_no_more_than_the_box_does() {
    // Every tile awake and moved a little; segments of several lengths and slants through
    // and beside the tube. The tiles kept hold every node within the radius of a segment
    // (the exact set), and are among those whose boxes meet the box round the capsules (the
    // query the press used before).
    let mut m = tube_with_tiles(TILE_ROWS, TILE_COLS);
    m.stay_awake();
    for _ in 0..3 {
        m.add_force(m.node(1, 64, 64), Vec3::X * 2e-4);
        m.advance(1e-3, 0.9);
    }
    let centre = m.position(m.node(1, 64, 0));
    let cases = [
        (centre + Vec3::new(0.0, 0.3, 0.0), centre, 0.0025),
        (
            centre + Vec3::new(0.2, 0.2, 0.1),
            centre - Vec3::Y * 0.002,
            0.0025,
        ),
        (
            centre - Vec3::X * 0.004,
            centre + Vec3::new(0.004, 0.001, 0.0),
            0.0005,
        ),
        (
            centre + Vec3::Z * 0.05,
            centre + Vec3::new(0.0, 0.0, 0.03),
            0.002,
        ),
    ];
    let (tr, tc) = m.tiles();
    for (k, &(p0, p1, r)) in cases.iter().enumerate() {
        let mut kept = Vec::new();
        m.awake_tiles_near_capsules(&[(p0, p1, r)], &mut kept);
        let reached: Vec<usize> = (0..tr * tc)
            .filter(|&t| {
                let ([r0, r1], [c0, c1]) = m.tile_span(t);
                (0..LAYERS).any(|l| {
                    (r0..r1).any(|i| {
                        (c0..c1).any(|j| {
                            let x = m.position(m.node(l, i, j));
                            let s = ((x - p0).dot(p1 - p0) / (p1 - p0).length_squared())
                                .clamp(0.0, 1.0);
                            x.distance(p0 + (p1 - p0) * s) < r
                        })
                    })
                })
            })
            .collect();
        let r3 = Vec3::splat(r);
        let mut boxed = Vec::new();
        m.awake_tiles_near(p0.min(p1) - r3, p0.max(p1) + r3, 0.0, &mut boxed);
        assert!(
            reached.iter().all(|t| kept.contains(t)),
            "case {k}: {reached:?} in {kept:?}"
        );
        assert!(
            kept.iter().all(|t| boxed.contains(t)),
            "case {k}: {kept:?} in {boxed:?}"
        );
        if k < 2 {
            assert!(
                !reached.is_empty(),
                "case {k}: the segment reaches the tube"
            );
        }
        if k == 1 {
            assert!(kept.len() < boxed.len(), "case {k}: {kept:?} of {boxed:?}");
        }
    }
}
