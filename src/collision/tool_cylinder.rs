//! Instruments as generalized cylinders against tissue vertices: the collision test of the
//! rectum paper ("Generalized cylinder based collision detection for haptics", Fig. 4), its
//! penalty forces, and the query that tests only the points near the tool (through the blocks
//! of `point_blocks`).
//!
//! An instrument is one or more generalized cylinders. Each has an axis `p0`–`p1` and a radius
//! that varies along it. A tissue vertex `v` is tested in two steps, exactly as the paper:
//!
//! 1. **Angles.** `v` can only be inside if `∠p1 p0 v ≤ 90°` and `∠p0 p1 v ≤ 90°`. With
//!    `a = p1 - p0`, the angle at `p0` is at most 90° iff `a · (v - p0) ≥ 0`, and the angle at
//!    `p1` iff `-a · (v - p1) ≥ 0`: together, the projection of `v` on the axis line falls on the
//!    segment (ends included), at `t = a · (v - p0) / |a|²` in `[0, 1]`.
//! 2. **Distance.** `p = p0 + t a` is the axis point closest to `v` and `d = |v - p|` the
//!    distance to the axis line. If `d < r(t)` the vertex penetrates, by `depth = r(t) - d`, and
//!    the penalty force on it points along `p → v` (out of the tool).
//!
//! A vertex on the axis (`d = 0`, or within the rounding of `p`: 8 f32 steps of the largest
//! axis-end coordinate) has no direction `p → v`; it is given depth `r(t)` and the direction
//! `Vec3::any_orthonormal_vector` of the unit axis (Duff et al.'s branchless basis), which is
//! fixed for a given axis, so the answer is deterministic and never NaN. Elsewhere the direction
//! is `v - p` with its (rounding-sized) component along the axis removed.
//!
//! The cylinder is *flat-ended*: step 1 cuts it at the planes through `p0` and `p1`
//! perpendicular to the axis, as in the paper. Only vertex positions are used, so the test works
//! on point clouds as well as meshes. Where a vertex is inside several cylinders of one
//! instrument (the joint of an L-hook, the hinge of a grasper) it is reported once, for the
//! cylinder it penetrates deepest, so overlapping cylinders do not push it twice.
//!
//! Forces are distributed by area: the force on a vertex is `k · A · depth · dir`, with `k` a
//! stiffness per unit area (Pa/m) and `A` the area the vertex stands for (m²). The total force
//! of a tool pressed into a surface is then `k ∫ depth dA`, whatever the mesh resolution.

use super::point_blocks::{BLOCK_POINTS, PointBlocks, PointCloud};
use glam::{Quat, Vec3};

/// Radius of a 5 mm laparoscopic instrument's shaft, metres.
const SHAFT_RADIUS_M: f32 = 2.5e-3;
/// Shaft length from the handle to the working end, metres: 5 mm instruments are sold with
/// working lengths of about 310–360 mm; 330 mm is taken.
const SHAFT_LENGTH_M: f32 = 0.33;
/// Radius of the L-hook's electrode wire (about 1 mm in diameter), metres.
const HOOK_WIRE_RADIUS_M: f32 = 0.5e-3;
/// Length of the L-hook's bent part, from the shaft's axis to the hook's end, metres (hooks
/// are about 5–7 mm).
const HOOK_LENGTH_M: f32 = 6e-3;
/// Length over which the L-hook's insulated end narrows from the shaft to the wire, metres (an
/// estimate: the insulation ends in a cone about a centimetre long).
const HOOK_TAPER_M: f32 = 10e-3;
/// Length of a grasper's jaws from the hinge, metres.
const JAW_LENGTH_M: f32 = 20e-3;
/// Each jaw is half of the 5 mm shaft's cross-section: its axis lies this far off the hinge
/// pin, and its radius is this at the hinge, metres.
const JAW_BASE_RADIUS_M: f32 = 1.25e-3;
/// A jaw narrows towards its tip to this radius, metres (an estimate for atraumatic jaws).
const JAW_TIP_RADIUS_M: f32 = 0.75e-3;
/// The broad phase inflates each block's box by this much beyond a cylinder's largest radius,
/// metres, so that rounding can never make it skip a point the narrow phase would report
/// (f32 rounding at coordinates of a few metres is a few micrometres at most).
const BROAD_MARGIN_M: f32 = 1e-5;

