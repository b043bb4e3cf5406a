//! Skinning on a rod: points (a surface mesh's vertices, another model's first layer)
//! bound once to the rod's centreline and carried by it as it deforms.
//!
//! A point `p` is bound to the nearest place of the centreline, element `e` at parameter
//! `t` in `[0, 1]` (the projection on the element's segment, clamped; ties to the lower
//! element), written `u = e + t` in element units. There the skin has
//!
//! - a centreline point `c(u) = x_e + t (x_{e+1} - x_e)`, linear between the nodes, and
//! - a frame `R(u)`: the element frames stand at the elements' midpoints `u = k + 1/2`, and
//!   between two midpoints the frame is the normalised linear blend (nlerp) of the two
//!   frames as quaternions, `q(u) = normalise((1 - w) q_k + w q_{k+1})` with
//!   `w = u - (k + 1/2)`; before the first midpoint and after the last the end element's frame
//!   holds.
//!
//! The point keeps its offset in that frame, `o = R(u)^T (p - c(u))` at binding, and is placed at
//! `p' = c(u) + R(u) o`. Both `c` and `R` are continuous in `u` (the frames change across an
//! element boundary only through the blend, never by a jump), so a bent rod carries the skin
//! without seams at element boundaries. nlerp rather than slerp: for the angle `theta` between
//! neighbouring element frames, nlerp's rotation differs from slerp's by at most about
//! `theta^3 / 250` rad (6e-5 rad at a joint bent by 0.25 rad, 1.3 um at 2 cm from the axis),
//! far below what a rendered surface shows, at a fraction of slerp's cost (no trigonometry
//! per point).
//!
//! A rigid motion of the rod (every node `x -> Q x + T`, every frame `R -> Q R`) moves every
//! skinned point rigidly: `c` is affine in the nodes and `q -> Q q` is linear on quaternions
//! and keeps their dot products (so the blend and its normalisation commute with it).
//!
//! Placing runs in parallel over fixed chunks of the output, each point computed on its own,
//! so the bytes written are the same on any number of threads. The centreline point is
//! computed in f64 and the rotated offset (a few centimetres) in f32, rounded to f32 once at
//! the end.

use super::skinned::{RodModelError, SkinnedRod};
use crate::models::cosserat::CosseratRod;
use glam::{DMat3, DQuat, DVec3, Quat, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// Points placed per parallel task: fixed, so the split never depends on the thread count.
const CHUNK: usize = 4096;

/// Which bound points to place. The output's `k`-th entry is the `k`-th point selected.
#[derive(Debug, Clone)]
pub enum Selection<'a> {
    /// Every bound point, in order.
    All,
    /// The points `range` (indices into the bound points).
    Range(Range<usize>),
    /// The points listed, in the list's order.
    List(&'a [u32]),
}

/// A rod's centreline nodes and element frames (material to world), as the skin reads them:
/// the live rod's, or any other (a test's rigidly moved copy).
#[derive(Debug, Clone, Copy)]
pub struct RodPose<'a> {
    /// Node positions, m (elements + 1).
    pub positions: &'a [DVec3],
    /// Element frames, columns d1, d2, d3 (elements).
    pub frames: &'a [DMat3],
}

impl<'a> RodPose<'a> {
    /// The pose of a Cosserat rod as it is now.
    pub fn of(rod: &'a CosseratRod) -> Self {
        RodPose {
            positions: rod.positions(),
            frames: rod.frames(),
        }
    }

    fn check(&self, elements: usize) -> Result<(), RodModelError> {
        if self.frames.len() != elements || self.positions.len() != elements + 1 {
            return Err(RodModelError::PoseMismatch {
                elements,
                nodes: self.positions.len(),
                frames: self.frames.len(),
            });
        }
        Ok(())
    }
}

/// Where one point is bound: element and parameter along it, the pair of element frames
/// blended there and the blend's weight, and the offset in the blended frame.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bound {
    element: u32,
    pair: u32,
    t: f32,
    w: f32,
    offset: Vec3,
}

/// Points bound to a rod's centreline (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Skin {
    elements: usize,
    bound: Vec<Bound>,
}

