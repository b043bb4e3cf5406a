//! The rectum as a Cosserat rod (rectum paper, "Cosserat rectum modelling" and appendix A,
//! eqs 7-13) with "rigid spheres attached to the cosserat rod, which approximates the 3D shape
//! as bounding volumes of the rectum": the bowel's centreline is a [`CosseratRod`] clamped at
//! both ends (the section is held by the sigmoid above and the anal canal below), one sphere of
//! the bowel's outer radius rides on each node, instruments press the spheres, graspers hold
//! material points of the rod's surface, and the surface mesh is carried by a [`Skin`].
//!
//! **Contact.** Node `i` stands for the length `l_i` of rod around it (half of each element
//! beside it at rest). A sphere of radius `r` at `x_i` that reaches a depth `d_i` into a tool is
//! pushed out along the separating direction `n_i` by the penalty
//!
//!   f_i = k d_i l_i n_i,
//!
//! with `k` a stiffness per unit length of rod (Pa = N/m per m of rod); the total, `k sum_i
//! d_i l_i`, is a quadrature of `k integral depth(s) ds` along the rod and does not change with
//! the element count. The tool feels `-sum_i f_i`.
//!
//! **Grasp.** A grasp holds a material point of the rod's surface: element `e`, parameter `t`
//! along it and an offset `o` in the element's frame, so the point is
//! `p = x_e + t (x_{e+1} - x_e) + R_e o`. A spring of stiffness `k_g` pulls it to the jaw `j`:
//! `f = k_g (j - p)`, split onto the nodes as `(1 - t) f` and `t f` with the torque
//! `(R_e o) x f` on the element (statically the same as `f` applied at `p`); the tool feels
//! `-f`.
//!
//! **Stepping.** Both penalties enter the rod's backward-Euler step as given forces (explicit),
//! which is stable while `k_g dt^2 / m < 4` for the mass `m` moved (symplectic Euler's bound)
//! and, for contact, `k dt^2 / (rho A) < 4` (per unit length: node mass `rho A l_i` against
//! stiffness `k l_i`). The world's step may be longer than a grasp allows (2-4 ms in the
//! scenarios), so the rod takes substeps no longer than [`SkinnedRodParams::max_substep_s`] nor
//! `sqrt(2 m_min / k_g)` (ratio 2 on the lightest free node); the grasp spring is evaluated
//! again at every substep, while contact forces (computed once by the caller for the step) are
//! held over the step's substeps. A world step within those bounds is one rod step.

use super::skin::{RodPose, Skin, nearest_place};
use crate::collision::{Instrument, ToolCylinder};
use crate::mesh::TriMesh;
use crate::models::cosserat::{CosseratRod, RodParams};
use glam::{DVec3, Vec3};
use std::sync::Arc;

/// Substeps per world step at most (a stiffer grasp than this allows is stepped anyway).
const MAX_SUBSTEPS: usize = 64;
/// The model's name in the world unless given another ([`SkinnedRod::with_name`]).
const NAME: &str = "rod";