/// What is wrong with a tool's shape, a point set or the inputs of a force computation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ToolError {
    /// An axis end (metres) has a non-finite coordinate.
    #[error("axis end {which} is {value}; both axis ends must be finite (metres)")]
    NonFinitePoint { which: &'static str, value: Vec3 },
    /// The axis ends coincide, so the axis has no direction.
    #[error("p0 and p1 are both {point}; the axis needs two distinct ends")]
    DegenerateAxis { point: Vec3 },
    /// The radius profile has no samples.
    #[error("the radius profile is empty; give at least one (t, radius) sample")]
    EmptyProfile,
    /// A radius (metres) is not finite or not strictly positive.
    #[error("radius sample {sample} is {value} m; every radius must be finite and > 0")]
    BadRadius { sample: usize, value: f32 },
    /// A sample's axis parameter is outside [0, 1] or not greater than the one before.
    #[error(
        "radius sample {sample} is at t = {t}; t must lie in [0, 1] and increase strictly from \
         one sample to the next"
    )]
    BadParameter { sample: usize, t: f32 },
    /// An instrument was given no cylinders.
    #[error("an instrument needs at least one cylinder")]
    NoCylinders,
    /// A pose has a non-finite position or a quaternion that is not finite and non-zero.
    #[error(
        "pose position {position} / orientation {orientation} is unusable; the position must be \
         finite and the quaternion finite and non-zero"
    )]
    BadPose { position: Vec3, orientation: Quat },
    /// A grasper's jaw opening (radians) is not finite or outside [0, π].
    #[error("jaw opening is {value} rad; it must be finite and in [0, π]")]
    BadOpening { value: f32 },
    /// The coordinate slices of a point set differ in length.
    #[error("x, y and z have {x}, {y} and {z} entries; one per point each is expected")]
    ComponentLengths { x: usize, y: usize, z: usize },
    /// A block index names no block of the point set.
    #[error("block {block} does not exist; the point set has {blocks} blocks")]
    NoSuchBlock { block: u32, blocks: usize },
    /// The blocks were built for a point set of another size: call `PointBlocks::refresh`.
    #[error("the blocks cover {blocks_points} points but the point set has {points}; refresh them")]
    StaleBlocks { blocks_points: usize, points: usize },
    /// A contact names a vertex that has no entry in the per-vertex areas.
    #[error("vertex {vertex} has no area: {len} areas were given, one per vertex is expected")]
    MissingArea { vertex: u32, len: usize },
    /// An area (m²) is negative or not finite.
    #[error("the area of vertex {vertex} is {value} m²; areas must be finite and >= 0")]
    BadArea { vertex: u32, value: f32 },
    /// The penalty stiffness (Pa/m) is negative or not finite.
    #[error("penalty stiffness is {value} Pa/m; it must be finite and >= 0")]
    BadStiffness { value: f32 },
}

/// One generalized cylinder: an axis `p0`–`p1` (metres, world frame) swept by a radius that
/// varies along it, piecewise linearly between samples `(t_k, r_k)` (`t` from 0 at `p0` to 1 at
/// `p1`) and constant before the first sample and after the last.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolCylinder {
    p0: Vec3,
    p1: Vec3,
    /// `p1 - p0`.
    axis: Vec3,
    /// `1 / |p1 - p0|²`.
    inv_len2: f32,
    /// `axis` normalised.
    unit_axis: Vec3,
    /// The direction given to a vertex on the axis (unit, perpendicular to the axis).
    on_axis_dir: Vec3,
    /// A vertex this close to the axis point, metres, counts as on the axis: the rounding of
    /// `p` (a few f32 steps of the coordinates) is all that separates them.
    on_axis_m: f32,
    /// Strictly increasing parameters in [0, 1].
    t: Vec<f32>,
    /// Radius at each parameter, metres.
    r: Vec<f32>,
    max_r: f32,
}

