//! The force-based soft body on a 2-simplex mesh (nephrectomy paper): per-point spring,
//! damping, pressure and offset forces integrated explicitly with unit mass, then XPBD stretch
//! and dihedral bending constraints, and breakable ties between regions.
//!
//! Points at rest sleep: a point whose speed stayed below `sleep_speed_m_per_s` for
//! `SLEEP_STEPS` steps at its rest position is skipped until a contact, a constraint or a cut
//! wakes it. A sleeping point is exactly at rest, so skipping it changes nothing.

use super::forces;
use super::simplex::SimplexMesh;
use super::xpbd::{self, Bend, Stretch};
use crate::collision::FaceBvh;
use crate::sim::{
    Contact, ContactKind, CutStroke, EventKind, ModelOutput, ModelSizes, ModelSnapshot,
    SurfaceView, TissueModel, ToolId,
};
use glam::{Quat, Vec3};
use parry3d::bounding_volume::Aabb;
use serde::{Deserialize, Serialize};

const SLEEP_STEPS: u16 = 30;
/// A sleeping anchored point must be this close to rest, metres.
const SLEEP_DISTANCE_M: f32 = 2e-5;
/// A point that belongs to no pressure group.
const NO_GROUP: u32 = u32::MAX;
/// A sleeping point nudged less than this by a constraint is put back and stays asleep, m.
const WAKE_DISTANCE_M: f32 = 1e-5;
/// BVH leaves are enlarged by this margin so that small motions need no refit, metres.
const BVH_MARGIN_M: f32 = 1e-3;

/// Parameters of the force-based soft body. Every field has its unit in its name.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SoftBodyParams {
    /// Spring pulling each anchored point to its rest position, N/m per unit-mass point.
    pub spring_n_per_m: f32,
    /// Velocity damping d in v (1 - d dt), 1/s.
    pub damping_per_s: f32,
    /// Pressure a pressing tool applies, Pa.
    pub pressure_pa: f32,
    /// Area over which a pressing tool applies its pressure, m^2.
    pub contact_area_m2: f32,
    /// Lift of the force origin above the contact point along the normal, m.
    pub offset_m: f32,
    /// Distance scale of the falloff F / (1 + (d / l)^2), m.
    pub falloff_m: f32,
    /// Internal pressure per unit relative volume loss, Pa.
    pub volume_stiffness_pa: f32,
    /// XPBD compliance of the stretch constraints (eq 11), m/N.
    pub stretch_compliance_m_per_n: f32,
    /// XPBD compliance of the dihedral bending constraints (eq 12), rad/(N m).
    pub bend_compliance_per_n_m: f32,
    /// XPBD compliance of the ties, m/N.
    pub tie_compliance_m_per_n: f32,
    /// A tie breaks when its constraint force exceeds this, N.
    pub tie_break_force_n: f32,
    /// Constraint projections per step.
    pub solver_iterations: u32,
    /// Speed under which a point counts as still, m/s.
    pub sleep_speed_m_per_s: f32,
}

/// The soft body's parameters a supervisor may change while a session runs (the nephrectomy
/// paper lets users tune the soft-body variables live, its Figure 5).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Tuning {
    /// Spring to the rest position, N/m per unit-mass point (eq 2).
    pub spring_n_per_m: f32,
    /// Velocity damping, 1/s (eq 5).
    pub damping_per_s: f32,
    /// Pressure of a pressing tool, Pa (eq 4).
    pub pressure_pa: f32,
    /// Lift of the force origin above the contact, m.
    pub offset_m: f32,
}

impl Tuning {
    /// Each value's name and allowed range (the sliders' ends).
    pub const RANGES: [(&'static str, f32, f32); 4] = [
        ("spring_n_per_m", 1.0, 400.0),
        ("damping_per_s", 0.0, 50.0),
        ("pressure_pa", 0.0, 10_000.0),
        ("offset_m", 0.0, 0.01),
    ];

    pub fn of(p: &SoftBodyParams) -> Tuning {
        Tuning {
            spring_n_per_m: p.spring_n_per_m,
            damping_per_s: p.damping_per_s,
            pressure_pa: p.pressure_pa,
            offset_m: p.offset_m,
        }
    }

    pub fn values(&self) -> [f32; 4] {
        [
            self.spring_n_per_m,
            self.damping_per_s,
            self.pressure_pa,
            self.offset_m,
        ]
    }

    /// `Err(key, message)` for the first value outside its range or not a number.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        for ((key, lo, hi), v) in Tuning::RANGES.iter().zip(self.values()) {
            if !(v.is_finite() && (*lo..=*hi).contains(&v)) {
                return Err((key, format!("must be {lo} to {hi}, got {v}")));
            }
        }
        Ok(())
    }

    /// These values written into `p`.
    pub fn apply(&self, p: &mut SoftBodyParams) {
        p.spring_n_per_m = self.spring_n_per_m;
        p.damping_per_s = self.damping_per_s;
        p.pressure_pa = self.pressure_pa;
        p.offset_m = self.offset_m;
    }
}

impl Default for SoftBodyParams {
    fn default() -> Self {
        Self {
            spring_n_per_m: 40.0,
            damping_per_s: 8.0,
            pressure_pa: 1500.0,
            contact_area_m2: 1e-4,
            offset_m: 0.002,
            falloff_m: 0.006,
            volume_stiffness_pa: 2000.0,
            stretch_compliance_m_per_n: 1e-3,
            bend_compliance_per_n_m: 0.1,
            tie_compliance_m_per_n: 1e-4,
            tie_break_force_n: 2.0,
            solver_iterations: 1,
            sleep_speed_m_per_s: 1e-4,
        }
    }
}

/// A piece of the body cut free of its anchors.
#[derive(Debug, Clone)]
struct FreePart {
    points: Vec<u32>,
    /// The fitted motion from rest: x = rotation * rest + translation (m).
    rotation: Quat,
    translation: Vec3,
    /// Farthest point from the piece's rest centre, m.
    radius_m: f32,
    /// How far the piece moved since its BVH leaves were last refreshed, m.
    bvh_drift_m: f32,
}

impl Default for FreePart {
    fn default() -> Self {
        FreePart {
            points: Vec::new(),
            rotation: Quat::IDENTITY,
            translation: Vec3::ZERO,
            radius_m: 0.0,
            bvh_drift_m: 0.0,
        }
    }
}

/// The rotation part of a deformation gradient `a`, by Mueller et al.'s (2016) iteration from
/// a starting guess: robust when `a` is flat or degenerate (then the guess is kept).
fn extract_rotation(a: glam::Mat3, guess: Quat) -> Quat {
    let mut q = guess;
    for _ in 0..20 {
        let r = glam::Mat3::from_quat(q);
        let num = r.x_axis.cross(a.x_axis) + r.y_axis.cross(a.y_axis) + r.z_axis.cross(a.z_axis);
        let den = (r.x_axis.dot(a.x_axis) + r.y_axis.dot(a.y_axis) + r.z_axis.dot(a.z_axis)).abs()
            + 1e-12;
        let omega = num / den;
        let w = omega.length();
        if !w.is_finite() || w < 1e-7 {
            break;
        }
        q = (Quat::from_axis_angle(omega / w, w) * q).normalize();
    }
    q
}

/// A breakable distance constraint between two points (tumour to kidney bed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tie {
    pub a: u32,
    pub b: u32,
    pub rest_m: f32,
    pub alive: bool,
}

