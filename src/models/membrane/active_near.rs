//! The active set's broad phase for an instrument: the awake tiles near a box or near the
//! capsules of an instrument's cylinders, by the tiles' boxes (their cost follows the tiles,
//! not their nodes). The tiles returned are those the caller reads: on a device they are
//! brought up to date and come back with the next step (`device_lazy.rs`), and so do the
//! tiles the same query would meet reaching [`AHEAD_M`] further (where the caller may read at
//! the next step), so that a moving instrument rarely waits for a round trip to the device.

use crate::models::membrane::Membrane;
use glam::Vec3;

/// Slack on a capsule's reach, relative and absolute (m): a tile is kept when rounding might
/// put one of its nodes just inside.
const SLACK_REL: f32 = 1e-4;
const SLACK_M: f32 = 1e-6;

/// How much further than a query reaches the tiles it would meet come back with the next step
/// on a device, m: an instrument at 1 m/s moves this far in a 1 ms step. The tiles are 2 mm
/// along the rectum's section and 5 to 8 mm around it, so this brings back about half the
/// tiles that all the neighbours of the read ones would (measured in the rectum's demo).
pub const AHEAD_M: f32 = 1e-3;

impl Membrane {
    /// The positions of nodes `c0..c1` of row `i` of layer `l`, one slice per coordinate
    /// (the state holds a row's x, its y and its z each in one stretch), m; empty slices
    /// where the row or the columns lie outside the grid. The caller reads a tile it was
    /// given by a query here (on a device, the tiles that are current on the CPU).
    pub fn row_positions(&self, l: usize, i: usize, [c0, c1]: [usize; 2]) -> [&[f32]; 3] {
        let inside = l < super::LAYERS && i < self.rows && c0 <= c1 && c1 <= self.cols;
        #[cfg(test)]
        if inside && c0 < c1 {
            self.assert_current(self.node(l, i, c0));
        }
        let d = &self.state.data;
        std::array::from_fn(|c| {
            let s = self.state_at(c, self.node(l, i, 0));
            d.get(s + c0..s + c1).filter(|_| inside).unwrap_or(&[])
        })
    }

    /// The awake tiles whose box (all layers, as the last step left them) comes within
    /// `margin` of the box `(lo, hi)`, ascending, into `out`. Without an active set, the one
    /// tile that is the whole grid. Their nodes are current on the CPU.
    pub fn awake_tiles_near(&mut self, lo: Vec3, hi: Vec3, margin: f32, out: &mut Vec<usize>) {
        self.awake_tiles_near_among(lo, hi, margin, &[], out);
    }

    /// [`Membrane::awake_tiles_near`] among the tiles `among` marks (by tile; every tile
    /// where it is empty): a caller that reads only some nodes (a region's) leaves the tiles
    /// without any unread, so on a device they need not come back.
    pub fn awake_tiles_near_among(
        &mut self,
        lo: Vec3,
        hi: Vec3,
        margin: f32,
        among: &[bool],
        out: &mut Vec<usize>,
    ) {
        out.clear();
        let Some(a) = &self.activity else {
            out.push(0);
            return;
        };
        let ahead = self.marks_ahead();
        let mut next = Vec::new();
        let m = Vec3::splat(margin.max(0.0));
        let far = m + Vec3::splat(if ahead { AHEAD_M } else { 0.0 });
        for t in 0..a.awake.len() {
            let Some((blo, bhi)) = a.tile_box(t) else {
                continue;
            };
            let kept = among.get(t).copied().unwrap_or(among.is_empty());
            let meets = |m: Vec3| (blo - m).cmple(hi).all() && (bhi + m).cmpge(lo).all();
            if !(kept && a.awake[t] && meets(far)) {
                continue;
            }
            if meets(m) {
                out.push(t);
            } else {
                next.push(t);
            }
        }
        self.read_tiles(out);
        self.read_tiles_next(&next);
    }

    /// The awake tiles that may hold a node within `r` of a segment `(p0, p1, r)` of
    /// `capsules` (an instrument's cylinders at their widest), ascending, into `out`: every
    /// tile with such a node is among them. A tile is kept where the segment meets its box
    /// grown by `r` on every side and comes within `r` plus half the box's diagonal of the
    /// box's middle (each holds for every such node, so both do). Without an active set, the
    /// one tile that is the whole grid. Their nodes are current on the CPU.
    pub fn awake_tiles_near_capsules(
        &mut self,
        capsules: &[(Vec3, Vec3, f32)],
        out: &mut Vec<usize>,
    ) {
        out.clear();
        let Some(a) = &self.activity else {
            out.push(0);
            return;
        };
        let ahead = if self.marks_ahead() { AHEAD_M } else { 0.0 };
        let mut next = Vec::new();
        for t in 0..a.awake.len() {
            let Some((lo, hi)) = a.tile_box(t).filter(|_| a.awake[t]) else {
                continue;
            };
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let (mid, half) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
            let meets = |extra: f32| {
                capsules.iter().any(|&(p0, p1, r)| {
                    let r = r + extra;
                    let grow = Vec3::splat(r * (1.0 + SLACK_REL) + SLACK_M);
                    let reach = (r + half) * (1.0 + SLACK_REL) + SLACK_M;
                    segment_meets_box(p0, p1, lo - grow, hi + grow)
                        && distance_to_segment(mid, p0, p1) <= reach
                })
            };
            if meets(0.0) {
                out.push(t);
            } else if ahead > 0.0 && meets(ahead) {
                next.push(t);
            }
        }
        self.read_tiles(out);
        self.read_tiles_next(&next);
    }
}

/// Whether the segment `a`-`b` meets the box `lo`-`hi` (the part of the segment within each
/// axis's slab, intersected over the axes).
fn segment_meets_box(a: Vec3, b: Vec3, lo: Vec3, hi: Vec3) -> bool {
    let d = b - a;
    let (mut s0, mut s1) = (0.0f32, 1.0f32);
    for k in 0..3 {
        if d[k] == 0.0 {
            if a[k] < lo[k] || a[k] > hi[k] {
                return false;
            }
            continue;
        }
        let (u, v) = ((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]);
        s0 = s0.max(u.min(v));
        s1 = s1.min(u.max(v));
        if s0 > s1 {
            return false;
        }
    }
    true
}

/// The distance from `p` to the segment `a`-`b`, m.
fn distance_to_segment(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let s = if len2 > 0.0 {
        ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * s)
}