/// The answer of the two-step test for one vertex and one cylinder.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Penetration {
    t: f32,
    axis_point: Vec3,
    depth_m: f32,
    dir: Vec3,
}

impl ToolCylinder {
    /// A cylinder from `p0` to `p1` (metres) with the radius profile `profile`: pairs
    /// `(t, radius_m)` with `t` in [0, 1] strictly increasing and every radius finite and > 0.
    /// One sample is a constant radius.
    pub fn new(p0: Vec3, p1: Vec3, profile: &[(f32, f32)]) -> Result<Self, ToolError> {
        for (which, value) in [("p0", p0), ("p1", p1)] {
            if !value.is_finite() {
                return Err(ToolError::NonFinitePoint { which, value });
            }
        }
        let axis = p1 - p0;
        let len2 = axis.length_squared();
        let inv_len2 = len2.recip();
        // An axis so short that |a|² underflows is as unusable as p0 == p1.
        if !(len2 > 0.0 && inv_len2.is_finite()) {
            return Err(ToolError::DegenerateAxis { point: p0 });
        }
        if profile.is_empty() {
            return Err(ToolError::EmptyProfile);
        }
        let mut prev_t = f32::NEG_INFINITY;
        for (sample, &(t, r)) in profile.iter().enumerate() {
            if !((0.0..=1.0).contains(&t) && t > prev_t) {
                return Err(ToolError::BadParameter { sample, t });
            }
            if !(r.is_finite() && r > 0.0) {
                return Err(ToolError::BadRadius { sample, value: r });
            }
            prev_t = t;
        }
        let unit_axis = axis
            .try_normalize()
            .ok_or(ToolError::DegenerateAxis { point: p0 })?;
        let scale = p0.abs().max_element() + p1.abs().max_element();
        Ok(Self {
            p0,
            p1,
            axis,
            inv_len2,
            unit_axis,
            on_axis_dir: unit_axis.any_orthonormal_vector(),
            on_axis_m: 8.0 * f32::EPSILON * scale,
            t: profile.iter().map(|s| s.0).collect(),
            r: profile.iter().map(|s| s.1).collect(),
            max_r: profile.iter().map(|s| s.1).fold(0.0, f32::max),
        })
    }

    /// A cylinder of constant radius `radius_m` from `p0` to `p1` (metres).
    pub fn constant(p0: Vec3, p1: Vec3, radius_m: f32) -> Result<Self, ToolError> {
        Self::new(p0, p1, &[(0.0, radius_m)])
    }

    /// The same cylinder with every radius grown by `by_m` (metres, >= 0): tested against
    /// points, it is this cylinder tested against spheres of radius `by_m` (particles).
    pub fn inflated(&self, by_m: f32) -> Self {
        let by = if by_m.is_finite() { by_m.max(0.0) } else { 0.0 };
        Self {
            r: self.r.iter().map(|r| r + by).collect(),
            max_r: self.max_r + by,
            ..self.clone()
        }
    }

    /// The axis end at `t = 0`, metres.
    pub fn p0(&self) -> Vec3 {
        self.p0
    }

    /// The axis end at `t = 1`, metres.
    pub fn p1(&self) -> Vec3 {
        self.p1
    }

    /// Most radius samples [`ToolCylinder::rows`] carries.
    pub const ROW_SAMPLES: usize = 4;

