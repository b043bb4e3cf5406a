//! Layer 0's targets carried by a chain of frames (a rod's skin). Each layer-0 node is bound
//! once to a segment of the chain (a share `t` of the way along it), to a blend of two of the
//! chain's frames (weight `w` on the second) and to an offset in the blended frame; its target
//! is then `a + (b - a) t + q offset`, with `a`, `b` the segment's ends and `q` the blended,
//! normalised frame. The holder hands the chain's pose each step
//! ([`Membrane::pose_targets`]); the membrane places the targets where its step needs them: on
//! the CPU for the tiles it steps or places there, on its device for the tiles the device
//! steps (`device_chain.rs`), so that a device's step takes no targets from the CPU. The CPU's
//! targets of a tile are placed from a pose once; each tile remembers which.

use super::active::Activity;
use super::{Membrane, MembraneError};
use glam::{DVec3, Quat, Vec3};

/// Where one layer-0 node is bound on the chain (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChainBinding {
    /// The segment, between points `segment` and `segment + 1` of the pose.
    pub segment: u32,
    /// The share of the way along it, in [0, 1].
    pub t: f32,
    /// The frames blended: `pair` and `pair + 1`, with weight `w` on the second.
    pub pair: u32,
    pub w: f32,
    /// The offset in the blended frame, m.
    pub offset: Vec3,
}

/// The bound nodes, the pose and what each tile's CPU targets were placed from.
#[derive(Debug, Clone)]
pub(super) struct Chain {
    /// Per layer-0 node (row-major).
    pub bound: Vec<ChainBinding>,
    pub segments: usize,
    /// The pose: `segments + 1` points (m) and `frames(segments)` unit frames.
    pub points: Vec<DVec3>,
    pub quats: Vec<Quat>,
    /// The pose's number (0: none handed yet).
    pub pose: u64,
    /// Marks this binding (a copy of `bound` made under another stamp is not current: see
    /// `active_drawn.rs`).
    pub stamp: u64,
    /// Per tile (of the active set; one without): the pose its CPU targets came from.
    placed: Vec<u64>,
}

/// Frames a chain of `segments` segments has: one a segment, and at least two (a single
/// frame is repeated, so that the pair 0 exists).
pub fn frames(segments: usize) -> usize {
    segments.max(2)
}

impl Chain {
    /// Node `k`'s target under the pose.
    #[inline]
    pub fn target(&self, k: usize) -> Option<Vec3> {
        self.target_of(self.bound.get(k)?)
    }

    /// The target of a node bound at `b` under the pose.
    #[inline]
    pub fn target_of(&self, b: &ChainBinding) -> Option<Vec3> {
        let (e, p) = (b.segment as usize, b.pair as usize);
        let (a, z) = (*self.points.get(e)?, *self.points.get(e + 1)?);
        let c = a + (z - a) * f64::from(b.t);
        let q = (*self.quats.get(p)? * (1.0 - b.w) + *self.quats.get(p + 1)? * b.w).normalize();
        Some((c + (q * b.offset).as_dvec3()).as_vec3())
    }

    /// Whether tile `t`'s CPU targets are placed from the present pose.
    pub fn current(&self, t: usize) -> bool {
        self.pose > 0 && self.placed.get(t) == Some(&self.pose)
    }
}

impl Membrane {
    /// Binds layer 0's nodes (`bound`, one a node, row-major) to a chain of `segments`
    /// segments: from the first pose handed on, the chain places layer 0's targets (module
    /// docs), and [`Membrane::set_target`] no longer holds past the next pose. An error names
    /// the first binding that does not fit the chain; the membrane is left as it was.
    pub fn bind_targets(
        &mut self,
        bound: Vec<ChainBinding>,
        segments: usize,
    ) -> Result<(), MembraneError> {
        let nodes = self.rows * self.cols;
        if bound.len() != nodes {
            return Err(MembraneError::BadBinding {
                node: bound.len().min(nodes),
                why: format!("{} bindings for {nodes} layer-0 nodes", bound.len()),
            });
        }
        if segments == 0 {
            return Err(MembraneError::BadBinding {
                node: 0,
                why: "a chain needs at least one segment".into(),
            });
        }
        for (node, b) in bound.iter().enumerate() {
            let why = if b.segment as usize >= segments {
                format!("segment {} of a chain of {segments}", b.segment)
            } else if b.pair as usize + 1 >= frames(segments) {
                format!(
                    "frames {} and {} of {}",
                    b.pair,
                    b.pair + 1,
                    frames(segments)
                )
            } else if !(b.t.is_finite() && b.w.is_finite() && b.offset.is_finite()) {
                "a share, weight or offset that is not finite".into()
            } else {
                continue;
            };
            return Err(MembraneError::BadBinding { node, why });
        }
        self.chain = Some(Box::new(Chain {
            bound,
            segments,
            points: Vec::new(),
            quats: Vec::new(),
            pose: 0,
            stamp: super::active::stamp(),
            placed: Vec::new(),
        }));
        self.device.chain_changed();
        Ok(())
    }

