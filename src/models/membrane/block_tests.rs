//! The block kernel against the row kernel: one substep of a run, node by node, bit for bit.

use super::block::{Block, BlockPass};
use super::forces::{self, RowScratch, Whole};
use super::tests::{params, tube};
use super::*;

/// One substep of `h` over `span` by the row kernel (as the active set stepped runs before
/// the block kernel): the span's new state by row, layer, component and column.
fn by_rows(m: &Membrane, span: ([usize; 2], [usize; 2]), h: f32) -> Vec<f32> {
    let ([r0, r1], [c0, c1]) = span;
    let (rows, cols) = (m.rows, m.cols);
    let whole = Whole {
        data: &m.state.data,
        rows,
        cols,
    };
    let mut sc = RowScratch::default();
    let mut out = Vec::new();
    let (g, d) = (m.params.gravity, m.params.damping_per_s);
    for i in r0..r1 {
        forces::row::<_, false>(m, &whole, i, c0..c1, i == r0, &mut sc);
        for l in 0..LAYERS {
            let b = l * rows + i;
            let inv_m = &m.rows_data[(b * field::COUNT + field::INV_MASS) * cols..][..cols];
            let mut row = vec![0.0f32; 6 * (c1 - c0)];
            let w = c1 - c0;
            for c in 0..3 {
                let f = sc.row(l, c, cols);
                for j in c0..c1 {
                    let x0 = m.state.data[(b * 6 + c) * cols + j];
                    let v0 = m.state.data[(b * 6 + 3 + c) * cols + j];
                    let acc = f[j] * inv_m[j] + (g[c] - d * v0);
                    let v = v0 + h * acc;
                    row[(3 + c) * w + j - c0] = v;
                    row[c * w + j - c0] = x0 + h * v;
                }
            }
            out.extend(row);
        }
    }
    out
}

type Span = ([usize; 2], [usize; 2]);

/// The same substep of the runs `runs` by one block over `span` (the rectangle round them),
/// the runs' new state in the same order, run by run.
fn by_block(m: &Membrane, span: Span, runs: &[Span], h: f32) -> Vec<f32> {
    let mut copy = m.clone();
    let mut block = Block::default();
    block.prepare(&copy, span, runs);
    copy.vectorized(BlockPass {
        m: &copy,
        block: &mut block,
        h,
    });
    block.scatter(&mut copy);
    let (rows, cols) = (m.rows, m.cols);
    let mut out = Vec::new();
    for &([r0, r1], [c0, c1]) in runs {
        for i in r0..r1 {
            for l in 0..LAYERS {
                let b = l * rows + i;
                for k in 0..6 {
                    out.extend_from_slice(&copy.state.data[(b * 6 + k) * cols + c0..][..c1 - c0]);
                }
            }
        }
    }
    // Nothing outside the runs was written.
    let inside = |node: usize| {
        let (_, i, j) = m.coords(node);
        runs.iter()
            .any(|([r0, r1], [c0, c1])| (*r0..*r1).contains(&i) && (*c0..*c1).contains(&j))
    };
    for node in (0..m.len()).filter(|&node| !inside(node)) {
        for c in 0..6 {
            let at = m.state_at(c, node);
            assert_eq!(copy.state.data[at].to_bits(), m.state.data[at].to_bits());
        }
    }
    out
}

/// A tube (a ring round the section) or a flat sheet, moved off its rest, with a cut, the
/// attachments' targets moved and external forces (two on one node).
fn stirred(periodic: bool) -> Membrane {
    let mut shape = tube(12, 16, 0.012, [0.01, 0.012, 0.013, 0.016]);
    shape.periodic = periodic;
    let mut m = Membrane::new(shape, params(Integrator::Symplectic)).expect("membrane");
    let (rows, cols) = (m.rows, m.cols);
    for node in 0..m.len() {
        let s = node as f32;
        let kick = Vec3::new((s * 0.37).sin(), (s * 0.91).cos(), (s * 0.13).sin()) * 2e-4;
        for c in 0..3 {
            let (x, v) = (m.state_at(c, node), m.state_at(3 + c, node));
            m.state.data[x] += kick[c];
            m.state.data[v] = 30.0 * kick[c];
        }
    }
    m.cut_plane(m.position(m.node(1, 6, 3)), 0.003);
    for j in 0..cols {
        let p = m.position(m.node(0, 4, j)) + Vec3::new(3e-4, 0.0, 0.0);
        m.set_target(4, j, p);
    }
    m.add_force(m.node(2, 5, 7), Vec3::new(0.01, -0.02, 0.005));
    m.add_force(m.node(2, 5, 7), Vec3::new(-0.003, 0.001, 0.002));
    m.add_force(m.node(0, 0, 0), Vec3::new(0.0, 0.004, 0.0));
    m.add_force(m.node(3, rows - 1, cols - 1), Vec3::new(0.002, 0.0, 0.0));
    forces::sort_external(&mut m.external);
    m
}

#[test]
fn the_block_kernel_steps_a_run_as_the_row_kernel_does_bit_for_bit() {
    for periodic in [true, false] {
        let m = stirred(periodic);
        let (rows, cols) = (m.rows, m.cols);
        let h = 0.5 * m.explicit_step_limit();
        let spans = [
            ([0, rows], [0, cols]),        // everything (the ring closes on itself)
            ([0, 2], [0, 4]),              // the first rows, the seam on the left
            ([rows - 3, rows], [9, cols]), // the last rows, the seam on the right
            ([4, 7], [3, 4]),              // one column wide
            ([4, 8], [5, 7]),              // two columns wide, through the cut
            ([2, 10], [1, cols - 1]),      // the middle
        ];
        for span in spans {
            let (a, b) = (by_rows(&m, span, h), by_block(&m, span, &[span], h));
            assert_eq!(a.len(), b.len());
            let moved = a
                .iter()
                .zip(&m.state.data)
                .any(|(x, y)| x.to_bits() != y.to_bits());
            assert!(moved, "{span:?}: the substep moved nothing");
            for (k, (x, y)) in a.iter().zip(&b).enumerate() {
                assert_eq!(
                    x.to_bits(),
                    y.to_bits(),
                    "periodic {periodic}, span {span:?}, value {k}: {x} vs {y}"
                );
            }
        }
    }
}