    /// The cylinder as seven rows of four floats, as a compute kernel reads it
    /// (`shaders/particles.wgsl`'s `Cylinder`): `(p0, 1 / |a|²)`, `(p1, on-axis distance)`,
    /// `(a, bits of the sample count)`, `(unit axis, 0)`, `(on-axis direction, 0)`, the
    /// samples' `t`, their radii. None for a profile of more than [`Self::ROW_SAMPLES`]
    /// samples.
    pub fn rows(&self) -> Option<[[f32; 4]; 7]> {
        let n = self.t.len();
        if n > Self::ROW_SAMPLES {
            return None;
        }
        let row = |v: Vec3, w: f32| [v.x, v.y, v.z, w];
        let mut t = [0.0; 4];
        let mut r = [0.0; 4];
        t[..n].copy_from_slice(&self.t);
        r[..n].copy_from_slice(&self.r);
        Some([
            row(self.p0, self.inv_len2),
            row(self.p1, self.on_axis_m),
            row(self.axis, f32::from_bits(n as u32)),
            row(self.unit_axis, 0.0),
            row(self.on_axis_dir, 0.0),
            t,
            r,
        ])
    }

    /// The largest radius of the profile, metres.
    pub fn max_radius_m(&self) -> f32 {
        self.max_r
    }

    /// The distance from the axis segment within which a point may penetrate, with room for
    /// rounding, metres. A point that [`Self::penetration`] takes lies within `r(t)` of an
    /// axis point, so within `max_r` of the segment; the sieve's own rounding (about 1e-7 of
    /// the coordinates, in metres) is far below the micrometre added.
    fn sieve_reach_m(&self) -> f32 {
        self.max_r * (1.0 + 1e-3) + 1e-6
    }

    /// The radius at axis parameter `t`, metres: linear between the bracketing samples,
    /// the first sample's radius before it and the last one's after it.
    pub fn radius_at(&self, t: f32) -> f32 {
        // `t` holds at least one sample (checked by `new`); the fallbacks are never taken.
        let first = self.r.first().copied().unwrap_or(0.0);
        let last = self.r.last().copied().unwrap_or(0.0);
        let k = self.t.partition_point(|&tk| tk <= t);
        if k == 0 {
            return first;
        }
        if k == self.t.len() {
            return last;
        }
        let (t0, t1) = (self.t[k - 1], self.t[k]);
        let (r0, r1) = (self.r[k - 1], self.r[k]);
        r0 + (r1 - r0) * ((t - t0) / (t1 - t0))
    }

    /// The paper's two steps (module docs) for vertex `v`; `None` when `v` is outside. A
    /// non-finite `v` is always outside (one of the step-1 products is NaN or -inf).
    fn penetration(&self, v: Vec3) -> Option<Penetration> {
        // Step 1: ∠p1 p0 v ≤ 90° and ∠p0 p1 v ≤ 90°, as signs of dot products (NaN rejects).
        let s0 = self.axis.dot(v - self.p0);
        if s0.is_nan() || s0 < 0.0 {
            return None;
        }
        let s1 = (-self.axis).dot(v - self.p1);
        if s1.is_nan() || s1 < 0.0 {
            return None;
        }
        // Step 2: distance to the axis line against the radius there. Rounding can push t
        // a hair past the ends when step 1 passed at exactly 90°; clamp it back.
        let t = (s0 * self.inv_len2).clamp(0.0, 1.0);
        let axis_point = self.p0 + self.axis * t;
        let r = self.radius_at(t);
        let off = v - axis_point;
        let d2 = off.length_squared();
        if d2.is_nan() || d2 >= r * r {
            return None;
        }
        let d = d2.sqrt();
        if d <= self.on_axis_m {
            return Some(Penetration {
                t,
                axis_point,
                depth_m: r,
                dir: self.on_axis_dir,
            });
        }
        // Rounding in `t` leaves a residue along the axis in `off`; drop it from the direction.
        let perp = off - self.unit_axis * off.dot(self.unit_axis);
        Some(Penetration {
            t,
            axis_point,
            depth_m: r - d,
            dir: perp.try_normalize().unwrap_or(self.on_axis_dir),
        })
    }