/// The rectum rod's figures. SI units throughout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkinnedRodParams {
    /// Rod elements between the clamped ends (nodes: one more). Default 30: 5 mm elements on
    /// the 15 cm section, a quarter of its 2 cm radius, enough for the smooth bends a grasper
    /// makes, at about 70 us per rod step.
    pub elements: usize,
    /// Effective Young's modulus of the bowel wall in bending, Pa. Default 200 kPa, a choice:
    /// uniaxial tests give the colorectal wall's linear-region modulus as 1.8 MPa (porcine)
    /// and 5.2 MPa (human) (Christensen et al. 2015, SpringerPlus 4:142) and 0.6-1.8 MPa for
    /// the colon under quasi-static load (Massalou et al. 2019, J Biomech 91:102-108), but a
    /// grasper bends the bowel at the small strains of the wall's J-shaped curve's toe, far
    /// softer than the linear region, and a thin tube (radius 7 times its wall here) flattens as
    /// it bends, so the bending stiffness of an intact circular section (`E I`) overstates it.
    /// At the defaults, lifting the mid section's anterior surface 9 mm takes about 5 N (the
    /// section is an arch clamped at both ends); tune against expert feel.
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio; default 0.45 (soft tissue is nearly incompressible).
    pub poisson_ratio: f64,
    /// Density of the wall, kg/m^3; default 1050 (soft tissue). The rod is the empty wall: its
    /// mass per length is `rho A` of the tube's section.
    pub density_kg_per_m3: f64,
    /// Outer radius of the bowel (and of each bounding sphere), m; default 20 mm, the
    /// anatomy's rectum radius (diameter 3-4 cm empty).
    pub radius_m: f64,
    /// Wall thickness, m; default 3 mm (the rectal wall is 2-4 mm thick).
    pub wall_m: f64,
    /// Drag on the centreline's motion, 1/s (force `-c m v`); default 10 (the surrounding
    /// tissue and fluid; a choice: `c / (2 omega)`, 3 % of critical at `omega` = 180 rad/s,
    /// the clamped span's first bending mode by Euler-Bernoulli at the defaults).
    pub damping_per_s: f64,
    /// Eq 12's curvature-rate damping per unit length, N m^2 s; default 1e-4, a choice that
    /// damps the first bending mode (`omega` about 180 rad/s, `E I` = 0.012 N m^2) by about
    /// `omega gamma / (2 E I)` = 75 % of critical: the bowel wall is strongly viscous, and a
    /// released bowel should settle, not ring.
    pub curvature_damping_n_m2_s: f64,
    /// Gravity, m/s^2; default (0, -9.81, 0): the patient supine, anterior (+y) up.
    pub gravity_m_per_s2: DVec3,
    /// Contact stiffness per unit length of rod, Pa (N/m per m of rod); default 5e4: a 5 mm
    /// shaft laid 2 mm into the bowel across it pushes with about 1.2 N, and `k dt^2 / (rho A)`
    /// is 0.55 at a 2 ms step (stable to about 5 ms).
    pub contact_stiffness_pa: f64,
    /// Grasp spring, N/m; default 5000: about ten times the rod's stiffness under a pull on
    /// the mid section's surface (about 550 N/m at the defaults), so a held point lags its jaw
    /// by about a tenth of the pull's travel (1 mm in 10 mm). A stiffer spring holds closer
    /// and needs shorter substeps (`max_substep_s`).
    pub grasp_stiffness_n_per_m: f64,
    /// How far from the rod's surface a jaw may take hold, m; default 5 mm.
    pub grasp_reach_m: f64,
    /// Longest rod substep, s; default 1 ms (module docs: a grasp's stability). The grasp
    /// shortens it further to `sqrt(2 m_min / k_g)`: 0.86 ms at the defaults, so a 1 ms world
    /// step is 2 rod steps, a 4 ms one 5.
    pub max_substep_s: f64,
}

impl Default for SkinnedRodParams {
    fn default() -> Self {
        SkinnedRodParams {
            elements: 30,
            youngs_modulus_pa: 200e3,
            poisson_ratio: 0.45,
            density_kg_per_m3: 1050.0,
            radius_m: 0.02,
            wall_m: 0.003,
            damping_per_s: 10.0,
            curvature_damping_n_m2_s: 1e-4,
            gravity_m_per_s2: DVec3::new(0.0, -9.81, 0.0),
            contact_stiffness_pa: 5e4,
            grasp_stiffness_n_per_m: 5000.0,
            grasp_reach_m: 0.005,
            max_substep_s: 1e-3,
        }
    }
}

/// Why a rectum rod could not be built, or a skin query could not be answered.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RodModelError {
    #[error("rectum rod parameter `{field}` is {value}; expected {expected}")]
    BadParameter {
        field: &'static str,
        value: f64,
        expected: &'static str,
    },
    #[error(
        "the rod's axis has {points} points and is {length_m} m long; it needs at least 2 \
         distinct points"
    )]
    ShortAxis { points: usize, length_m: f64 },
    #[error("{what} {index} is {value}; every coordinate must be finite (metres)")]
    NonFinite {
        what: &'static str,
        index: usize,
        value: Vec3,
    },
    #[error("point {index} is not bound by this skin, which holds {points} points")]
    NoSuchPoint { index: usize, points: usize },
    #[error("the output has {found} entries; the selection has {expected} points")]
    OutputLength { expected: usize, found: usize },
    #[error(
        "the pose has {nodes} nodes and {frames} frames; the skin was bound to {elements} \
         elements (nodes: one more)"
    )]
    PoseMismatch {
        elements: usize,
        nodes: usize,
        frames: usize,
    },
}