    /// The chain's pose now: `segments + 1` points (m) and its frames (one a segment, at
    /// least two; see [`frames`]), each in the hemisphere of the one before. Places the
    /// targets the next step needs on the CPU, unless the membrane's device places them. An
    /// error (no chain bound, a pose of another size, a value not finite) leaves the last
    /// pose in place.
    pub fn pose_targets(&mut self, points: &[DVec3], quats: &[Quat]) -> Result<(), MembraneError> {
        let Some(c) = self.chain.as_deref_mut() else {
            return Err(MembraneError::BadPose("no chain is bound".into()));
        };
        if points.len() != c.segments + 1 || quats.len() != frames(c.segments) {
            return Err(MembraneError::BadPose(format!(
                "{} points and {} frames for a chain of {} segments (expected {} and {})",
                points.len(),
                quats.len(),
                c.segments,
                c.segments + 1,
                frames(c.segments)
            )));
        }
        if !(points.iter().all(|p| p.is_finite()) && quats.iter().all(|q| q.is_finite())) {
            return Err(MembraneError::BadPose(
                "a point or frame is not finite".into(),
            ));
        }
        c.points.clear();
        c.points.extend_from_slice(points);
        c.quats.clear();
        c.quats.extend_from_slice(quats);
        c.pose += 1;
        if !self.device.places_targets() {
            let tiles = self.tiles_needing_targets(false);
            let a = self.activity.take();
            place(self, a.as_ref(), &tiles);
            self.activity = a;
        }
        Ok(())
    }

    /// Places every tile's targets from the chain's pose on the CPU (before drawing or
    /// placing the whole membrane).
    pub fn place_all_targets(&mut self) {
        let tiles: Vec<usize> = (0..self.activity.as_ref().map_or(1, |a| a.awake.len())).collect();
        let a = self.activity.take();
        place(self, a.as_ref(), &tiles);
        self.activity = a;
    }

    /// Layer 0's target at row `i`, column `j` as the CPU would place it now: the chain's,
    /// where the tile's CPU targets lag its pose, else the one set.
    pub(super) fn target_now(&self, i: usize, j: usize, tile: usize) -> Vec3 {
        if let Some(c) = self
            .chain
            .as_deref()
            .filter(|c| c.pose > 0 && !c.current(tile))
            && let Some(p) = c.target(i * self.cols + j)
        {
            return p;
        }
        self.target_set(i, j)
    }

    /// Layer 0's target at row `i`, column `j` as last placed or set on the CPU.
    pub(super) fn target_set(&self, i: usize, j: usize) -> Vec3 {
        Vec3::from_array(std::array::from_fn(|c| {
            self.attach[(i * 4 + 1 + c) * self.cols + j]
        }))
    }
}

/// Places the CPU's targets of tiles `tiles` (of the active set `a`; tile 0 is the whole grid
/// without one) whose targets lag the chain's pose: each row of the grid on its own (in
/// parallel where they are many; each value is written once, so the bytes are the same).
pub(super) fn place(m: &mut Membrane, a: Option<&Activity>, tiles: &[usize]) {
    use rayon::prelude::*;
    let (rows, cols) = (m.rows, m.cols);
    let Some(c) = m.chain.as_deref_mut().filter(|c| c.pose > 0) else {
        return;
    };
    let count = a.map_or(1, |a| a.awake.len());
    c.placed.resize(count, 0);
    // Per grid row, the column spans to place.
    let mut spans: Vec<Vec<[usize; 2]>> = Vec::new();
    let mut nodes = 0;
    for &t in tiles {
        if t >= count || c.placed[t] == c.pose {
            continue;
        }
        c.placed[t] = c.pose;
        let ([r0, r1], cs) = a.map_or(([0, rows], [0, cols]), |a| a.span(t, rows, cols));
        if spans.is_empty() {
            spans.resize(rows, Vec::new());
        }
        for row in &mut spans[r0..r1] {
            row.push(cs);
        }
        nodes += (r1 - r0) * (cs[1] - cs[0]);
    }
    if nodes == 0 {
        return;
    }
    let c = &*c;
    // Layer 0's slot: row `i` is four runs of `cols` from `i * 4 * cols`.
    let slot = &mut m.attach[..rows * 4 * cols];
    let one = |(i, x): (usize, &mut [f32])| {
        for &[c0, c1] in &spans[i] {
            for j in c0..c1 {
                if let Some(p) = c.target(i * cols + j) {
                    for (k, v) in p.to_array().into_iter().enumerate() {
                        x[(1 + k) * cols + j] = v;
                    }
                }
            }
        }
    };
    if super::active::worth_threads(nodes) {
        slot.par_chunks_mut(4 * cols).enumerate().for_each(one);
    } else {
        slot.chunks_mut(4 * cols).enumerate().for_each(one);
    }
}