    /// Whether the cylinder may hold a point of the box `lo`–`hi`: every point of the cylinder
    /// is within `max_r` of the axis segment, so it suffices that the segment meets the box
    /// inflated by `max_r` (plus a rounding margin). Slab test on `p0 + s a`, `s` in [0, 1].
    fn may_touch(&self, lo: Vec3, hi: Vec3) -> bool {
        if !(lo.cmple(hi).all()) {
            return false; // an empty block (no finite point)
        }
        let grow = Vec3::splat(self.max_r + BROAD_MARGIN_M);
        let (lo, hi) = (lo - grow, hi + grow);
        let (mut s_in, mut s_out) = (0.0f32, 1.0f32);
        for i in 0..3 {
            let (o, d) = (self.p0[i], self.axis[i]);
            if d == 0.0 {
                if o < lo[i] || o > hi[i] {
                    return false;
                }
            } else {
                let (a, b) = ((lo[i] - o) / d, (hi[i] - o) / d);
                s_in = s_in.max(a.min(b));
                s_out = s_out.min(a.max(b));
                if s_in > s_out {
                    return false;
                }
            }
        }
        true
    }
}

/// A vertex inside an instrument.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolContact {
    /// Index of the tissue vertex in the point set (point sets hold fewer than 2³² points).
    pub vertex: u32,
    /// Index of the cylinder it penetrates deepest, in the instrument's order.
    pub cylinder: u32,
    /// Parameter of the closest axis point, 0 at the cylinder's `p0`, 1 at its `p1`.
    pub t: f32,
    /// The closest axis point `p`, metres.
    pub axis_point: Vec3,
    /// Penetration depth `r(t) - d`, metres (> 0).
    pub depth_m: f32,
    /// Unit direction `p → v`, along which the penalty force pushes the vertex out.
    pub dir: Vec3,
}

/// How much of the point set a query looked at.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueryStats {
    /// Blocks whose points were tested (all of them for a query without blocks).
    pub blocks_examined: usize,
    /// Points given the two-step test.
    pub points_examined: usize,
}

/// An instrument: one or more generalized cylinders (the paper's L-hook is one cylinder; a
/// dissector or shear several).
#[derive(Debug, Clone, PartialEq)]
pub struct Instrument {
    cylinders: Vec<ToolCylinder>,
}

/// `orientation` normalised, or the error naming the pose.
fn check_pose(position: Vec3, orientation: Quat) -> Result<Quat, ToolError> {
    let bad = ToolError::BadPose {
        position,
        orientation,
    };
    if !(position.is_finite() && orientation.is_finite()) {
        return Err(bad);
    }
    let len = orientation.length();
    if !(len.is_finite() && len > 0.0 && len.recip().is_finite()) {
        return Err(bad);
    }
    Ok(orientation * len.recip())
}

impl Instrument {
    /// An instrument made of `cylinders`; contacts name them by their index here.
    pub fn new(cylinders: Vec<ToolCylinder>) -> Result<Self, ToolError> {
        if cylinders.is_empty() {
            return Err(ToolError::NoCylinders);
        }
        Ok(Self { cylinders })
    }

    /// A 5 mm monopolar L-hook. The pose follows the simulator's aim-pose convention: the
    /// instrument points along its local -Z axis; `tip` (metres) is the corner of the L, on the
    /// shaft's axis, and the hook points along local +Y. Two cylinders:
    ///
    /// 0. the straight part, from the handle end (330 mm up the shaft) to `tip`: radius 2.5 mm
    ///    along the shaft, narrowing linearly over the last 10 mm to the 0.5 mm wire (one
    ///    generalized cylinder with a variable radius, as the paper models the L-hook);
    /// 1. the hook, a 1 mm wire (radius 0.5 mm) 6 mm long from `tip`, at a right angle.
    ///
    /// `orientation` is normalised; it must be finite and non-zero, `tip` finite.
    pub fn l_hook(tip: Vec3, orientation: Quat) -> Result<Self, ToolError> {
        let q = check_pose(tip, orientation)?;
        let handle = tip + q * (Vec3::Z * SHAFT_LENGTH_M);
        let taper_start = 1.0 - HOOK_TAPER_M / SHAFT_LENGTH_M;
        let straight = ToolCylinder::new(
            handle,
            tip,
            &[
                (0.0, SHAFT_RADIUS_M),
                (taper_start, SHAFT_RADIUS_M),
                (1.0, HOOK_WIRE_RADIUS_M),
            ],
        )?;
        let hook =
            ToolCylinder::constant(tip, tip + q * (Vec3::Y * HOOK_LENGTH_M), HOOK_WIRE_RADIUS_M)?;
        Self::new(vec![straight, hook])
    }