impl SkinnedRodParams {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), RodModelError> {
        let bad = |field, value, expected| {
            Err(RodModelError::BadParameter {
                field,
                value,
                expected,
            })
        };
        let p = self;
        if !(2..=10_000).contains(&p.elements) {
            return bad("elements", p.elements as f64, "an integer from 2 to 10000");
        }
        let positive = [
            ("youngs_modulus_pa", p.youngs_modulus_pa),
            ("density_kg_per_m3", p.density_kg_per_m3),
            ("radius_m", p.radius_m),
            ("max_substep_s", p.max_substep_s),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(field, v, "a finite value > 0");
            }
        }
        if !(p.poisson_ratio.is_finite() && p.poisson_ratio > -1.0 && p.poisson_ratio < 0.5) {
            return bad("poisson_ratio", p.poisson_ratio, "a value in (-1, 0.5)");
        }
        if !(p.wall_m.is_finite() && p.wall_m > 0.0 && p.wall_m <= p.radius_m) {
            return bad("wall_m", p.wall_m, "a value in (0, radius_m]");
        }
        let non_negative = [
            ("damping_per_s", p.damping_per_s),
            ("curvature_damping_n_m2_s", p.curvature_damping_n_m2_s),
            ("contact_stiffness_pa", p.contact_stiffness_pa),
            ("grasp_stiffness_n_per_m", p.grasp_stiffness_n_per_m),
            ("grasp_reach_m", p.grasp_reach_m),
        ];
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return bad(field, v, "a finite value >= 0");
            }
        }
        if let Some(v) = p
            .gravity_m_per_s2
            .to_array()
            .into_iter()
            .find(|v| !v.is_finite())
        {
            return bad("gravity_m_per_s2", v, "finite components");
        }
        Ok(())
    }

    /// The Cosserat rod's material and section.
    pub fn rod_params(&self) -> RodParams {
        RodParams {
            youngs_modulus_pa: self.youngs_modulus_pa,
            poisson_ratio: self.poisson_ratio,
            density_kg_per_m3: self.density_kg_per_m3,
            radius_m: self.radius_m,
            wall_m: Some(self.wall_m),
            damping_per_s: self.damping_per_s,
            curvature_damping_n_m2_s: self.curvature_damping_n_m2_s,
            gravity: self.gravity_m_per_s2,
        }
    }
}

/// A grasp: the material point held (module docs) and the jaw it is pulled to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grip {
    pub element: usize,
    /// Parameter along the element, 0 at node `element`, 1 at the next.
    pub t: f64,
    /// Offset of the held point from the centreline in the element's frame, m.
    pub offset: DVec3,
    /// Where the jaw is, m (the spring's other end).
    pub jaw: DVec3,
}