#[derive(Debug, Clone)]
struct Held {
    tool: ToolId,
    points: Vec<(u32, Vec3)>,
    rotation: Quat,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Constraint {
    Stretch(u32),
    Bend(u32),
    Tie(u32),
}

/// Box of face `f`: its simplex point padded by the rest distance to its corners (x 1.25),
/// and its three neighbours.
fn leaf_aabb(x: &[Vec3], pad: &[f32], neighbors: &[[u32; 3]], f: usize) -> Aabb {
    let p = x[f];
    let pad = Vec3::splat(pad[f] * 1.25);
    let mut lo = p - pad;
    let mut hi = p + pad;
    for &n in &neighbors[f] {
        lo = lo.min(x[n as usize]);
        hi = hi.max(x[n as usize]);
    }
    Aabb::new(lo, hi)
}

pub struct SoftBody {
    name: String,
    pub params: SoftBodyParams,
    mesh: SimplexMesh,
    region: Vec<u8>,
    /// Region whose largest connected part is anchored to the body.
    anchor_region: u8,
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    normal: Vec<Vec3>,
    area: Vec<f32>,
    volume_term: Vec<f32>,
    alive: Vec<bool>,
    anchored: Vec<bool>,
    kinematic: Vec<bool>,
    inv_mass: Vec<f32>,
    stretch: Vec<Stretch>,
    stretch_alive: Vec<bool>,
    bend: Vec<Bend>,
    bend_alive: Vec<bool>,
    ties: Vec<Tie>,
    /// Constraints touching each point (CSR).
    adj_start: Vec<u32>,
    /// Constraint ids (see [`SoftBody::kind`]): 4 bytes each.
    adj: Vec<u32>,
    awake: Vec<bool>,
    /// Where each sleeping point sleeps.
    sleep_at: Vec<Vec3>,
    still: Vec<u16>,
    active: Vec<u32>,
    /// Per pressure group: the enclosed volume at rest, m^3.
    rest_volume: Vec<f32>,
    /// Per point: its pressure group (one per connected part and region that encloses a
    /// volume), or `NO_GROUP` for points of an open, free part, which enclose nothing.
    pressure_group: Vec<u32>,
    /// Pieces cut free of the anchored organ, and each point's piece (or `NO_GROUP`).
    free_parts: Vec<FreePart>,
    part_of: Vec<u32>,
    /// Points of carried pieces whose BVH leaves are due a refresh this step.
    bvh_pending: Vec<u32>,
    held: Vec<Held>,
    bvh: FaceBvh,
    leaf_pad: Vec<f32>,
    topology_dirty: bool,
    component: Vec<u32>,
    checkpoint: (Vec<Vec3>, Vec<Vec3>),
    // Scratch, reused every step.
    stamp: Vec<u32>,
    stamp_now: u32,
    force: Vec<Vec3>,
    touched: Vec<u32>,
    /// Per point: how far the instrument tips pushed it this step (and which points).
    pushed: Vec<Vec3>,
    pushed_list: Vec<u32>,
    constraints_now: Vec<u32>,
    moved: Vec<u32>,
    before: Vec<Vec3>,
    lambda: Vec<f32>,
    /// One bit per constraint: listed this step (cleared again once the list is made).
    listed: Vec<u64>,
    /// Per region: the running sum of volume terms.
    volume: Vec<f64>,
    steps_since_resum: u32,
    contacting: [bool; 2],
}

impl SoftBody {
    /// Builds a body from a simplex mesh and a region per face.
    pub fn new(name: &str, mesh: SimplexMesh, region: Vec<u8>, params: SoftBodyParams) -> Self {
        let n = mesh.len();
        let x = mesh.rest.clone();
        let mut stretch = Vec::with_capacity(n * 3 / 2);
        let mut bend = Vec::with_capacity(n * 3 / 2);
        for i in 0..n {
            for k in 0..3 {
                let j = mesh.neighbors[i][k] as usize;
                if i < j {
                    stretch.push(Stretch {
                        a: i as u32,
                        b: j as u32,
                        rest_m: (x[i] - x[j]).length(),
                    });
                    // Wings: the next neighbour of each end, turning the same way round.
                    let c = mesh.neighbors[i][(k + 1) % 3];
                    let kj = mesh.neighbors[j]
                        .iter()
                        .position(|&q| q as usize == i)
                        .unwrap_or(0);
                    let d = mesh.neighbors[j][(kj + 1) % 3];
                    let mut b = Bend {
                        a: i as u32,
                        b: j as u32,
                        c,
                        d,
                        rest_rad: 0.0,
                    };
                    b.rest_rad = xpbd::dihedral(&x, &b);
                    bend.push(b);
                }
            }
        }
        let mut body = SoftBody {
            name: name.to_string(),
            params,
            region,
            anchor_region: 0,
            v: vec![Vec3::ZERO; n],
            normal: vec![Vec3::ZERO; n],
            area: vec![0.0; n],
            volume_term: vec![0.0; n],
            alive: vec![true; n],
            anchored: vec![true; n],
            kinematic: vec![false; n],
            inv_mass: vec![1.0; n],
            stretch_alive: vec![true; stretch.len()],
            bend_alive: vec![true; bend.len()],
            stretch,
            bend,
            ties: Vec::new(),
            adj_start: Vec::new(),
            adj: Vec::new(),
            awake: vec![false; n],
            sleep_at: x.clone(),
            still: vec![0; n],
            active: Vec::new(),
            rest_volume: Vec::new(),
            pressure_group: vec![NO_GROUP; n],
            free_parts: Vec::new(),
            part_of: vec![NO_GROUP; n],
            bvh_pending: Vec::new(),
            held: Vec::new(),
            bvh: FaceBvh::new(&[], |_| Aabb::new_invalid()),
            leaf_pad: vec![0.0; n],
            topology_dirty: true,
            component: vec![0; n],
            checkpoint: (x.clone(), vec![Vec3::ZERO; n]),
            stamp: vec![0; n],
            stamp_now: 0,
            force: vec![Vec3::ZERO; n],
            touched: Vec::new(),
            pushed: vec![Vec3::ZERO; n],
            pushed_list: Vec::new(),
            constraints_now: Vec::new(),
            moved: Vec::new(),
            before: Vec::new(),
            lambda: Vec::new(),
            listed: Vec::new(),
            volume: Vec::new(),
            steps_since_resum: 0,
            contacting: [false; 2],
            x,
            mesh,
        };
        body.regroup_pressure();
        for i in 0..n {
            body.refresh_normal(i);
        }
        // Pad each leaf by the distance from the simplex point to its face's corners at rest.
        for f in 0..n {
            let c = body.mesh.faces[f].map(|v| body.mesh.tri_rest[v as usize]);
            body.leaf_pad[f] = c
                .iter()
                .map(|p| (*p - body.x[f]).length())
                .fold(0.0, f32::max);
        }
        body.bvh = FaceBvh::new(&body.mesh.rest, |f| body.leaf_aabb(f));
        body.rebuild_adjacency();
        body
    }

    /// Adds breakable ties (e.g. tumour to its bed).
    pub fn set_ties(&mut self, ties: Vec<Tie>) {
        self.ties = ties;
        self.rebuild_adjacency();
        self.topology_dirty = true;
    }

    pub fn ties(&self) -> &[Tie] {
        &self.ties
    }

    pub fn mesh(&self) -> &SimplexMesh {
        &self.mesh
    }

    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }

    /// Changes the tunable parameters from the next step on (points at rest stay asleep:
    /// at rest none of these four moves them).
    pub fn tune(&mut self, t: &Tuning) {
        t.apply(&mut self.params);
    }

    /// The model's name in the scenario ("kidney", "renal_artery", ...).
    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn regions(&self) -> &[u8] {
        &self.region
    }

    pub fn alive(&self) -> &[bool] {
        &self.alive
    }

    /// Connected part of each point (after the last topology update).
    pub fn components(&self) -> &[u32] {
        &self.component
    }

    fn rebuild_render_runs(&mut self) {
        let rest = &self.mesh.rest;
        let normals: Vec<Vec3> = (0..rest.len())
            .map(|i| self.mesh.normal_area(rest, &self.alive, i).0)
            .collect();
        let alive = self.alive.clone();
        self.mesh.rebuild_render(&alive, &normals);
    }

    /// Brings connected parts and anchoring up to date after cuts or torn ties.
    pub fn refresh_topology(&mut self) {
        if self.topology_dirty {
            self.update_topology();
        }
    }

    pub fn is_anchored(&self, i: usize) -> bool {
        self.anchored[i]
    }

    /// Overwrites a point's position (tests inject faults with this).
    pub fn set_position(&mut self, i: usize, p: Vec3) {
        self.x[i] = p;
        self.wake(i);
    }

    /// Number of points awake after the last step.
    pub fn awake_count(&self) -> usize {
        self.active.len()
    }

    /// Rest area of face `f`, m^2.
    pub fn rest_face_area(&self, f: usize) -> f32 {
        let [a, b, c] = self.mesh.faces[f].map(|v| self.mesh.tri_rest[v as usize]);
        0.5 * (b - a).cross(c - a).length()
    }