/// The pair of element frames blended at `u = e + t` and the blend's weight (module docs).
#[inline]
fn blend(elements: usize, e: usize, t: f32) -> (usize, f32) {
    if elements < 2 {
        return (0, 0.0);
    }
    let s = e as f32 + t - 0.5;
    // The conversion truncates, which is the floor once `s` is no longer negative (and a
    // portable build without SSE4.1 makes `floor` a call).
    let k = (s.max(0.0) as usize).min(elements - 2);
    (k, (s - k as f32).clamp(0.0, 1.0))
}

/// The element frames as unit quaternions, each in the hemisphere of the one before (so the
/// blend of a pair never takes the long way round); a single frame is repeated, so that pair
/// 0 exists for every rod.
fn chain_quats(frames: &[DMat3]) -> Vec<DQuat> {
    let mut q: Vec<DQuat> = frames
        .iter()
        .map(|r| DQuat::from_mat3(r).normalize())
        .collect();
    for k in 1..q.len() {
        if q[k - 1].dot(q[k]) < 0.0 {
            q[k] = -q[k];
        }
    }
    if let [only] = q[..] {
        q.push(only);
    }
    q
}

/// The nearest place of the polyline `x` to `p`: (element, parameter, squared distance).
pub(super) fn nearest_place(x: &[DVec3], p: DVec3) -> (usize, f64, f64) {
    let mut best = (0, 0.0, f64::INFINITY);
    for (e, w) in x.windows(2).enumerate() {
        let a = w[1] - w[0];
        let len2 = a.length_squared();
        let t = if len2 > 0.0 {
            ((p - w[0]).dot(a) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let d2 = (w[0] + a * t - p).length_squared();
        if d2 < best.2 {
            best = (e, t, d2);
        }
    }
    best
}

impl Skin {
    /// Binds `points` (m) to `rod` as it is now (normally at rest); see the module docs. A
    /// non-finite point is bound to the first node with no offset (it is placed there).
    pub fn bind(rod: &SkinnedRod, points: &[Vec3]) -> Skin {
        Self::bind_pose(RodPose::of(rod.rod()), points)
    }

    /// [`Skin::bind`] on any pose (the frames one fewer than the nodes; a pose with no element
    /// binds every point to its first node).
    pub fn bind_pose(pose: RodPose<'_>, points: &[Vec3]) -> Skin {
        let elements = pose
            .frames
            .len()
            .min(pose.positions.len().saturating_sub(1));
        let quats = chain_quats(&pose.frames[..elements]);
        let x = &pose.positions[..(elements + 1).min(pose.positions.len())];
        let bound = points
            .par_iter()
            .with_min_len(CHUNK)
            .map(|&p| {
                let unbound = Bound {
                    element: 0,
                    pair: 0,
                    t: 0.0,
                    w: 0.0,
                    offset: Vec3::ZERO,
                };
                if elements == 0 || !p.is_finite() {
                    return unbound;
                }
                let p = p.as_dvec3();
                let (e, t, _) = nearest_place(x, p);
                // The parameter is kept in f32; bind at exactly the place that will be used.
                let t32 = t as f32;
                let t = f64::from(t32);
                let c = x[e] + (x[e + 1] - x[e]) * t;
                let (k, w) = blend(elements, e, t32);
                let q = (quats[k] * (1.0 - f64::from(w)) + quats[k + 1] * f64::from(w)).normalize();
                Bound {
                    element: e as u32,
                    pair: k as u32,
                    t: t32,
                    w,
                    offset: (q.inverse() * (p - c)).as_vec3(),
                }
            })
            .collect();
        Skin { elements, bound }
    }

    /// How many points are bound.
    pub fn len(&self) -> usize {
        self.bound.len()
    }

    /// Heap bytes held, for the profiler.
    pub fn heap_bytes(&self) -> usize {
        self.bound.capacity() * std::mem::size_of::<Bound>()
    }

    pub fn is_empty(&self) -> bool {
        self.bound.is_empty()
    }

    /// The rod's element count this skin was bound to.
    pub fn elements(&self) -> usize {
        self.elements
    }

    /// Where point `i` is bound: (element, parameter along it, offset in the skin's frame, m).
    pub fn binding(&self, i: usize) -> Option<(usize, f32, Vec3)> {
        self.bound
            .get(i)
            .map(|b| (b.element as usize, b.t, b.offset))
    }

    /// Point `i`'s whole binding: (element, parameter along it, the pair of frames blended
    /// and the weight on the second, offset in the blended frame, m). Placing it by
    /// [`Skin::frames`] of a pose reproduces [`Skin::place`].
    pub fn frame_binding(&self, i: usize) -> Option<(u32, f32, u32, f32, Vec3)> {
        self.bound
            .get(i)
            .map(|b| (b.element, b.t, b.pair, b.w, b.offset))
    }

    /// The frames the skin blends for `pose`: the element frames as unit quaternions, each in
    /// the hemisphere of the one before, at least two (a single frame repeated).
    pub fn frames(pose: RodPose<'_>) -> Vec<Quat> {
        chain_quats(pose.frames)
            .iter()
            .map(|q| q.as_quat())
            .collect()
    }

    /// Places the selected points where the rod carries them now; `out[k]` gets the `k`-th
    /// selected point (`out` as long as the selection).
    pub fn place(
        &self,
        rod: &SkinnedRod,
        which: Selection<'_>,
        out: &mut [Vec3],
    ) -> Result<(), RodModelError> {
        self.place_pose(RodPose::of(rod.rod()), which, out)
    }

    /// [`Skin::place`] on any pose with the bound element count.
    pub fn place_pose(
        &self,
        pose: RodPose<'_>,
        which: Selection<'_>,
        out: &mut [Vec3],
    ) -> Result<(), RodModelError> {
        let n = self.elements;
        if n == 0 {
            // Nothing to carry the points: every point stays at the pose's first node.
            let at = pose
                .positions
                .first()
                .copied()
                .unwrap_or(DVec3::ZERO)
                .as_vec3();
            return self.select(&which, out, |_| at);
        }
        pose.check(n)?;
        let quats: Vec<Quat> = chain_quats(pose.frames)
            .iter()
            .map(|q| q.as_quat())
            .collect();
        let x = pose.positions;
        self.select(&which, out, |b| {
            let e = b.element as usize;
            let (a, z) = (x[e], x[e + 1]);
            let c = a + (z - a) * f64::from(b.t);
            let k = b.pair as usize;
            let q = (quats[k] * (1.0 - b.w) + quats[k + 1] * b.w).normalize();
            (c + (q * b.offset).as_dvec3()).as_vec3()
        })
    }

    /// Checks the selection against the bound points and `out`, then writes `f` of each
    /// selected point's binding into `out`, in parallel over fixed chunks.
    fn select(
        &self,
        which: &Selection<'_>,
        out: &mut [Vec3],
        f: impl Fn(&Bound) -> Vec3 + Sync,
    ) -> Result<(), RodModelError> {
        let points = self.bound.len();
        let wanted = match which {
            Selection::All => points,
            Selection::Range(r) => {
                if r.start > r.end || r.end > points {
                    return Err(RodModelError::NoSuchPoint {
                        index: r.end.max(r.start),
                        points,
                    });
                }
                r.len()
            }
            Selection::List(list) => {
                if let Some(&bad) = list.iter().find(|&&i| i as usize >= points) {
                    return Err(RodModelError::NoSuchPoint {
                        index: bad as usize,
                        points,
                    });
                }
                list.len()
            }
        };
        if out.len() != wanted {
            return Err(RodModelError::OutputLength {
                expected: wanted,
                found: out.len(),
            });
        }
        let bound = &self.bound[..];
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                let first = c * CHUNK;
                match which {
                    Selection::All => {
                        for (slot, b) in chunk.iter_mut().zip(&bound[first..]) {
                            *slot = f(b);
                        }
                    }
                    Selection::Range(r) => {
                        for (slot, b) in chunk.iter_mut().zip(&bound[r.start + first..]) {
                            *slot = f(b);
                        }
                    }
                    Selection::List(list) => {
                        for (slot, &i) in chunk.iter_mut().zip(&list[first..]) {
                            *slot = f(&bound[i as usize]);
                        }
                    }
                }
            });
        Ok(())
    }
}