/// A tubular organ as a rod: its bounding spheres, its grasps and its skinned surface.
#[derive(Debug, Clone)]
pub struct SkinnedRod {
    /// Its name in a world, and in its events.
    name: String,
    params: SkinnedRodParams,
    rod: CosseratRod,
    /// Node positions as built, m.
    rest: Vec<DVec3>,
    /// Each node's share of the rod's rest length, m.
    share: Vec<f64>,
    /// Node positions in f32 (sphere centres, the collider's centreline), m.
    centre: Vec<Vec3>,
    /// The spheres' radii (all the rod's outer radius), m.
    radii: Vec<f32>,
    /// Forces on nodes for the next step (contacts, other models), N.
    load: Vec<DVec3>,
    /// Couples waiting for the next step, per element, N m.
    couples: Vec<DVec3>,
    /// The stiffness of the waiting loads per node, N/m ([`SkinnedRod::add_surface_force`]).
    load_k: Vec<f64>,
    grips: [Option<Grip>; 2],
    /// Grips the world's grasp contacts took (released when their contact stops).
    world_grip: [bool; 2],
    /// Contact reactions on each tool for the next step's output, N; whether any came.
    pending: [Vec3; 2],
    touched: [bool; 2],
    substep_s: f64,
    /// The surface at rest and its skin (shared with the snapshots built off the simulation
    /// thread: [`SkinnedRod::mesh_later`]).
    surface: Arc<TriMesh>,
    skin: Arc<Skin>,
    saved: CosseratRod,
    saved_grips: [Option<Grip>; 2],
    saved_world_grip: [bool; 2],
}

/// `n + 1` points evenly spaced by arc length along `axis`.
fn resample(axis: &[Vec3], n: usize) -> Result<Vec<DVec3>, RodModelError> {
    if let Some((index, &value)) = axis.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        return Err(RodModelError::NonFinite {
            what: "axis point",
            index,
            value,
        });
    }
    let pts: Vec<DVec3> = axis.iter().map(|p| p.as_dvec3()).collect();
    let mut cum = vec![0.0f64];
    for w in pts.windows(2) {
        cum.push(cum[cum.len() - 1] + (w[1] - w[0]).length());
    }
    let total = cum[cum.len() - 1];
    if pts.len() < 2 || total.is_nan() || total <= 1e-9 {
        return Err(RodModelError::ShortAxis {
            points: axis.len(),
            length_m: total,
        });
    }
    Ok((0..=n)
        .map(|i| {
            let s = total * i as f64 / n as f64;
            let k = cum.partition_point(|&c| c <= s).clamp(1, pts.len() - 1) - 1;
            let len = cum[k + 1] - cum[k];
            let t = if len > 0.0 { (s - cum[k]) / len } else { 0.0 };
            pts[k].lerp(pts[k + 1], t.clamp(0.0, 1.0))
        })
        .collect())
}

/// How deep a sphere of radius `rs` at `c` reaches into cylinder `cyl`, and the unit
/// direction that separates it (from the tool towards the sphere); none if they do not meet.
///
/// Along the axis segment (the centre's projection at `t` in [0, 1]) the cylinder's side is at
/// the radius `r(t)` from the axis (the paper's test, with the radius at the projection), so
/// the depth is `rs + r(t) - rho` for the centre at `rho` from the axis, pushed radially (a
/// centre inside the cylinder too). Beyond an end the cylinder is flat, a disc of the end's
/// radius `R`: a centre over the disc (`rho <= R`) meets its face at the distance `h` beyond the
/// end plane and is pushed along the axis; a centre outside it meets the rim, at
/// `sqrt(h^2 + (rho - R)^2)`, and is pushed away from the rim. A centre on the axis is pushed
/// along a fixed normal of the axis.
fn sphere_into_cylinder(cyl: &ToolCylinder, c: DVec3, rs: f64) -> Option<(f64, DVec3)> {
    let (p0, p1) = (cyl.p0().as_dvec3(), cyl.p1().as_dvec3());
    let a = p1 - p0;
    let len2 = a.length_squared();
    let unit = a.try_normalize()?;
    let t_raw = (c - p0).dot(a) / len2;
    if (0.0..=1.0).contains(&t_raw) {
        let q = p0 + a * t_raw;
        let off = c - q;
        let perp = off - unit * off.dot(unit);
        let rho = perp.length();
        let r = f64::from(cyl.radius_at(t_raw as f32));
        let depth = rs + r - rho;
        if depth.is_nan() || depth <= 0.0 {
            return None;
        }
        let dir = perp
            .try_normalize()
            .unwrap_or_else(|| unit.any_orthonormal_vector());
        return Some((depth, dir));
    }
    let (end, out, r) = if t_raw < 0.0 {
        (p0, -unit, f64::from(cyl.radius_at(0.0)))
    } else {
        (p1, unit, f64::from(cyl.radius_at(1.0)))
    };
    let off = c - end;
    let h = off.dot(out);
    let perp = off - out * h;
    let rho = perp.length();
    let (dist, dir) = if rho <= r {
        (h, out)
    } else {
        let rim = end + perp * (r / rho);
        let d = c - rim;
        let dist = d.length();
        (dist, d.try_normalize().unwrap_or(out))
    };
    let depth = rs - dist;
    (depth > 0.0).then_some((depth, dir))
}