    fn rebuild_adjacency(&mut self) {
        let n = self.x.len();
        let mut count = vec![0u32; n + 1];
        let each = |c: Constraint, s: &Self, f: &mut dyn FnMut(u32)| match c {
            Constraint::Stretch(k) => {
                let q = s.stretch[k as usize];
                f(q.a);
                f(q.b);
            }
            Constraint::Bend(k) => {
                let q = s.bend[k as usize];
                for p in [q.a, q.b, q.c, q.d] {
                    f(p);
                }
            }
            Constraint::Tie(k) => {
                let q = s.ties[k as usize];
                f(q.a);
                f(q.b);
            }
        };
        let all: Vec<Constraint> = (0..self.stretch.len() as u32)
            .map(Constraint::Stretch)
            .chain((0..self.bend.len() as u32).map(Constraint::Bend))
            .chain((0..self.ties.len() as u32).map(Constraint::Tie))
            .collect();
        for &c in &all {
            each(c, self, &mut |p| count[p as usize + 1] += 1);
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut adj = vec![0u32; count[n] as usize];
        for &c in &all {
            let id = self.constraint_index(c) as u32;
            each(c, self, &mut |p| {
                adj[fill[p as usize] as usize] = id;
                fill[p as usize] += 1;
            });
        }
        self.adj_start = count;
        self.adj = adj;
        self.listed = vec![0; all.len().div_ceil(64)];
    }

    /// What constraint id `id` is: stretch constraints first, then bends, then ties.
    fn kind(&self, id: u32) -> Constraint {
        let (ns, nb) = (self.stretch.len() as u32, self.bend.len() as u32);
        if id < ns {
            Constraint::Stretch(id)
        } else if id < ns + nb {
            Constraint::Bend(id - ns)
        } else {
            Constraint::Tie(id - ns - nb)
        }
    }

    fn constraint_index(&self, c: Constraint) -> usize {
        match c {
            Constraint::Stretch(k) => k as usize,
            Constraint::Bend(k) => self.stretch.len() + k as usize,
            Constraint::Tie(k) => self.stretch.len() + self.bend.len() + k as usize,
        }
    }

    fn leaf_aabb(&self, f: usize) -> Aabb {
        leaf_aabb(&self.x, &self.leaf_pad, &self.mesh.neighbors, f)
    }

    fn refresh_normal(&mut self, i: usize) {
        let (n, a) = self.mesh.normal_area(&self.x, &self.alive, i);
        self.normal[i] = n;
        self.area[i] = a;
        let term = if self.alive[i] {
            self.x[i].dot(n) * a / 3.0
        } else {
            0.0
        };
        if let Some(v) = self.volume.get_mut(self.pressure_group[i] as usize) {
            *v += (term - self.volume_term[i]) as f64;
        }
        self.volume_term[i] = term;
    }

    /// Sums the volume terms from scratch (also done periodically against rounding drift).
    fn resum_volumes(&mut self) {
        let mut v = vec![0.0f64; self.rest_volume.len()];
        for (i, t) in self.volume_term.iter().enumerate() {
            if let Some(g) = v.get_mut(self.pressure_group[i] as usize) {
                *g += *t as f64;
            }
        }
        self.volume = v;
        self.steps_since_resum = 0;
    }

    fn region_volumes(&mut self) -> Vec<f32> {
        self.steps_since_resum += 1;
        if self.volume.len() != self.rest_volume.len() || self.steps_since_resum >= 1024 {
            self.resum_volumes();
        }
        self.volume.iter().map(|&v| v as f32).collect()
    }

    fn wake(&mut self, i: usize) {
        if !self.awake[i] && self.alive[i] {
            self.awake[i] = true;
            self.active.push(i as u32);
        }
        self.still[i] = 0;
    }

    /// Recomputes connected parts over live springs and ties; the largest part of the anchor
    /// region keeps its anchor springs, every other part floats free.
    fn update_topology(&mut self) {
        let n = self.x.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(p: &mut [u32], mut i: u32) -> u32 {
            while p[i as usize] != i {
                p[i as usize] = p[p[i as usize] as usize];
                i = p[i as usize];
            }
            i
        }
        let union = |p: &mut Vec<u32>, a: u32, b: u32| {
            let (ra, rb) = (find(p, a), find(p, b));
            if ra != rb {
                let (lo, hi) = (ra.min(rb), ra.max(rb));
                p[hi as usize] = lo;
            }
        };
        for (k, s) in self.stretch.iter().enumerate() {
            if self.stretch_alive[k] {
                union(&mut parent, s.a, s.b);
            }
        }
        for t in &self.ties {
            if t.alive {
                union(&mut parent, t.a, t.b);
            }
        }
        let mut count = vec![0u32; n];
        for i in 0..n {
            let r = find(&mut parent, i as u32);
            self.component[i] = r;
            if self.alive[i] && self.region[i] == self.anchor_region {
                count[r as usize] += 1;
            }
        }
        // The part holding most of the anchor region; none if that region has no live point.
        let main = (0..n)
            .max_by_key(|&r| (count[r], std::cmp::Reverse(r)))
            .filter(|&r| count[r] > 0)
            .map_or(u32::MAX, |r| r as u32);
        for i in 0..n {
            let anchored = self.alive[i] && self.component[i] == main;
            if self.anchored[i] && !anchored {
                self.wake(i);
            }
            self.anchored[i] = anchored;
        }
        self.regroup_free_parts();
        self.regroup_pressure();
        self.topology_dirty = false;
    }

    /// Lists the live parts that float free (not anchored), in order of their first point.
    fn regroup_free_parts(&mut self) {
        let n = self.x.len();
        let mut parts: Vec<FreePart> = Vec::new();
        let mut by_component: Vec<(u32, u32)> = Vec::new();
        self.part_of.fill(NO_GROUP);
        for i in 0..n {
            if !self.alive[i] || self.anchored[i] {
                continue;
            }
            let c = self.component[i];
            let k = match by_component.binary_search_by(|e| e.0.cmp(&c)) {
                Ok(k) => by_component[k].1,
                Err(k) => {
                    let id = parts.len() as u32;
                    by_component.insert(k, (c, id));
                    parts.push(FreePart::default());
                    id
                }
            };
            parts[k as usize].points.push(i as u32);
            self.part_of[i] = k;
        }
        for part in &mut parts {
            let rest = &self.mesh.rest;
            let count = part.points.len().max(1) as f32;
            let centre = part.points.iter().map(|&i| rest[i as usize]).sum::<Vec3>() / count;
            part.radius_m = part
                .points
                .iter()
                .map(|&i| (rest[i as usize] - centre).length())
                .fold(0.0, f32::max);
            let (q, t) = self.fit_part(part);
            (part.rotation, part.translation) = (q, t);
        }
        self.free_parts = parts;
    }

    /// The best rigid motion of a free piece from rest (Mueller et al.'s 2005 shape matching),
    /// as x = rotation * rest + translation: fitted to the held points when a grasper holds
    /// three or more of them (the instrument carries the piece), else to all its points.
    fn fit_part(&self, part: &FreePart) -> (Quat, Vec3) {
        let rest = &self.mesh.rest;
        let held: Vec<u32> = part
            .points
            .iter()
            .copied()
            .filter(|&i| self.kinematic[i as usize])
            .collect();
        let fit: &[u32] = if held.len() >= 3 { &held } else { &part.points };
        let count = fit.len().max(1) as f32;
        let c: Vec3 = fit.iter().map(|&i| self.x[i as usize]).sum::<Vec3>() / count;
        let c0: Vec3 = fit.iter().map(|&i| rest[i as usize]).sum::<Vec3>() / count;
        let mut a = glam::Mat3::ZERO;
        for &i in fit {
            let (p, q) = (self.x[i as usize] - c, rest[i as usize] - c0);
            a += glam::Mat3::from_cols(p * q.x, p * q.y, p * q.z);
        }
        let q = extract_rotation(a, part.rotation);
        (q, c - q * c0)
    }

    /// Moves each free piece's spring goals with the piece's fitted motion, so a cut-out
    /// specimen keeps its shape and follows the grasper instead of stretching out of its
    /// jaws. Sleeping points of the piece ride along rigidly (they stay asleep; only points
    /// disturbed relative to the piece wake), which keeps a carried specimen cheap.
    fn match_free_parts(&mut self) {
        for k in 0..self.free_parts.len() {
            let part = &self.free_parts[k];
            let busy = part
                .points
                .iter()
                .any(|&i| self.awake[i as usize] || self.kinematic[i as usize]);
            if !busy {
                continue;
            }
            let (q, t) = self.fit_part(part);
            let (q0, t0) = (part.rotation, part.translation);
            let radius = part.radius_m;
            let change = (t - t0).length() + q.angle_between(q0) * radius;
            if change <= 1e-9 {
                continue;
            }
            let delta = q * q0.inverse();
            // Leaves are padded by the BVH margin: refresh the piece's leaves only when it has
            // moved half of that since they were last fitted.
            let drift = self.free_parts[k].bvh_drift_m + change;
            let refit = drift > 0.5 * BVH_MARGIN_M;
            self.free_parts[k].bvh_drift_m = if refit { 0.0 } else { drift };
            let points = std::mem::take(&mut self.free_parts[k].points);
            for &i in &points {
                let i = i as usize;
                if !self.awake[i] {
                    // Rigidly carried: position, normal and volume term move with the piece.
                    let carried = delta * (self.x[i] - t0) + t;
                    self.x[i] = carried;
                    self.sleep_at[i] = carried;
                    self.normal[i] = delta * self.normal[i];
                    let term = if self.alive[i] {
                        carried.dot(self.normal[i]) * self.area[i] / 3.0
                    } else {
                        0.0
                    };
                    if let Some(v) = self.volume.get_mut(self.pressure_group[i] as usize) {
                        *v += (term - self.volume_term[i]) as f64;
                    }
                    self.volume_term[i] = term;
                }
                if refit {
                    self.bvh_pending.push(i as u32);
                }
            }
            let part = &mut self.free_parts[k];
            part.points = points;
            part.rotation = q;
            part.translation = t;
        }
    }

    /// Sorts the points into pressure groups: one per (connected part, region). A closed part
    /// encloses a volume whatever its pose; an open part (cut) only while it is anchored in
    /// place, so a cut-free open piece gets no internal pressure (its "volume" would change
    /// as it moves, pumping energy into it). Rest volumes are taken over what is left, at
    /// rest, so the pressure starts from zero.
    fn regroup_pressure(&mut self) {
        let n = self.x.len();
        let mut key_to_group: Vec<((u32, u8), u32)> = Vec::new();
        let mut closed: Vec<bool> = Vec::new();
        let mut anchored: Vec<bool> = Vec::new();
        let mut group = vec![NO_GROUP; n];
        for i in 0..n {
            if !self.alive[i] {
                continue;
            }
            let key = (self.component[i], self.region[i]);
            let g = match key_to_group.binary_search_by(|e| e.0.cmp(&key)) {
                Ok(k) => key_to_group[k].1,
                Err(k) => {
                    let g = closed.len() as u32;
                    key_to_group.insert(k, (key, g));
                    closed.push(true);
                    anchored.push(false);
                    g
                }
            };
            group[i] = g;
            let g = g as usize;
            anchored[g] |= self.anchored[i];
            closed[g] &= self.mesh.neighbors[i]
                .iter()
                .all(|&q| self.alive[q as usize]);
        }
        let mut rest_volume = vec![0.0f32; closed.len()];
        let rest = &self.mesh.rest;
        for i in 0..n {
            let g = group[i];
            if g == NO_GROUP {
                continue;
            }
            if !(closed[g as usize] || anchored[g as usize]) {
                group[i] = NO_GROUP;
                continue;
            }
            let (nn, a) = self.mesh.normal_area(rest, &self.alive, i);
            rest_volume[g as usize] += rest[i].dot(nn) * a / 3.0;
        }
        self.pressure_group = group;
        self.rest_volume = rest_volume;
        // Volume terms are current; the sums start again over the new groups.
        self.volume.clear();
    }

    /// The spring force (eq 2) pulling point `i` to its goal: its rest position, or for a
    /// piece cut free, its rest position carried by the piece's motion. Zero for a free point
    /// of no piece.
    fn spring_pull(&self, i: usize) -> Vec3 {
        let k = self.params.spring_n_per_m;
        if self.anchored[i] {
            forces::spring_force(k, self.x[i], self.mesh.rest[i])
        } else if let Some(part) = self.free_parts.get(self.part_of[i] as usize) {
            let goal = part.rotation * self.mesh.rest[i] + part.translation;
            forces::spring_force(k, self.x[i], goal)
        } else {
            Vec3::ZERO
        }
    }

    fn next_stamp(&mut self) -> u32 {
        self.stamp_now = self.stamp_now.wrapping_add(1);
        if self.stamp_now == 0 {
            self.stamp.fill(0);
            self.stamp_now = 1;
        }
        self.stamp_now
    }

    fn apply_contacts(&mut self, contacts: &[Contact], out: &mut ModelOutput) {
        let p = self.params;
        let mut seen = [false; 2];
        for c in contacts {
            seen[c.tool.index()] = true;
            match c.kind {
                ContactKind::Press {
                    pressure_pa,
                    area_m2,
                } => {
                    let pressed = pressure_pa * area_m2;
                    let from = forces::offset_point(c.point, c.normal, p.offset_m);
                    // Beyond 2 falloff lengths the force is under a fifth of the peak: ignored.
                    let reach = 2.0 * p.falloff_m;
                    let q = Aabb::new(from - Vec3::splat(reach), from + Vec3::splat(reach));
                    let found: Vec<u32> = self.bvh.faces_in(&q).collect();
                    let mut total = Vec3::ZERO;
                    for f in found {
                        let i = f as usize;
                        if !self.alive[i] || (self.x[i] - from).length() > reach {
                            continue;
                        }
                        self.wake(i);
                        self.refresh_normal(i);
                        let cf = forces::contact_force(
                            self.x[i],
                            self.normal[i],
                            from,
                            pressed,
                            p.falloff_m,
                        );
                        self.force[i] += cf.pressure + cf.offset;
                        total += cf.pressure + cf.offset;
                        self.touched.push(i as u32);
                    }
                    out.reactions.push((c.tool, -total));
                }
                ContactKind::Sphere { radius_m } => {
                    let q = Aabb::new(
                        c.point - Vec3::splat(radius_m * 2.0),
                        c.point + Vec3::splat(radius_m * 2.0),
                    );
                    let found: Vec<u32> = self.bvh.faces_in(&q).collect();
                    for f in found {
                        if (self.x[f as usize] - c.point).length() < radius_m * 1.5 {
                            self.wake(f as usize);
                        }
                    }
                }
                ContactKind::Grasp { rotation, radius_m } => {
                    if let Some(h) = self.held.iter_mut().find(|h| h.tool == c.tool) {
                        h.rotation = rotation;
                        let (rot, pts) = (h.rotation, h.points.clone());
                        // The held tissue pulls the jaws back toward its rest (eq 2's springs;
                        // nothing once the piece is cut free and carried).
                        let mut pull = Vec3::ZERO;
                        for (i, local) in pts {
                            let target = c.point + rot * local;
                            let i = i as usize;
                            self.wake(i);
                            self.x[i] = target;
                            pull += self.spring_pull(i);
                        }
                        out.reactions.push((c.tool, pull));
                        continue;
                    }
                    let q = Aabb::new(
                        c.point - Vec3::splat(radius_m),
                        c.point + Vec3::splat(radius_m),
                    );
                    let mut found: Vec<(f32, u32)> = self
                        .bvh
                        .faces_in(&q)
                        .filter(|&f| self.alive[f as usize])
                        .map(|f| ((self.x[f as usize] - c.point).length(), f))
                        .filter(|&(d, _)| d <= radius_m)
                        .collect();
                    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    found.truncate(24);
                    if found.is_empty() {
                        continue;
                    }
                    let inv = rotation.inverse();
                    let points: Vec<(u32, Vec3)> = found
                        .iter()
                        .map(|&(_, f)| (f, inv * (self.x[f as usize] - c.point)))
                        .collect();
                    for &(f, _) in &points {
                        self.kinematic[f as usize] = true;
                        self.inv_mass[f as usize] = 0.0;
                        self.wake(f as usize);
                    }
                    out.events.push(EventKind::Grasp {
                        tool: c.tool.name().to_string(),
                        model: self.name.clone(),
                        vertices: points.len() as u32,
                    });
                    self.held.push(Held {
                        tool: c.tool,
                        points,
                        rotation,
                    });
                }
            }
        }
        // Release grasps whose tool sent no grasp this step.
        let mut k = 0;
        while k < self.held.len() {
            let tool = self.held[k].tool;
            let still = contacts
                .iter()
                .any(|c| c.tool == tool && matches!(c.kind, ContactKind::Grasp { .. }));
            if still {
                k += 1;
                continue;
            }
            let h = self.held.remove(k);
            for (i, _) in h.points {
                self.kinematic[i as usize] = false;
                self.inv_mass[i as usize] = if self.alive[i as usize] { 1.0 } else { 0.0 };
                self.wake(i as usize);
            }
            out.events.push(EventKind::Release {
                tool: tool.name().to_string(),
            });
        }
        for h in 0..2 {
            if seen[h] && !self.contacting[h] {
                out.events.push(EventKind::Contact {
                    tool: ToolId::BOTH[h].name().to_string(),
                    model: self.name.clone(),
                });
            }
            self.contacting[h] = seen[h];
        }
    }

    fn collect_constraints(&mut self) {
        self.constraints_now.clear();
        // Walk the awake points in index order (the active list is sorted) and list each live
        // constraint once: a fixed order whatever the order points woke in.
        for &i in &self.active {
            let (s, e) = (
                self.adj_start[i as usize] as usize,
                self.adj_start[i as usize + 1] as usize,
            );
            for &id in &self.adj[s..e] {
                let live = match self.kind(id) {
                    Constraint::Stretch(k) => self.stretch_alive[k as usize],
                    Constraint::Bend(k) => self.bend_alive[k as usize],
                    Constraint::Tie(k) => self.ties[k as usize].alive,
                };
                let (word, bit) = (id as usize / 64, 1u64 << (id % 64));
                if live && self.listed[word] & bit == 0 {
                    self.listed[word] |= bit;
                    self.constraints_now.push(id);
                }
            }
        }
        for &id in &self.constraints_now {
            self.listed[id as usize / 64] = 0;
        }
    }

    fn project(&mut self, dt: f32, out: &mut ModelOutput) {
        let p = self.params;
        let list = std::mem::take(&mut self.constraints_now);
        // One Lagrange multiplier per listed constraint, from zero each step.
        self.lambda.clear();
        self.lambda.resize(list.len(), 0.0);
        for _ in 0..p.solver_iterations.max(1) {
            for (li, &id) in list.iter().enumerate() {
                let l = self.lambda[li];
                let dl = match self.kind(id) {
                    Constraint::Stretch(k) => xpbd::project_stretch(
                        &mut self.x,
                        &self.inv_mass,
                        &self.stretch[k as usize],
                        p.stretch_compliance_m_per_n,
                        dt,
                        l,
                    ),
                    Constraint::Bend(k) => xpbd::project_bend(
                        &mut self.x,
                        &self.inv_mass,
                        &self.bend[k as usize],
                        p.bend_compliance_per_n_m,
                        dt,
                        l,
                    ),
                    Constraint::Tie(k) => {
                        let t = self.ties[k as usize];
                        xpbd::project_stretch(
                            &mut self.x,
                            &self.inv_mass,
                            &Stretch {
                                a: t.a,
                                b: t.b,
                                rest_m: t.rest_m,
                            },
                            p.tie_compliance_m_per_n,
                            dt,
                            l,
                        )
                    }
                };
                self.lambda[li] = l + dl;
            }
        }
        // Ties whose force exceeds the threshold tear.
        for (li, &id) in list.iter().enumerate() {
            if let Constraint::Tie(k) = self.kind(id) {
                let force = self.lambda[li].abs() / (dt * dt);
                if force > p.tie_break_force_n {
                    self.ties[k as usize].alive = false;
                    self.topology_dirty = true;
                    out.events.push(EventKind::TieBroken {
                        model: self.name.clone(),
                        force_n: force,
                    });
                }
            }
        }
        self.constraints_now = list;
    }
}

impl SoftBody {
    /// Heap bytes held by each part of the body (capacity, not length), for the profiler.
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let m = &self.mesh;
        let fans: usize = b(&m.fan_start) + b(&m.fan_faces);
        let render: usize = b(&m.render);
        vec![
            ("mesh.neighbors", b(&m.neighbors)),
            ("mesh.faces", b(&m.faces)),
            ("mesh.fans", fans),
            ("mesh.tri_rest", b(&m.tri_rest)),
            ("mesh.rest", b(&m.rest)),
            ("mesh.render", render),
            ("mesh.corners", b(&m.corners)),
            ("x", b(&self.x)),
            ("v", b(&self.v)),
            ("normal", b(&self.normal)),
            ("area+volume_term+inv_mass+leaf_pad", b(&self.area) * 4),
            (
                "flags",
                b(&self.alive) * 4 + b(&self.region) + b(&self.still),
            ),
            ("stretch", b(&self.stretch) + b(&self.stretch_alive)),
            ("bend", b(&self.bend) + b(&self.bend_alive)),
            ("adj", b(&self.adj_start) + b(&self.adj)),
            ("sleep_at", b(&self.sleep_at)),
            ("groups+parts+component+stamp", b(&self.pressure_group) * 4),
            ("bvh", self.bvh.heap_bytes()),
            ("checkpoint", b(&self.checkpoint.0) + b(&self.checkpoint.1)),
            (
                "force+pushed+before",
                b(&self.force) + b(&self.pushed) + b(&self.before),
            ),
            ("constraints_now", b(&self.constraints_now)),
            ("lambda+listed", b(&self.lambda) + b(&self.listed)),
            (
                "lists",
                b(&self.active)
                    + b(&self.touched)
                    + b(&self.moved)
                    + b(&self.pushed_list)
                    + b(&self.bvh_pending),
            ),
        ]
    }
}