    /// A 5 mm grasper with its jaws open by `opening_rad` (the angle between the two jaws, in
    /// [0, π]). Aim-pose convention: the instrument points along local -Z; `hinge` (metres) is
    /// the jaws' pivot on the shaft's axis, the pin along local X, the jaws opening in the
    /// local Y-Z plane. Three cylinders:
    ///
    /// 0. the shaft, radius 2.5 mm, from the handle end (330 mm up the axis) to `hinge`;
    /// 1. the upper jaw (towards +Y) and 2. the lower jaw, each 20 mm long. Each jaw is half of
    ///    the shaft's cross-section, so its axis runs 1.25 mm off the pin (on its own side) and
    ///    its radius narrows from 1.25 mm at the hinge to 0.75 mm at the tip. Each jaw turns by
    ///    half the opening about the pin, so their axes make the angle `opening_rad`.
    pub fn grasper(hinge: Vec3, orientation: Quat, opening_rad: f32) -> Result<Self, ToolError> {
        let q = check_pose(hinge, orientation)?;
        if !(opening_rad.is_finite() && (0.0..=std::f32::consts::PI).contains(&opening_rad)) {
            return Err(ToolError::BadOpening { value: opening_rad });
        }
        let shaft = ToolCylinder::constant(
            hinge + q * (Vec3::Z * SHAFT_LENGTH_M),
            hinge,
            SHAFT_RADIUS_M,
        )?;
        let profile = [(0.0, JAW_BASE_RADIUS_M), (1.0, JAW_TIP_RADIUS_M)];
        let jaw = |side: f32| {
            // A rotation about +X by α takes -Z towards +Y: the upper jaw turns by +opening/2.
            let turn = q * Quat::from_rotation_x(side * 0.5 * opening_rad);
            let base = Vec3::Y * (side * JAW_BASE_RADIUS_M);
            ToolCylinder::new(
                hinge + turn * base,
                hinge + turn * (base + Vec3::NEG_Z * JAW_LENGTH_M),
                &profile,
            )
        };
        Self::new(vec![shaft, jaw(1.0)?, jaw(-1.0)?])
    }

    /// The cylinders, in the order contacts name them.
    pub fn cylinders(&self) -> &[ToolCylinder] {
        &self.cylinders
    }

    /// The instrument with every cylinder grown by `by_m` (see [`ToolCylinder::inflated`]).
    pub fn inflated(&self, by_m: f32) -> Self {
        Self {
            cylinders: self.cylinders.iter().map(|c| c.inflated(by_m)).collect(),
        }
    }

    /// The deepest penetration of vertex `v` over the cylinders (ties go to the lower index),
    /// skipping cylinder `c` where `touch[c]` is false (an empty `touch` tests them all).
    fn deepest(&self, vertex: usize, v: Vec3, touch: &[bool]) -> Option<ToolContact> {
        let mut best: Option<ToolContact> = None;
        for (c, cyl) in self.cylinders.iter().enumerate() {
            if !touch.get(c).copied().unwrap_or(true) {
                continue;
            }
            let Some(hit) = cyl.penetration(v) else {
                continue;
            };
            if best.is_none_or(|b| hit.depth_m > b.depth_m) {
                best = Some(ToolContact {
                    vertex: vertex as u32,
                    cylinder: c as u32,
                    t: hit.t,
                    axis_point: hit.axis_point,
                    depth_m: hit.depth_m,
                    dir: hit.dir,
                });
            }
        }
        best
    }