impl SkinnedRod {
    /// The rod along the polyline `axis` (m; e.g. the anatomy's axis points), resampled evenly
    /// by length into `elements + 1` nodes, clamped at both ends, its first director towards
    /// +y (anterior) made normal to the axis; `surface` (the rectum's mesh) is skinned to it.
    pub fn new(
        axis: &[Vec3],
        surface: &TriMesh,
        params: SkinnedRodParams,
    ) -> Result<Self, RodModelError> {
        params.validate()?;
        if let Some((index, &value)) = surface
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(RodModelError::NonFinite {
                what: "surface vertex",
                index,
                value,
            });
        }
        let n = params.elements;
        let rest = resample(axis, n)?;
        let mut rod = CosseratRod::along(&rest, DVec3::Y, params.rod_params());
        rod.fix_node(0, true);
        rod.fix_node(n, true);
        let mut share = vec![0.0; n + 1];
        for (e, w) in rest.windows(2).enumerate() {
            let l = (w[1] - w[0]).length();
            share[e] += 0.5 * l;
            share[e + 1] += 0.5 * l;
        }
        let m_min = rod.masses()[1..n]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let k_g = params.grasp_stiffness_n_per_m;
        let substep_s = if k_g > 0.0 {
            params.max_substep_s.min((2.0 * m_min / k_g).sqrt())
        } else {
            params.max_substep_s
        };
        let centre = rest.iter().map(|p| p.as_vec3()).collect();
        Ok(SkinnedRod {
            name: NAME.to_string(),
            params,
            centre,
            radii: vec![params.radius_m as f32; n + 1],
            load: vec![DVec3::ZERO; n + 1],
            couples: vec![DVec3::ZERO; n],
            load_k: vec![0.0; n + 1],
            rest,
            share,
            grips: [None; 2],
            world_grip: [false; 2],
            pending: [Vec3::ZERO; 2],
            touched: [false; 2],
            substep_s,
            surface: Arc::new(surface.clone()),
            skin: Arc::new(Skin::bind_pose(RodPose::of(&rod), &surface.positions)),
            saved: rod.clone(),
            rod,
            saved_grips: [None; 2],
            saved_world_grip: [false; 2],
        })
    }

    /// The same rod named `name` (in its world, and in its events).
    pub fn with_name(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }

    /// The couples on each element waiting for the next step, N m.
    pub fn pending_couples(&self) -> &[DVec3] {
        &self.couples
    }

    /// The stiffness of the loads waiting on each node, N/m
    /// ([`SkinnedRod::add_surface_force`]).
    pub fn pending_stiffness(&self) -> &[f64] {
        &self.load_k
    }

    pub fn params(&self) -> &SkinnedRodParams {
        &self.params
    }

    /// The Cosserat rod (positions, frames, energies).
    pub fn rod(&self) -> &CosseratRod {
        &self.rod
    }

    /// Node positions as built, m.
    pub fn rest_positions(&self) -> &[DVec3] {
        &self.rest
    }

    /// Each node's share of the rod's rest length, m (they sum to the length).
    pub fn length_shares(&self) -> &[f64] {
        &self.share
    }

    /// The bounding spheres' centres (the nodes), m.
    pub fn sphere_centres(&self) -> &[Vec3] {
        &self.centre
    }

    /// The bounding spheres' radius (the bowel's outer radius), m.
    pub fn sphere_radius_m(&self) -> f64 {
        self.params.radius_m
    }

    /// Forces waiting on each node for the next step (contacts, other models), N.
    pub fn pending_forces(&self) -> &[DVec3] {
        &self.load
    }

    /// The surface mesh's skin.
    pub fn skin(&self) -> &Skin {
        &self.skin
    }

    /// The surface mesh as built.
    pub fn surface(&self) -> &TriMesh {
        &self.surface
    }

    /// The longest substep the rod takes, s (module docs).
    pub fn substep_s(&self) -> f64 {
        self.substep_s
    }

    /// Adds a force on node `i` for the next step, N (a node that does not exist, or a
    /// non-finite force, is ignored).
    pub fn add_node_force(&mut self, i: usize, f: DVec3) {
        if let Some(slot) = self.load.get_mut(i)
            && f.is_finite()
        {
            *slot += f;
        }
    }

    /// Adds, for the next step, the loads of many surface points on element `e` at once
    /// (their sum over [`SkinnedRod::add_surface_force`]): `ends` the forces on its two
    /// nodes, `couple` the couple on the element, `k` the stiffness on each node (N, N m,
    /// N/m). A missing element or a non-finite value is ignored.
    pub fn add_element_load(&mut self, e: usize, ends: [DVec3; 2], couple: DVec3, k: [f64; 2]) {
        let finite = ends.iter().all(|f| f.is_finite())
            && couple.is_finite()
            && k.iter().all(|k| k.is_finite());
        if e >= self.couples.len() || !finite {
            return;
        }
        self.load[e] += ends[0];
        self.load[e + 1] += ends[1];
        self.couples[e] += couple;
        self.load_k[e] += k[0].max(0.0);
        self.load_k[e + 1] += k[1].max(0.0);
    }

    /// Adds, for the next step, a force `f` (N) acting on the rod's surface at `lever` (m)
    /// from the centreline point at parameter `t` of element `e`: `(1 - t) f` and `t f` on
    /// the element's nodes and the couple `lever x f` on the element, statically the same as
    /// `f` at that point (the grasp's split, module docs). `k` (N/m) is the force's
    /// stiffness, shared the same way: the force falls by `k` per metre the rod moves during
    /// the step, taken implicitly by the rod's step (tissue holding the rod, whose load
    /// would otherwise come one step late and ring). A missing element or a non-finite value
    /// is ignored.
    pub fn add_surface_force(&mut self, e: usize, t: f64, lever: DVec3, f: DVec3, k: f64) {
        if e >= self.couples.len()
            || !(t.is_finite() && lever.is_finite() && f.is_finite() && k.is_finite())
        {
            return;
        }
        let t = t.clamp(0.0, 1.0);
        self.load[e] += f * (1.0 - t);
        self.load[e + 1] += f * t;
        self.couples[e] += lever.cross(f);
        let k = k.max(0.0);
        self.load_k[e] += k * (1.0 - t);
        self.load_k[e + 1] += k * t;
    }

    /// Pushes every sphere that reaches into a tool out by `k d_i l_i` (module docs), with
    /// `depth(i)` the depth and separating direction of sphere `i`, if it touches. Returns the
    /// reaction on the tool and records it for hand `hand`'s output.
    fn push_spheres(&mut self, hand: usize, depth: impl Fn(DVec3) -> Option<(f64, DVec3)>) -> Vec3 {
        let k = self.params.contact_stiffness_pa;
        let mut total = DVec3::ZERO;
        for i in 0..self.load.len() {
            let Some((d, dir)) = depth(self.rod.positions()[i]) else {
                continue;
            };
            let f = dir * (k * d * self.share[i]);
            self.load[i] += f;
            total += f;
        }
        let reaction = (-total).as_vec3();
        if let (Some(p), Some(t)) = (self.pending.get_mut(hand), self.touched.get_mut(hand)) {
            *p += reaction;
            *t = true;
        }
        reaction
    }

    /// Tool contact: every bounding sphere against every cylinder of `tool` (the deepest
    /// cylinder only, so overlapping cylinders do not push a sphere twice), each touching
    /// sphere pushed out by the penalty `k d_i l_i` for the next step (see
    /// `sphere_into_cylinder` for the side, the flat ends and their rims). A sphere whose
    /// centre lies outside the tool's box grown by the sphere's radius is skipped. Returns the
    /// tool's reaction (minus the sum of the forces), N, and adds it to hand `hand`'s output (0
    /// left, 1 right; another hand's reaction is returned only).
    pub fn press(&mut self, tool: &Instrument, hand: usize) -> Vec3 {
        let rs = self.params.radius_m;
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for c in tool.cylinders() {
            let (a, b) = (c.p0().as_dvec3(), c.p1().as_dvec3());
            let grow = DVec3::splat(f64::from(c.max_radius_m()) + rs);
            lo = lo.min(a.min(b) - grow);
            hi = hi.max(a.max(b) + grow);
        }
        self.push_spheres(hand, |x| {
            if !(x.cmpge(lo).all() && x.cmple(hi).all()) {
                return None;
            }
            let mut best: Option<(f64, DVec3)> = None;
            for c in tool.cylinders() {
                if let Some(hit) = sphere_into_cylinder(c, x, rs)
                    && best.is_none_or(|b| hit.0 > b.0)
                {
                    best = Some(hit);
                }
            }
            best
        })
    }

    /// A sphere tool (an instrument's tip, radius `radius_m` about `centre`) against the
    /// bounding spheres: depth `r + radius_m - |x_i - centre|`, pushed away from the centre.
    pub fn press_sphere(&mut self, centre: Vec3, radius_m: f32, hand: usize) -> Vec3 {
        let (c, rt) = (centre.as_dvec3(), f64::from(radius_m));
        let rs = self.params.radius_m;
        if !(c.is_finite() && rt.is_finite() && rt >= 0.0) {
            return Vec3::ZERO;
        }
        self.push_spheres(hand, |x| {
            let off = x - c;
            let dist = off.length();
            let depth = rs + rt - dist;
            (depth > 0.0).then(|| (depth, off.try_normalize().unwrap_or(DVec3::Y)))
        })
    }

    /// Takes hold with hand `hand` (0 left, 1 right) of the rod's surface point nearest `jaw`
    /// if the jaw is within the grasp reach of the surface (or inside the rod); replaces the
    /// hand's former grasp. The surface point is where the line from the nearest centreline
    /// point to the jaw leaves the tube (the first director's side for a jaw on the axis).
    pub fn grasp(&mut self, hand: usize, jaw: Vec3) -> bool {
        self.grasp_within(hand, jaw, self.params.grasp_reach_m)
    }

    fn grasp_within(&mut self, hand: usize, jaw: Vec3, reach_m: f64) -> bool {
        let j = jaw.as_dvec3();
        if hand > 1 || !j.is_finite() {
            return false;
        }
        let x = self.rod.positions();
        let (e, t, d2) = nearest_place(x, j);
        let r = self.params.radius_m;
        let gap = d2.sqrt() - r;
        if gap.is_nan() || gap > reach_m {
            return false;
        }
        let frame = self.rod.frames()[e];
        let c = x[e] + (x[e + 1] - x[e]) * t;
        let out = (j - c).try_normalize().unwrap_or(frame.x_axis);
        self.grips[hand] = Some(Grip {
            element: e,
            t,
            offset: frame.transpose() * (out * r),
            jaw: j,
        });
        true
    }

    /// Where grasp `g`'s material point is now and the lever from the centreline to it
    /// (world), m.
    fn held(&self, g: &Grip) -> (DVec3, DVec3) {
        let x = self.rod.positions();
        let lever = self.rod.frames()[g.element] * g.offset;
        (
            x[g.element] + (x[g.element + 1] - x[g.element]) * g.t + lever,
            lever,
        )
    }

    /// Where hand `hand`'s held material point is now, m.
    pub fn held_point(&self, hand: usize) -> Option<Vec3> {
        let g = self.grips.get(hand).copied().flatten()?;
        Some(self.held(&g).0.as_vec3())
    }

    /// The grasp: which material point hand `hand` holds, and its jaw.
    pub fn grip(&self, hand: usize) -> Option<Grip> {
        self.grips.get(hand).copied().flatten()
    }

    /// Moves hand `hand`'s jaw to `jaw`: the grasp spring pulls the held material point
    /// towards it from now on (re-evaluated at every substep, module docs). Returns the
    /// reaction on the tool now, `-k_g (jaw - p)`, N; zero if the hand holds nothing. The
    /// reaction the step reports for the hand is the spring's mean over the step.
    pub fn hold(&mut self, hand: usize, jaw: Vec3) -> Vec3 {
        let j = jaw.as_dvec3();
        let Some(g) = self.grips.get_mut(hand).and_then(|g| g.as_mut()) else {
            return Vec3::ZERO;
        };
        if j.is_finite() {
            g.jaw = j;
        }
        let g = *g;
        let (p, _) = self.held(&g);
        (-(g.jaw - p) * self.params.grasp_stiffness_n_per_m).as_vec3()
    }

    /// Lets go of whatever hand `hand` holds.
    pub fn release(&mut self, hand: usize) {
        if let Some(g) = self.grips.get_mut(hand) {
            *g = None;
        }
        if let Some(w) = self.world_grip.get_mut(hand) {
            *w = false;
        }
    }

    /// Puts hand `hand`'s grasp spring on the rod for the next rod step; returns its force on
    /// the rod, N.
    fn apply_grip(&mut self, hand: usize) -> DVec3 {
        let Some(g) = self.grips[hand] else {
            return DVec3::ZERO;
        };
        let (p, lever) = self.held(&g);
        let f = (g.jaw - p) * self.params.grasp_stiffness_n_per_m;
        self.rod.add_force(g.element, f * (1.0 - g.t));
        self.rod.add_force(g.element + 1, f * g.t);
        self.rod.add_torque(g.element, lever.cross(f));
        f
    }

    /// Advances the rod by `dt_s` (substeps as the module docs say) under the waiting forces
    /// and the grasps. Returns the reaction on each tool that pressed or held this step, N:
    /// the contacts' reactions plus the grasp spring's mean over the substeps.
    pub fn advance(&mut self, dt_s: f64) -> [Option<Vec3>; 2] {
        let mut grip_sum = [DVec3::ZERO; 2];
        let steps = if dt_s.is_finite() && dt_s > 0.0 {
            ((dt_s / self.substep_s).ceil() as usize).clamp(1, MAX_SUBSTEPS)
        } else {
            0
        };
        let start: Vec<DVec3> = self.rod.positions().to_vec();
        for _ in 0..steps {
            // A stiff load falls with the motion since the step began; the rest of its fall
            // within this substep is the rod step's own (implicit).
            for (i, f) in self.load.iter().enumerate() {
                let k = self.load_k[i];
                self.rod
                    .add_force(i, *f - (self.rod.positions()[i] - start[i]) * k);
                self.rod.add_node_stiffness(i, k);
            }
            for (e, c) in self.couples.iter().enumerate() {
                self.rod.add_torque(e, *c);
            }
            for (hand, sum) in grip_sum.iter_mut().enumerate() {
                *sum -= self.apply_grip(hand);
            }
            self.rod.step(dt_s / steps as f64);
        }
        self.load.iter_mut().for_each(|f| *f = DVec3::ZERO);
        self.couples.iter_mut().for_each(|c| *c = DVec3::ZERO);
        self.load_k.iter_mut().for_each(|k| *k = 0.0);
        self.refresh_centres();
        let mut out = [None; 2];
        for (hand, slot) in out.iter_mut().enumerate() {
            let held = self.grips[hand].is_some() && steps > 0;
            if self.touched[hand] || held {
                let grip = if held {
                    (grip_sum[hand] / steps as f64).as_vec3()
                } else {
                    Vec3::ZERO
                };
                *slot = Some(self.pending[hand] + grip);
            }
        }
        self.pending = [Vec3::ZERO; 2];
        self.touched = [false; 2];
        out
    }

    fn refresh_centres(&mut self) {
        for (c, x) in self.centre.iter_mut().zip(self.rod.positions()) {
            *c = x.as_vec3();
        }
    }
}

#[path = "skinned_model.rs"]
mod model;