impl TissueModel for SoftBody {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> &'static str {
        "simplex_soft_body"
    }

    fn sizes(&self) -> ModelSizes {
        ModelSizes {
            vertices: self.x.len(),
            triangles: self.mesh.faces.len(),
            constraints: self.stretch.len() + self.bend.len() + self.ties.len(),
        }
    }

    fn step(&mut self, dt: f32, contacts: &[Contact], out: &mut ModelOutput) {
        if self.topology_dirty {
            self.update_topology();
        }
        let p = self.params;
        self.apply_contacts(contacts, out);
        self.match_free_parts();
        // Normals and areas of every point whose neighbourhood may move (eq 3 needs them).
        self.active.sort_unstable();
        self.active.dedup();
        let stamp = self.next_stamp();
        self.moved.clear();
        for k in 0..self.active.len() {
            let i = self.active[k] as usize;
            for j in std::iter::once(i as u32).chain(self.mesh.neighbors[i]) {
                if self.stamp[j as usize] != stamp {
                    self.stamp[j as usize] = stamp;
                    self.moved.push(j);
                }
            }
        }
        let moved = std::mem::take(&mut self.moved);
        for &i in &moved {
            self.refresh_normal(i as usize);
        }
        let volumes = self.region_volumes();
        let pressure: Vec<f32> = volumes
            .iter()
            .zip(&self.rest_volume)
            .map(|(&v, &v0)| forces::volume_pressure(p.volume_stiffness_pa, v0, v))
            .collect();
        // Forces and explicit integration (eqs 1, 4, 5, 7, 8).
        self.before.clear();
        for k in 0..self.active.len() {
            let i = self.active[k] as usize;
            self.before.push(self.x[i]);
            if self.kinematic[i] || !self.alive[i] {
                self.v[i] = Vec3::ZERO;
                continue;
            }
            let mut f = self.force[i] + self.spring_pull(i);
            if let Some(&pg) = pressure.get(self.pressure_group[i] as usize) {
                f += forces::pressure_force(pg, self.normal[i], self.area[i]);
            }
            let (x, v) = forces::integrate(self.x[i], self.v[i], f, p.damping_per_s, dt);
            self.x[i] = x;
            self.v[i] = v;
        }
        for &i in &self.touched {
            self.force[i as usize] = Vec3::ZERO;
        }
        self.touched.clear();
        // Constraints (Algorithm 2), then the instrument tips as inequality constraints.
        self.collect_constraints();
        let n_active = self.active.len();
        self.project(dt, out);
        for c in contacts {
            if let ContactKind::Sphere { radius_m } = c.kind {
                let q = Aabb::new(
                    c.point - Vec3::splat(radius_m * 2.0),
                    c.point + Vec3::splat(radius_m * 2.0),
                );
                let found: Vec<u32> = self.bvh.faces_in(&q).collect();
                let mut held_back = Vec3::ZERO;
                for f in found {
                    let i = f as usize;
                    let d = self.x[i] - c.point;
                    let len = d.length();
                    if self.alive[i] && !self.kinematic[i] && len < radius_m {
                        // A point ahead of the tip's centre goes on ahead of it (to the
                        // sphere, along the way the tool points), so the tip tents the surface
                        // like a probe; pushed straight out from the centre, the points in
                        // front would slide aside and let the tip through between them. A
                        // point behind the centre is pushed straight out.
                        let ahead = -c.normal;
                        let along = d.dot(ahead);
                        let corr = if along >= 0.0 {
                            let t =
                                (along * along + radius_m * radius_m - len * len).sqrt() - along;
                            ahead * t
                        } else {
                            let dir = if len > 1e-9 { d / len } else { ahead };
                            dir * (radius_m - len)
                        };
                        self.x[i] += corr;
                        held_back += self.spring_pull(i);
                        if self.pushed[i] == Vec3::ZERO {
                            self.pushed_list.push(i as u32);
                        }
                        self.pushed[i] += corr;
                        self.wake(i);
                    }
                }
                // The tissue presses on the tip with the pull of the points the tip holds
                // away from their rest (eq 2's springs): it grows with depth and is gone the
                // moment the tip leaves the tissue. The share the dent's rim passes on through
                // the stretch constraints is left out. (The correction over dt^2 would
                // measure how fast the tip moves into the tissue, not how hard it presses.)
                out.reactions.push((c.tool, held_back));
            }
        }
        // Constraint corrections become velocity; points moved by neighbours wake up. A tip's
        // push moves tissue and stops it moving into the tip (an inelastic contact), but adds
        // no speed of its own: turned into velocity, the correction fights the bending
        // constraints and pumps energy into a free piece every step.
        for k in 0..n_active {
            let i = self.active[k] as usize;
            if self.alive[i] && !self.kinematic[i] {
                let push = self.pushed[i];
                let mut v = (self.x[i] - push - self.before[k]) / dt;
                // Inelastic contact: no speed left into the tip.
                let n = push.normalize_or_zero();
                v -= n * v.dot(n).min(0.0);
                self.v[i] = v;
            }
        }
        for &i in &self.pushed_list {
            self.pushed[i as usize] = Vec3::ZERO;
        }
        self.pushed_list.clear();
        let stamp2 = self.next_stamp();
        let list = std::mem::take(&mut self.constraints_now);
        for &id in &list {
            let pts: [u32; 4] = match self.kind(id) {
                Constraint::Stretch(k) => {
                    let s = self.stretch[k as usize];
                    [s.a, s.b, s.a, s.b]
                }
                Constraint::Bend(k) => {
                    let b = self.bend[k as usize];
                    [b.a, b.b, b.c, b.d]
                }
                Constraint::Tie(k) => {
                    let t = self.ties[k as usize];
                    [t.a, t.b, t.a, t.b]
                }
            };
            for q in pts {
                let q = q as usize;
                if !self.awake[q] && self.stamp[q] != stamp2 && self.alive[q] {
                    self.stamp[q] = stamp2;
                    if (self.x[q] - self.sleep_at[q]).length() > WAKE_DISTANCE_M {
                        self.wake(q);
                    } else {
                        self.x[q] = self.sleep_at[q];
                    }
                }
            }
        }
        self.constraints_now = list;
        // Sleep bookkeeping and velocity from the projected positions.
        let v_sleep = p.sleep_speed_m_per_s;
        let mut k = 0;
        while k < self.active.len() {
            let i = self.active[k] as usize;
            let resting =
                !self.anchored[i] || (self.x[i] - self.mesh.rest[i]).length() < SLEEP_DISTANCE_M;
            if !self.kinematic[i] && self.v[i].length() < v_sleep && resting {
                self.still[i] += 1;
            } else {
                self.still[i] = 0;
            }
            if self.still[i] >= SLEEP_STEPS || !self.alive[i] {
                self.awake[i] = false;
                self.v[i] = Vec3::ZERO;
                if self.anchored[i] {
                    self.x[i] = self.mesh.rest[i];
                }
                self.sleep_at[i] = self.x[i];
                self.still[i] = 0;
                self.active.swap_remove(k);
                continue;
            }
            k += 1;
        }
        // Refit the BVH where anything moved.
        let stamp3 = self.next_stamp();
        let mut leaves = std::mem::take(&mut self.touched);
        let pending = std::mem::take(&mut self.bvh_pending);
        for &i in moved.iter().chain(self.active.iter()).chain(pending.iter()) {
            if self.stamp[i as usize] != stamp3 {
                self.stamp[i as usize] = stamp3;
                leaves.push(i);
            }
        }
        for &i in &leaves {
            self.bvh.mark(i);
        }
        leaves.clear();
        self.touched = leaves;
        self.bvh_pending = pending;
        self.bvh_pending.clear();
        let (x, pad, nb, alive) = (&self.x, &self.leaf_pad, &self.mesh.neighbors, &self.alive);
        self.bvh
            .refresh(|f| alive[f].then(|| leaf_aabb(x, pad, nb, f)), BVH_MARGIN_M);
        self.moved = moved;
    }

    fn cut(&mut self, stroke: &CutStroke, out: &mut ModelOutput) {
        let mut severed = 0u32;
        let mut removed = 0u32;
        for &f in &stroke.faces {
            let i = f as usize;
            if i >= self.alive.len() || !self.alive[i] {
                continue;
            }
            removed += 1;
            self.alive[i] = false;
            self.inv_mass[i] = 0.0;
            if let Some(v) = self.volume.get_mut(self.pressure_group[i] as usize) {
                *v -= self.volume_term[i] as f64;
            }
            self.volume_term[i] = 0.0;
            self.bvh.remove_face(f);
            let (s, e) = (self.adj_start[i] as usize, self.adj_start[i + 1] as usize);
            for k in s..e {
                match self.kind(self.adj[k]) {
                    Constraint::Stretch(c) => self.stretch_alive[c as usize] = false,
                    Constraint::Bend(c) => self.bend_alive[c as usize] = false,
                    Constraint::Tie(c) => {
                        if self.ties[c as usize].alive {
                            self.ties[c as usize].alive = false;
                            severed += 1;
                        }
                    }
                }
            }
            for n in self.mesh.neighbors[i] {
                self.wake(n as usize);
            }
        }
        if removed > 0 {
            self.topology_dirty = true;
            // Ray casts read the render triangles, so they change with the cut itself, never
            // with whoever happens to take a snapshot.
            self.rebuild_render_runs();
        }
        if severed > 0 {
            out.events.push(EventKind::TiesSevered {
                model: self.name.clone(),
                count: severed,
            });
        }
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            mesh: &self.mesh,
            positions: &self.x,
            normals: &self.normal,
            alive: &self.alive,
            regions: &self.region,
            bvh: &self.bvh,
        }
    }

    fn render_mesh(&mut self) -> ModelSnapshot {
        let mut normals = vec![Vec3::ZERO; self.x.len()];
        self.mesh.vertex_normals(&self.x, &self.alive, &mut normals);
        let positions: Vec<Vec3> = (0..self.mesh.render.len())
            .map(|r| self.mesh.render_position(r, &self.x, &normals))
            .collect();
        let mut indices = Vec::with_capacity(self.mesh.faces.len() * 3);
        let mut regions = Vec::with_capacity(self.mesh.faces.len());
        for f in 0..self.mesh.faces.len() {
            if self.alive[f] {
                indices.extend_from_slice(&self.mesh.corners[f]);
                regions.push(self.region[f]);
            }
        }
        // Smooth render normals from the triangles.
        let mut rn = vec![Vec3::ZERO; positions.len()];
        for t in indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| positions[i as usize]);
            let n = (b - a).cross(c - a);
            for &i in t {
                rn[i as usize] += n;
            }
        }
        let cut_edge = (0..self.mesh.render.len())
            .map(|r| self.mesh.is_split(r))
            .collect();
        ModelSnapshot {
            name: self.name.clone(),
            cut_edge,
            positions,
            normals: rn.into_iter().map(Vec3::normalize_or_zero).collect(),
            indices,
            regions,
            // The procedure says what each region is.
            roles: Vec::new(),
        }
    }

    fn checkpoint(&mut self) {
        self.checkpoint.0.clone_from(&self.x);
        self.checkpoint.1.clone_from(&self.v);
    }

    fn restore(&mut self) {
        self.x.clone_from(&self.checkpoint.0);
        self.v.clone_from(&self.checkpoint.1);
        for i in 0..self.x.len() {
            self.refresh_normal(i);
        }
        self.resum_volumes();
        self.active.clear();
        self.awake.fill(false);
    }

    fn state_is_finite(&self) -> bool {
        self.moved
            .iter()
            .chain(self.active.iter())
            .all(|&i| self.x[i as usize].is_finite() && self.v[i as usize].is_finite())
    }

    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        for (x, v) in self.x.iter().zip(&self.v) {
            for c in x.to_array().into_iter().chain(v.to_array()) {
                h.write(c.to_bits());
            }
        }
        for (i, a) in self.alive.iter().enumerate() {
            if !a {
                h.write(i as u32);
            }
        }
        h.0
    }
}