    /// Tests every point of `points` (the paper's "each vertex ... will be tested"); writes the
    /// penetrating ones to `out` (cleared first) in ascending vertex order.
    pub fn contacts_all(&self, points: PointCloud<'_>, out: &mut Vec<ToolContact>) -> QueryStats {
        out.clear();
        let n = points.len();
        points.for_each(0..n, |i, v| out.extend(self.deepest(i, v, &[])));
        QueryStats {
            blocks_examined: n.div_ceil(BLOCK_POINTS),
            points_examined: n,
        }
    }

    /// The contacts of the listed points only (`among`, indices into `points`, in the order
    /// given; an index past the end is skipped): a caller that has already culled the points
    /// near the instrument, e.g. once for several projections.
    pub fn contacts_among(&self, points: &[Vec3], among: &[u32], out: &mut Vec<ToolContact>) {
        out.clear();
        for &i in among {
            if let Some(&v) = points.get(i as usize) {
                out.extend(self.deepest(i as usize, v, &[]));
            }
        }
    }

    /// The same contacts as [`Self::contacts_all`], testing only the points of blocks that a
    /// cylinder may reach (each cylinder only against the blocks it may reach). `blocks` must
    /// be up to date for `points` (a block whose points moved since its last refresh may miss
    /// them). Sequential: the tool's neighbourhood is a few blocks, too little work for a
    /// fork-join on the haptic thread; contacts come in ascending vertex order. `out` is cleared
    /// first and reused, so a steady-state query does not allocate.
    pub fn contacts(
        &self,
        points: PointCloud<'_>,
        blocks: &PointBlocks,
        out: &mut Vec<ToolContact>,
    ) -> Result<QueryStats, ToolError> {
        out.clear();
        let n = points.len();
        if blocks.points != n {
            return Err(ToolError::StaleBlocks {
                blocks_points: blocks.points,
                points: n,
            });
        }
        let mut stats = QueryStats::default();
        // Up to 8 cylinders without allocating; more fall back to testing all of them.
        let mut touch = [false; 8];
        let mut near = [false; BLOCK_POINTS];
        let few = self.cylinders.len() <= touch.len();
        for (b, &(lo, hi)) in blocks.bounds.iter().enumerate() {
            let mut any = false;
            for (c, cyl) in self.cylinders.iter().enumerate() {
                let hit = cyl.may_touch(lo, hi);
                if let Some(slot) = touch.get_mut(c) {
                    *slot = hit;
                }
                any |= hit;
            }
            if !any {
                continue;
            }
            let range = b * BLOCK_POINTS..((b + 1) * BLOCK_POINTS).min(n);
            stats.blocks_examined += 1;
            stats.points_examined += range.len();
            let mask: &[bool] = if few { &touch } else { &[] };
            // The sieve: only points near a cylinder's axis segment are tested exactly.
            let near = &mut near[..range.len()];
            near.fill(false);
            for (c, cyl) in self.cylinders.iter().enumerate() {
                if mask.get(c).copied().unwrap_or(true) {
                    let segment = (cyl.p0, cyl.axis, cyl.inv_len2);
                    points.mark_near_segment(range.clone(), segment, cyl.sieve_reach_m(), near);
                }
            }
            for (k, _) in near.iter().enumerate().filter(|&(_, &n)| n) {
                let i = range.start + k;
                out.extend(self.deepest(i, points.point(i), mask));
            }
        }
        Ok(stats)
    }
}