#[test]
fn a_block_of_several_runs_steps_each_as_the_row_kernel_does_and_leaves_the_rest() {
    // Runs in successive rows of tiles step as one block over the rectangle round them;
    // the sleeping nodes inside it (between and beside the runs) are never written back.
    for periodic in [true, false] {
        let m = stirred(periodic);
        let h = 0.5 * m.explicit_step_limit();
        let cols = m.cols;
        let cases: [(Span, Vec<Span>); 3] = [
            (([2, 8], [1, 12]), vec![([2, 4], [1, 5]), ([4, 8], [3, 12])]),
            // Two runs in one row of tiles with a sleeping gap, and one under both.
            (
                ([4, 8], [0, cols]),
                vec![([4, 6], [0, 3]), ([4, 6], [9, cols]), ([6, 8], [2, 11])],
            ),
            (([0, 4], [5, 9]), vec![([0, 2], [5, 6]), ([2, 4], [8, 9])]),
        ];
        for (span, runs) in cases {
            let a: Vec<f32> = runs.iter().flat_map(|&r| by_rows(&m, r, h)).collect();
            let b = by_block(&m, span, &runs, h);
            assert_eq!(a.len(), b.len());
            for (k, (x, y)) in a.iter().zip(&b).enumerate() {
                assert_eq!(
                    x.to_bits(),
                    y.to_bits(),
                    "periodic {periodic}, block {span:?}, value {k}: {x} vs {y}"
                );
            }
        }
    }
}

#[test]
fn the_block_kernel_carries_a_run_through_a_step_as_the_row_kernel_does() {
    // Five substeps of a run inside sleeping tissue: after the first, the block keeps its
    // own nodes and refreshes only its ring; the row kernel reads everything afresh.
    let m = stirred(true);
    let span = ([3, 9], [14, 16]);
    let h = 0.5 * m.explicit_step_limit();
    let mut rows_way = m.clone();
    for _ in 0..5 {
        let new = by_rows(&rows_way, span, h);
        let ([r0, r1], [c0, c1]) = span;
        let w = c1 - c0;
        let (rows, cols) = (rows_way.rows, rows_way.cols);
        for (n, i) in (r0..r1).enumerate() {
            for l in 0..LAYERS {
                let b = l * rows + i;
                for k in 0..6 {
                    let src = &new[((n * LAYERS + l) * 6 + k) * w..][..w];
                    rows_way.state.data[(b * 6 + k) * cols + c0..][..w].copy_from_slice(src);
                }
            }
        }
    }
    let mut block_way = m.clone();
    let mut block = Block::default();
    block.prepare(&block_way, span, &[span]);
    for _ in 0..5 {
        block_way.vectorized(BlockPass {
            m: &block_way,
            block: &mut block,
            h,
        });
        block.scatter(&mut block_way);
    }
    assert_eq!(rows_way.state_hash(), block_way.state_hash());
    assert_ne!(m.state_hash(), block_way.state_hash(), "it moved");
}

#[test]
fn a_block_gathers_its_springs_again_only_after_they_change() {
    // A block prepared again over the same span keeps the springs, tethers and masses it
    // gathered and takes the attachments anew; after a cut, a damping set or a checkpoint
    // loaded it gathers everything. Each time its parameters are a fresh block's, bit for
    // bit.
    let mut m = stirred(true);
    let span = ([3, 9], [2, 12]);
    let mut kept = Block::default();
    let check = |m: &Membrane, kept: &mut Block, what: &str| {
        kept.prepare(m, span, &[span]);
        let mut fresh = Block::default();
        fresh.prepare(m, span, &[span]);
        assert_eq!(kept.params().len(), fresh.params().len(), "{what}");
        for (k, (a, b)) in kept.params().iter().zip(fresh.params()).enumerate() {
            assert_eq!(a.to_bits(), b.to_bits(), "{what}: value {k}");
        }
    };
    let fresh_par = |m: &Membrane| {
        let mut b = Block::default();
        b.prepare(m, span, &[span]);
        b.params().to_vec()
    };
    check(&m, &mut kept, "first");
    m.save();
    let before = fresh_par(&m);
    // The attachments' targets move every step.
    for j in 0..m.cols {
        let p = m.position(m.node(0, 5, j)) + Vec3::new(0.0, 2e-4, 0.0);
        m.set_target(5, j, p);
    }
    check(&m, &mut kept, "targets moved");
    assert_ne!(fresh_par(&m), before, "the targets are gathered");
    let cut = m.cut_plane(m.position(m.node(1, 6, 8)), 0.003);
    assert!(cut > 0, "the cut took springs");
    check(&m, &mut kept, "after a cut");
    let after_cut = fresh_par(&m);
    m.load();
    check(&m, &mut kept, "the checkpoint loaded");
    assert_ne!(fresh_par(&m), after_cut, "the load restored the springs");
    m.params.spring_damping_ratio *= 2.0;
    m.set_spring_damping();
    check(&m, &mut kept, "the damping set");
}