/// FNV-1a over 32-bit words: stable across platforms and runs.
#[derive(Clone, Copy)]
pub struct Fnv(pub u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    pub fn write(&mut self, w: u32) {
        for b in w.to_le_bytes() {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x100_0000_01b3);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::icosphere;
    use crate::sim::Quarantine;

    fn ball(level: u32, radius: f32, at: Vec3) -> crate::mesh::TriMesh {
        let mut m = icosphere(level);
        for p in &mut m.positions {
            *p = at + *p * radius;
        }
        m
    }

    fn body_of(m: &crate::mesh::TriMesh, regions: Vec<u8>) -> SoftBody {
        let s = SimplexMesh::dual(m).expect("closed mesh");
        SoftBody::new("test", s, regions, SoftBodyParams::default())
    }

    /// The point farthest along `dir`.
    fn farthest(b: &SoftBody, dir: Vec3) -> usize {
        (0..b.mesh().len())
            .max_by(|&i, &j| b.x[i].dot(dir).total_cmp(&b.x[j].dot(dir)))
            .unwrap_or(0)
    }

    #[test]
    fn a_closed_band_of_cut_faces_splits_connectivity() {
        let m = ball(3, 0.03, Vec3::ZERO);
        let mut b = body_of(&m, vec![0; m.triangle_count()]);
        let north = farthest(&b, Vec3::Y);
        let south = farthest(&b, -Vec3::Y);
        b.refresh_topology();
        assert_eq!(b.components()[north], b.components()[south]);
        let band: Vec<u32> = (0..b.mesh().len() as u32)
            .filter(|&f| b.x[f as usize].y.abs() < 0.003)
            .collect();
        let mut out = ModelOutput::default();
        b.cut(
            &CutStroke {
                faces: band.clone(),
            },
            &mut out,
        );
        b.refresh_topology();
        assert_ne!(b.components()[north], b.components()[south]);
        // One half keeps its anchors, the other floats free.
        assert_ne!(b.is_anchored(north), b.is_anchored(south));
        assert!(band.iter().all(|&f| !b.alive()[f as usize]));
        // A cut that does not close the loop leaves one piece.
        let mut c = body_of(&m, vec![0; m.triangle_count()]);
        let open: Vec<u32> = band
            .iter()
            .copied()
            .filter(|&f| c.x[f as usize].x < 0.02)
            .collect();
        c.cut(&CutStroke { faces: open }, &mut out);
        c.refresh_topology();
        assert_eq!(c.components()[north], c.components()[south]);
    }

    /// Two balls tied by one tie; the second is moved rigidly by `stretch_m` and stepped once.
    fn tie_after_stretch(stretch_m: f32) -> bool {
        let mut m = ball(1, 0.01, Vec3::ZERO);
        let n0 = m.triangle_count();
        m.append(&ball(1, 0.01, Vec3::new(0.03, 0.0, 0.0)));
        let mut regions = vec![0u8; n0];
        regions.extend(std::iter::repeat_n(1u8, m.triangle_count() - n0));
        let mut b = body_of(&m, regions.clone());
        let (a, c) = {
            let x = b.positions();
            let a = (0..n0)
                .max_by(|&i, &j| x[i].x.total_cmp(&x[j].x))
                .unwrap_or(0);
            let c = (n0..x.len())
                .min_by(|&i, &j| x[i].x.total_cmp(&x[j].x))
                .unwrap_or(0);
            (a, c)
        };
        let rest = (b.positions()[a] - b.positions()[c]).length();
        b.set_ties(vec![Tie {
            a: a as u32,
            b: c as u32,
            rest_m: rest,
            alive: true,
        }]);
        for i in n0..b.positions().len() {
            let p = b.positions()[i] + Vec3::new(stretch_m, 0.0, 0.0);
            b.set_position(i, p);
        }
        let mut out = ModelOutput::default();
        b.step(0.002, &[], &mut out);
        let broke = out
            .events
            .iter()
            .any(|e| matches!(e, EventKind::TieBroken { .. }));
        assert_eq!(broke, !b.ties()[0].alive);
        b.ties()[0].alive
    }

    #[test]
    fn a_tie_breaks_at_its_threshold_and_not_below() {
        let p = SoftBodyParams::default();
        // XPBD, one iteration, unit masses: F = C / (2 dt^2 + compliance).
        let at_threshold =
            p.tie_break_force_n * (2.0 * 0.002f32 * 0.002 + p.tie_compliance_m_per_n);
        assert!(
            tie_after_stretch(0.9 * at_threshold),
            "tie broke below its threshold"
        );
        assert!(
            !tie_after_stretch(1.1 * at_threshold),
            "tie held above its threshold"
        );
    }

    #[test]
    fn an_injected_nan_is_quarantined_rolled_back_and_reported() {
        let m = ball(2, 0.02, Vec3::ZERO);
        let mut b = body_of(&m, vec![0; m.triangle_count()]);
        let mut guard = Quarantine::new(4);
        let mut out = ModelOutput::default();
        let press = [Contact {
            tool: ToolId::Right,
            point: Vec3::new(0.0, 0.0, 0.02),
            normal: Vec3::Z,
            kind: ContactKind::Press {
                pressure_pa: 1500.0,
                area_m2: 1e-4,
            },
        }];
        for step in 1..=8 {
            b.step(0.002, &press, &mut out);
            assert!(guard.after_step(&mut b, step).is_none());
        }
        let good = b.positions().to_vec();
        b.set_position(5, Vec3::new(f32::NAN, 0.0, 0.0));
        b.step(0.002, &press, &mut out);
        let event = guard.after_step(&mut b, 9);
        assert_eq!(
            event,
            Some(EventKind::Quarantined {
                model: "test".into(),
                restored_step: 8
            })
        );
        assert!(guard.is_frozen());
        assert!(b.positions().iter().all(|p| p.is_finite()));
        assert_eq!(b.positions(), &good[..]);
    }

    /// Every live face is found by a BVH query for the centre of its own box: each ancestor
    /// on its path must contain that point, which stale ancestors after a move do not.
    fn bvh_bounds_every_live_face(b: &SoftBody) -> bool {
        (0..b.mesh().len()).filter(|&f| b.alive()[f]).all(|f| {
            let c = b.leaf_aabb(f).center();
            let q = Aabb::new(c, c);
            b.bvh.faces_in(&q).any(|l| l as usize == f)
        })
    }

    #[test]
    fn the_bvh_follows_deformation_through_partial_and_full_refits() {
        let m = ball(3, 0.03, Vec3::ZERO);
        let mut b = body_of(&m, vec![0; m.triangle_count()]);
        let mut out = ModelOutput::default();
        let dt = 0.002;
        // A 4 mm tip pressed 6 mm into the top and dragged sideways: leaves grow past their
        // margin every step (partial refits).
        let top = b.positions()[farthest(&b, Vec3::Z)];
        let tip_at = |k: usize| {
            let s = k as f32 * dt;
            [Contact {
                tool: ToolId::Left,
                point: top + Vec3::new(0.02 * s, 0.0, 0.004 - (0.03 * s).min(0.006)),
                normal: Vec3::Z,
                kind: ContactKind::Sphere { radius_m: 0.004 },
            }]
        };
        for k in 0..300 {
            b.step(dt, &tip_at(k), &mut out);
            if k % 50 == 49 {
                assert!(bvh_bounds_every_live_face(&b), "step {k}");
            }
        }
        let moved = (0..b.mesh().len())
            .map(|i| (b.positions()[i] - b.mesh.rest[i]).length())
            .fold(0.0, f32::max);
        assert!(
            moved > 5.0 * BVH_MARGIN_M,
            "the tip moved the surface {moved} m"
        );
        // A cut removes leaves (whole-tree refit), then the drag goes on (partial again).
        let band: Vec<u32> = (0..b.mesh().len() as u32)
            .filter(|&f| b.x[f as usize].y.abs() < 0.002 && b.x[f as usize].x < 0.0)
            .collect();
        b.cut(&CutStroke { faces: band }, &mut out);
        for k in 300..400 {
            b.step(dt, &tip_at(k), &mut out);
        }
        assert!(bvh_bounds_every_live_face(&b));
        let removed = (0..b.mesh().len()).filter(|&f| !b.alive()[f]).count();
        assert!(removed > 0);
        let root = b.bvh.root_aabb();
        let listed: Vec<u32> = b.bvh.faces_in(&root).collect();
        assert!(
            listed.iter().any(|&f| !b.alive()[f as usize]),
            "a partly cut patch stays"
        );
        let whole = (0..b.mesh().len()).filter(|&f| b.alive()[f]).count();
        assert_eq!(
            listed.iter().filter(|&&f| b.alive()[f as usize]).count(),
            whole,
            "every live face is in the tree once"
        );
    }

    #[test]
    fn a_press_dents_the_surface_and_it_springs_back() {
        let m = ball(3, 0.03, Vec3::ZERO);
        let mut b = body_of(&m, vec![0; m.triangle_count()]);
        let top = farthest(&b, Vec3::Z);
        let z0 = b.positions()[top].z;
        let press = [Contact {
            tool: ToolId::Right,
            point: b.positions()[top],
            normal: Vec3::Z,
            kind: ContactKind::Press {
                pressure_pa: 1500.0,
                area_m2: 1e-4,
            },
        }];
        let mut out = ModelOutput::default();
        for _ in 0..500 {
            b.step(0.002, &press, &mut out);
        }
        let dent = z0 - b.positions()[top].z;
        // The membrane (1000 N/m edges) and the gas pressure share the load with the anchors.
        assert!(dent > 2e-5 && dent < 5e-3, "dent {dent}");
        for _ in 0..3000 {
            b.step(0.002, &[], &mut out);
        }
        assert!((b.positions()[top].z - z0).abs() < 1e-6);
        assert_eq!(b.awake_count(), 0, "everything settles and sleeps");
    }

    #[test]
    fn a_tip_feels_the_tissue_push_back_harder_the_deeper_it_presses() {
        // A 3 mm tip held at depths below the top of an anchored 3 cm ball, 0.6 s each: the
        // tissue tents ahead of it, and the reaction points out of the surface, is zero
        // before contact and after, and grows with depth (more points, each further).
        let m = ball(4, 0.03, Vec3::ZERO);
        let mut b = body_of(&m, vec![0; m.triangle_count()]);
        let top = b.positions()[farthest(&b, Vec3::Z)];
        let r = 0.003;
        let mut out = ModelOutput::default();
        let mut held = |b: &mut SoftBody, depth: f32| {
            let c = [Contact {
                tool: ToolId::Left,
                point: top + Vec3::Z * (r - depth),
                normal: Vec3::Z,
                kind: ContactKind::Sphere { radius_m: r },
            }];
            let mut f = Vec3::ZERO;
            for _ in 0..300 {
                out.clear();
                b.step(0.002, &c, &mut out);
                f = out.reactions.iter().map(|(_, f)| *f).sum();
            }
            f
        };
        assert_eq!(held(&mut b, -0.0005), Vec3::ZERO, "half a millimetre above");
        let forces: Vec<Vec3> = [0.0005, 0.001, 0.002, 0.003]
            .iter()
            .map(|&d| held(&mut b, d))
            .collect();
        for w in forces.windows(2) {
            assert!(w[1].length() > w[0].length(), "{forces:?}");
        }
        for f in &forces {
            // Out of the surface, give or take the mesh's unevenness under a 3 mm tip.
            assert!(f.z > 0.8 * f.length(), "{f} points out of the surface");
        }
        assert!(forces[3].length() > 3.0 * forces[1].length(), "{forces:?}");
        assert_eq!(held(&mut b, -0.02), Vec3::ZERO, "withdrawn");
    }

    #[test]
    fn a_free_ball_pushed_by_a_tip_stays_whole() {
        // A free tumour-sized ball (no anchor region) shoved by a 3 mm tip at 9 cm/s.
        let m = ball(5, 0.02, Vec3::ZERO);
        let mut b = body_of(&m, vec![1; m.triangle_count()]);
        let params = SoftBodyParams {
            spring_n_per_m: 120.0,
            damping_per_s: 10.0,
            volume_stiffness_pa: 4000.0,
            ..SoftBodyParams::default()
        };
        b.params = params;
        let mut out = ModelOutput::default();
        let mut worst = 0.0f32;
        let dt = 0.002;
        for k in 0..800 {
            let depth = (k as f32 * dt * 0.09).min(0.012);
            let tip = Vec3::new(0.0, 0.0, 0.02 + 0.003 - depth);
            let c = [Contact {
                tool: ToolId::Left,
                point: tip,
                normal: Vec3::Z,
                kind: ContactKind::Sphere { radius_m: 0.003 },
            }];
            b.step(dt, &c, &mut out);
            let v = b.v.iter().map(|v| v.length()).fold(0.0, f32::max);
            worst = worst.max(v);
        }
        assert!(b.state_is_finite());
        assert!(worst < 0.5, "fastest point {worst} m/s");
    }

    #[test]
    fn a_grasped_free_piece_follows_the_grasper_and_keeps_its_shape() {
        let m = ball(4, 0.02, Vec3::ZERO);
        let mut b = body_of(&m, vec![1; m.triangle_count()]);
        let top = farthest(&b, Vec3::Z);
        let grip = b.positions()[top];
        let rest_centre: Vec3 = b.positions().iter().sum::<Vec3>() / b.mesh().len() as f32;
        let mut out = ModelOutput::default();
        let dt = 0.002;
        // Grip, then lift 4 cm in 1 s and hold for 1 s.
        for k in 0..1000 {
            let lift = (k as f32 * dt).min(1.0) * 0.04;
            let c = [Contact {
                tool: ToolId::Left,
                point: grip + Vec3::Z * lift,
                normal: Vec3::Z,
                kind: ContactKind::Grasp {
                    rotation: Quat::IDENTITY,
                    radius_m: 0.006,
                },
            }];
            b.step(dt, &c, &mut out);
        }
        assert!(b.state_is_finite());
        let centre: Vec3 = b.positions().iter().sum::<Vec3>() / b.mesh().len() as f32;
        let rise = centre.z - rest_centre.z;
        assert!((rise - 0.04).abs() < 0.004, "centre rose {rise} m of 0.04");
        // Still a ball: every point within 10 % of the radius from the centre.
        let worst = b
            .positions()
            .iter()
            .map(|p| ((*p - centre).length() - 0.02).abs())
            .fold(0.0, f32::max);
        assert!(worst < 0.002, "shape error {worst} m");
    }
}