/// The "standard point-based method" the paper compares against (Fig. 5c): only the tool's tip
/// touches tissue, as a sphere of `radius_m` (metres, finite and > 0) about `tip`. Every point
/// closer than `radius_m` to `tip` is written to `out` (cleared first) in ascending order, with
/// `cylinder` 0, `t` 0, `axis_point` the tip, `depth_m = radius_m - |v - tip|` and `dir` from
/// the tip to the point (a fixed unit vector, +X, for a point exactly at the tip).
pub fn tip_contacts(
    tip: Vec3,
    radius_m: f32,
    points: PointCloud<'_>,
    out: &mut Vec<ToolContact>,
) -> Result<(), ToolError> {
    out.clear();
    if !(radius_m.is_finite() && radius_m > 0.0) {
        return Err(ToolError::BadRadius {
            sample: 0,
            value: radius_m,
        });
    }
    points.for_each(0..points.len(), |i, v| {
        let off = v - tip;
        let d2 = off.length_squared();
        if d2 < radius_m * radius_m {
            out.push(ToolContact {
                vertex: i as u32,
                cylinder: 0,
                t: 0.0,
                axis_point: tip,
                depth_m: radius_m - d2.sqrt(),
                dir: off.try_normalize().unwrap_or(Vec3::X),
            });
        }
    });
    Ok(())
}

/// The area each vertex stands for, m².
#[derive(Debug, Clone, Copy)]
pub enum VertexAreas<'a> {
    /// Every vertex stands for the same area (a regular grid's cell area).
    Uniform(f32),
    /// Area of each vertex, indexed by vertex (e.g. a third of its triangles' areas).
    PerVertex(&'a [f32]),
}

impl VertexAreas<'_> {
    fn of(&self, vertex: u32) -> Result<f32, ToolError> {
        let a = match *self {
            Self::Uniform(a) => a,
            Self::PerVertex(areas) => {
                *areas.get(vertex as usize).ok_or(ToolError::MissingArea {
                    vertex,
                    len: areas.len(),
                })?
            }
        };
        if a.is_finite() && a >= 0.0 {
            Ok(a)
        } else {
            Err(ToolError::BadArea { vertex, value: a })
        }
    }
}

/// What the tissue does to the tool, in the world frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ToolReaction {
    /// Force on the tool, newtons: minus the sum of the penalty forces on the vertices.
    pub force_n: Vec3,
    /// Torque of those reactions about the point the caller named, newton-metres.
    pub torque_n_m: Vec3,
}

/// Penalty forces for `contacts`: vertex `i` is pushed by
/// `f_i = k · A_i · depth_i · dir_i` newtons, with `k = stiffness_pa_per_m` (force per unit area
/// per metre of depth, Pa/m) and `A_i` the vertex's area (m²). Summing `A_i depth_i` is a
/// quadrature of `∫ depth dA` over the contact patch, so the total does not change with the
/// mesh's resolution.
///
/// Writes `(vertex, f_i)` to `out` (cleared first) in the contacts' order and returns the
/// reaction on the tool: `F = -Σ f_i` and `τ = Σ (p_i - about) × (-f_i)`, with `p_i` the
/// contact's axis point (the force's line of action passes through it and the vertex). Sums run
/// sequentially in the contacts' order, so the result is the same on any thread count. On an
/// error `out` is left empty.
pub fn penalty_forces(
    contacts: &[ToolContact],
    areas: VertexAreas<'_>,
    stiffness_pa_per_m: f32,
    about: Vec3,
    out: &mut Vec<(u32, Vec3)>,
) -> Result<ToolReaction, ToolError> {
    out.clear();
    if !(stiffness_pa_per_m.is_finite() && stiffness_pa_per_m >= 0.0) {
        return Err(ToolError::BadStiffness {
            value: stiffness_pa_per_m,
        });
    }
    let mut reaction = ToolReaction::default();
    for c in contacts {
        let area = match areas.of(c.vertex) {
            Ok(a) => a,
            Err(e) => {
                out.clear();
                return Err(e);
            }
        };
        let f = c.dir * (stiffness_pa_per_m * area * c.depth_m);
        out.push((c.vertex, f));
        reaction.force_n -= f;
        reaction.torque_n_m += (c.axis_point - about).cross(-f);
    }
    Ok(reaction)
}

#[cfg(test)]
#[path = "tool_cylinder_tests.rs"]
mod tests;
