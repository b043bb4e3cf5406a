//! Tissue point sets for the instrument collision of `tool_cylinder`: a borrowed view over the
//! two layouts the models use (one slice per coordinate, or a slice of `Vec3`), and the broad
//! phase, an axis-aligned box per block of consecutive points.

use super::tool_cylinder::ToolError;
use glam::Vec3;
use rayon::prelude::*;
use std::ops::Range;

/// Points per block of the broad phase ([`PointBlocks`]): block `b` holds the points
/// `b * BLOCK_POINTS .. (b + 1) * BLOCK_POINTS`.
pub const BLOCK_POINTS: usize = 256;
/// Points below which the blocks' boxes are refreshed on the calling thread.
const PARALLEL_POINTS: usize = 16_384;

/// A tissue point set, borrowed: either one slice per coordinate (the membrane's layout) or a
/// slice of `Vec3` (meshes). Positions in metres.
#[derive(Debug, Clone, Copy)]
pub struct PointCloud<'a>(Layout<'a>);

#[derive(Debug, Clone, Copy)]
enum Layout<'a> {
    Components([&'a [f32]; 3]),
    Points(&'a [Vec3]),
}

impl<'a> PointCloud<'a> {
    /// Points `(x[i], y[i], z[i])`; the three slices must have the same length.
    pub fn from_components(x: &'a [f32], y: &'a [f32], z: &'a [f32]) -> Result<Self, ToolError> {
        if x.len() == y.len() && x.len() == z.len() {
            Ok(Self(Layout::Components([x, y, z])))
        } else {
            Err(ToolError::ComponentLengths {
                x: x.len(),
                y: y.len(),
                z: z.len(),
            })
        }
    }

    /// The points of a slice of positions.
    pub fn from_points(points: &'a [Vec3]) -> Self {
        Self(Layout::Points(points))
    }

    /// The number of points.
    pub fn len(&self) -> usize {
        match self.0 {
            Layout::Components([x, _, _]) => x.len(),
            Layout::Points(p) => p.len(),
        }
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Calls `f(index, position)` for the points in `range` (which must lie within the set), in
    /// ascending index order; the layout is matched once, not per point.
    pub(super) fn for_each(&self, range: Range<usize>, mut f: impl FnMut(usize, Vec3)) {
        match self.0 {
            Layout::Components([x, y, z]) => {
                let start = range.start;
                let (x, y, z) = (&x[range.clone()], &y[range.clone()], &z[range]);
                for (k, ((&px, &py), &pz)) in x.iter().zip(y).zip(z).enumerate() {
                    f(start + k, Vec3::new(px, py, pz));
                }
            }
            Layout::Points(p) => {
                let start = range.start;
                for (k, &q) in p[range].iter().enumerate() {
                    f(start + k, q);
                }
            }
        }
    }
}

impl PointCloud<'_> {
    /// The point at index `i` (which must lie within the set).
    pub(super) fn point(&self, i: usize) -> Vec3 {
        match self.0 {
            Layout::Components([x, y, z]) => Vec3::new(x[i], y[i], z[i]),
            Layout::Points(p) => p[i],
        }
    }

    /// Sets `near[k]` for each point `range.start + k` closer than `reach_m` to the segment
    /// from `p0` to `p0 + axis` (`inv_len2` is `1 / |axis|²`), and leaves the other flags as
    /// they are; `near` holds one flag per point of `range`. A non-finite point is never near.
    /// One pass of plain arithmetic over the coordinates, which the compiler vectorises: a
    /// cheap sieve before the exact test.
    pub(super) fn mark_near_segment(
        &self,
        range: Range<usize>,
        (p0, axis, inv_len2): (Vec3, Vec3, f32),
        reach_m: f32,
        near: &mut [bool],
    ) {
        let reach2 = reach_m * reach_m;
        let close = |px: f32, py: f32, pz: f32| {
            let (dx, dy, dz) = (px - p0.x, py - p0.y, pz - p0.z);
            let s = dx * axis.x + dy * axis.y + dz * axis.z;
            // A NaN stays NaN through the clamp, and so does the distance: not near.
            let t = (s * inv_len2).clamp(0.0, 1.0);
            let (ox, oy, oz) = (dx - axis.x * t, dy - axis.y * t, dz - axis.z * t);
            ox * ox + oy * oy + oz * oz < reach2
        };
        match self.0 {
            Layout::Components([x, y, z]) => {
                let (x, y, z) = (&x[range.clone()], &y[range.clone()], &z[range]);
                for (flag, ((&px, &py), &pz)) in near.iter_mut().zip(x.iter().zip(y).zip(z)) {
                    *flag |= close(px, py, pz);
                }
            }
            Layout::Points(p) => {
                for (flag, q) in near.iter_mut().zip(&p[range]) {
                    *flag |= close(q.x, q.y, q.z);
                }
            }
        }
    }
}

/// The broad phase: the point set cut into blocks of [`BLOCK_POINTS`] consecutive indices, with
/// an axis-aligned bounding box per block. It pays where consecutive indices lie close together
/// (a structured grid such as the membrane's, a mesh in scan order): a query then tests only the
/// blocks near the tool. Non-finite points are left out of the boxes (they never penetrate).
#[derive(Debug, Clone, Default)]
pub struct PointBlocks {
    /// (min, max) corner of each block's points, metres; (+inf, -inf) for a block with no
    /// finite point.
    pub(super) bounds: Vec<(Vec3, Vec3)>,
    /// The number of points the blocks cover.
    pub(super) points: usize,
}

fn block_bounds(points: PointCloud<'_>, block: usize) -> (Vec3, Vec3) {
    let n = points.len();
    let range = (block * BLOCK_POINTS).min(n)..((block + 1) * BLOCK_POINTS).min(n);
    match points.0 {
        // Lane by lane without a branch (which the compiler vectorises): a point that is not
        // finite moves neither corner.
        Layout::Components([x, y, z]) => {
            let (x, y, z) = (&x[range.clone()], &y[range.clone()], &z[range]);
            let mut l = [f32::INFINITY; 3];
            let mut h = [f32::NEG_INFINITY; 3];
            for ((&px, &py), &pz) in x.iter().zip(y).zip(z) {
                let ok = px.is_finite() & py.is_finite() & pz.is_finite();
                let (low, high) = if ok {
                    ([px, py, pz], [px, py, pz])
                } else {
                    ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3])
                };
                for k in 0..3 {
                    l[k] = l[k].min(low[k]);
                    h[k] = h[k].max(high[k]);
                }
            }
            (Vec3::from(l), Vec3::from(h))
        }
        Layout::Points(_) => {
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            points.for_each(range, |_, p| {
                if p.is_finite() {
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            });
            (lo, hi)
        }
    }
}

impl PointBlocks {
    /// Blocks and boxes for `points`, computed as by [`Self::refresh`].
    pub fn new(points: PointCloud<'_>) -> Self {
        let mut blocks = Self::default();
        blocks.refresh(points);
        blocks
    }

    /// Recomputes every block's box (and the block count, if the number of points changed),
    /// in parallel over blocks on a large cloud; each box depends only on its own points, so the result is the
    /// same on any thread count.
    pub fn refresh(&mut self, points: PointCloud<'_>) {
        let n = points.len();
        self.points = n;
        self.bounds
            .resize(n.div_ceil(BLOCK_POINTS), (Vec3::ZERO, Vec3::ZERO));
        let one = |(b, bound): (usize, &mut (Vec3, Vec3))| *bound = block_bounds(points, b);
        // A small cloud stays on this thread: handing a few blocks to a second one costs
        // more than it saves.
        if n >= PARALLEL_POINTS && rayon::current_num_threads() > 1 {
            self.bounds.par_iter_mut().enumerate().for_each(one);
        } else {
            self.bounds.iter_mut().enumerate().for_each(one);
        }
    }

    /// Recomputes only the boxes of `blocks` (the owner knows which points moved). The point
    /// count must be the one of the last full refresh.
    pub fn refresh_blocks(
        &mut self,
        blocks: &[u32],
        points: PointCloud<'_>,
    ) -> Result<(), ToolError> {
        if points.len() != self.points {
            return Err(ToolError::StaleBlocks {
                blocks_points: self.points,
                points: points.len(),
            });
        }
        let count = self.bounds.len();
        for &b in blocks {
            let slot = self
                .bounds
                .get_mut(b as usize)
                .ok_or(ToolError::NoSuchBlock {
                    block: b,
                    blocks: count,
                })?;
            *slot = block_bounds(points, b as usize);
        }
        Ok(())
    }

    /// The number of blocks.
    pub fn block_count(&self) -> usize {
        self.bounds.len()
    }

    /// The block holding point `index`.
    pub fn block_of(index: usize) -> u32 {
        (index / BLOCK_POINTS) as u32
    }
}

#[cfg(test)]
#[path = "point_blocks_tests.rs"]
mod tests;
