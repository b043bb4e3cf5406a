//! Which blocks of a step share nodes (`active.rs`): a block reads its ring (the rows above
//! and below it, its two columns either side) and the sleeping nodes between its runs from
//! the membrane at every substep. Where all of those are sleeping nodes, they keep their
//! state through the step, so the block need not read its ring's rows again; and before the
//! step's last substep a block writes back only those of its nodes that some block reads
//! that way (where the awake tissue straddles the section's seam at column 0, the two
//! blocks either side read each other's edge columns). Either way each block reads the
//! same values as when every block wrote back after every substep and read its whole ring
//! again: the bytes do not change.
//!
//! Layer 0's loads by group (`anchor_sums`) are taken from the forces each block finds at
//! its first substep, which are the row kernel's, bit for bit: one pass over the awake
//! nodes fewer a step.

use super::Activity;
use crate::models::membrane::Membrane;
use crate::models::membrane::block::Block;

/// No block.
const NONE: u32 = u32::MAX;

#[cfg(test)]
thread_local! {
    /// Every block writes all its nodes back after every substep and reads its whole ring
    /// and gaps again, and layer 0's loads are found by the row kernel before the substeps,
    /// as before this module (set on the thread that steps the model: the tests compare the
    /// two).
    pub(crate) static WHOLE_EXCHANGE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether this step exchanges everything ([`WHOLE_EXCHANGE`], tests only).
pub(super) fn whole_exchange() -> bool {
    #[cfg(test)]
    if WHOLE_EXCHANGE.with(std::cell::Cell::get) {
        return true;
    }
    false
}

/// Sets each block's [`Block::exports`], [`Block::ring_rows_live`] and
/// [`Block::live_gaps`] for this step's groups (`blocks[g]` prepared for `a.groups[g]`).
pub(super) fn mark(m: &Membrane, a: &mut Activity, blocks: &mut [Block]) {
    let (rows, cols) = (m.rows, m.cols);
    let (tr, tc) = (a.params.tile_rows, a.params.tile_cols);
    // Each awake tile's block.
    let mut of_tile = vec![NONE; a.awake.len()];
    for (g, group) in a.groups.iter().enumerate() {
        for &r in &group.members {
            let ([r0, _], [c0, c1]) = a.runs[r];
            let ti = r0 / tr;
            for tj in c0 / tc..c1.div_ceil(tc) {
                of_tile[ti * a.tiles_c + tj] = g as u32;
            }
        }
    }
    let block_at = |i: usize, j: usize| of_tile[(i / tr) * a.tiles_c + j / tc];
    let mut ring_live = vec![false; blocks.len()];
    for b in blocks.iter_mut() {
        b.exports.clear();
    }
    let mut live_gaps = Vec::new();
    for (g, group) in a.groups.iter().enumerate() {
        live_gaps.clear();
        let ([r0, r1], [c0, c1]) = group.span;
        let w = c1 - c0;
        // Every node the block reads but does not step as its own: rows `r0 - 1 ..= r1`
        // (those inside the membrane), block columns `0 ..= w + 1` (wrapped round).
        for i in r0.saturating_sub(1)..(r1 + 1).min(rows) {
            let ring_row = i + 1 == r0 || i == r1;
            for q in 0..w + 2 {
                let j = (c0 + q + cols - 1) % cols;
                let owner = block_at(i, j);
                if owner == NONE {
                    continue;
                }
                let own = !ring_row && (1..=w).contains(&q) && owner == g as u32;
                if own {
                    continue;
                }
                blocks[owner as usize].exports.push((i as u32, j as u32));
                if ring_row {
                    ring_live[g] = true;
                } else {
                    // Block row `i - r0 + 1`, column `q`: one node wide, joined below.
                    live_gaps.push((i + 1 - r0, q, q + 1));
                }
            }
        }
        let b = &mut blocks[g];
        b.live_gaps.clear();
        for &(r, qa, qb) in &live_gaps {
            match b.live_gaps.last_mut() {
                Some(last) if last.0 == r && last.2 == qa => last.2 = qb,
                _ => b.live_gaps.push((r, qa, qb)),
            }
        }
    }
    for (b, l) in blocks.iter_mut().zip(ring_live) {
        b.exports.sort_unstable();
        b.exports.dedup();
        b.ring_rows_live = l;
    }
}

/// Layer 0's loads on the awake runs, run by run in order as
/// [`Membrane::loads_over_runs`] lists them, from the blocks' first substep
/// ([`super::block::Block::keep_loads`]), summed by group.
pub(super) fn sum_block_loads(m: &mut Membrane, a: &Activity, blocks: &[Block]) {
    let mut block_of = vec![0; a.runs.len()];
    for (g, group) in a.groups.iter().enumerate() {
        for &r in &group.members {
            block_of[r] = g;
        }
    }
    let mut loads = std::mem::take(&mut m.load_scratch);
    loads.clear();
    for (&([r0, r1], [c0, c1]), &g) in a.runs.iter().zip(&block_of) {
        let b = &blocks[g];
        for i in r0..r1 {
            loads.extend((c0..c1).map(|j| (i as u32, j as u32, b.load(i, j))));
        }
    }
    crate::models::membrane::anchor_sums::from_loads(m, &loads);
    m.load_scratch = loads;
}

#[cfg(test)]
mod tests {
    use super::WHOLE_EXCHANGE;
    use crate::models::membrane::tests::{params, tube};
    use crate::models::membrane::{ActivityParams, Integrator, Membrane};
    use glam::Vec3;

    /// Awake tiles (row of tiles, column of tiles) on a 12 x 8 grid of 2 x 4 tiles: a blob
    /// across the section's seam (two blocks that read each other's edge columns), two tiles
    /// touching at a corner (one block's ring row holds the other's nodes), and a run inside
    /// another block's rectangle (a gap of that block holds it).
    const AWAKE: [(usize, usize); 11] = [
        (2, 0),
        (2, 7),
        (3, 0),
        (3, 7),
        (6, 2),
        (7, 3),
        (9, 1),
        (9, 3),
        (10, 1),
        (10, 2),
        (10, 3),
    ];

    fn membrane() -> Membrane {
        let mut p = params(Integrator::Symplectic);
        p.gravity = Vec3::ZERO;
        let (rows, cols) = (24, 32);
        let mut m = Membrane::new(tube(rows, cols, 0.012, [0.01, 0.012, 0.013, 0.016]), p)
            .expect("membrane");
        m.use_active_set(ActivityParams {
            tile_rows: 2,
            tile_cols: 4,
            ..ActivityParams::default()
        });
        // Layer 0's loads summed by row, each node weighted by its column.
        let members: Vec<_> = (0..rows * cols)
            .map(|k| {
                (
                    k / cols,
                    k % cols,
                    k / cols,
                    (k % cols) as f32 / cols as f32,
                )
            })
            .collect();
        let about: Vec<_> = (0..rows)
            .map(|i| Vec3::X * 0.012 * i as f32 / (rows - 1) as f32)
            .collect();
        m.group_anchor_loads(&members, &about).expect("groups");
        m
    }

    /// One step: the pattern's tiles kept awake and pushed, each its own way.
    fn step(m: &mut Membrane, k: usize) {
        let (_, tc) = m.tiles();
        for (n, &(ti, tj)) in AWAKE.iter().enumerate() {
            m.wake(ti * tc + tj);
            let ([r0, _], [c0, _]) = m.tile_span(ti * tc + tj);
            let s = if (n + k).is_multiple_of(2) { 1.0 } else { -1.0 };
            let f = Vec3::new(s * 2e-4, 1e-4 * n as f32, -s * 1e-4);
            m.add_force(m.node(1 + n % 2, r0 + 1, c0 + 1), f);
        }
        m.advance(1e-3, 0.9);
    }

    #[test]
    fn blocks_that_exchange_only_what_is_read_step_as_blocks_that_exchange_everything() {
        let mut whole = membrane();
        let mut lean = membrane();
        let mut seen = [false; 4];
        for k in 0..30 {
            WHOLE_EXCHANGE.with(|w| w.set(true));
            step(&mut whole, k);
            WHOLE_EXCHANGE.with(|w| w.set(false));
            step(&mut lean, k);
            let bits = |m: &Membrane| m.state.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert!(
                bits(&whole) == bits(&lean),
                "the states differ after step {k}"
            );
            assert_eq!(whole.anchor_sums(), lean.anchor_sums(), "step {k}");
            let a = lean.activity.as_ref().expect("an active set");
            let blocks = &a.buffers[..a.groups.len()];
            seen[0] |= blocks.iter().any(|b| !b.exports.is_empty());
            seen[1] |= blocks.iter().any(|b| b.ring_rows_live);
            seen[2] |= blocks.iter().any(|b| !b.ring_rows_live);
            seen[3] |= blocks.iter().any(|b| !b.live_gaps.is_empty());
        }
        // Each way a block can share was taken.
        assert_eq!(seen, [true; 4]);
        // The loads were summed (not all zero) and the tissue moved.
        assert!(lean.anchor_sums().iter().any(|s| s.force.length() > 0.0));
        assert!(lean.awake_fraction() > 0.0);
    }
}
