//! The force-based soft body on a 2-simplex mesh (nephrectomy paper): each point with its real
//! mass is held to its rest shape by an elastic foundation (eq 2's spring per unit area, plus
//! a shear layer between neighbours), pushed by pressure and offset forces (eqs 3-6) and
//! damped (eq 5), integrated implicitly (see `implicit`); then XPBD stretch and dihedral
//! bending constraints (eqs 11-12) with the same masses; breakable ties between regions.
//!
//! Points at rest sleep: a point whose speed stayed below `sleep_speed_m_per_s` for
//! `SLEEP_TIME_S` seconds at its rest position is skipped until a contact, a constraint or a cut
//! wakes it. A sleeping point is exactly at rest, so skipping it changes nothing.

use super::forces;
use super::simplex::SimplexMesh;
use super::xpbd::{self, Bend, Stretch};
use crate::collision::FaceBvh;
use crate::sim::{
    Collider, Contact, ContactKind, CutStroke, EventKind, MeshSurface, ModelOutput, ModelSizes,
    ModelSnapshot, TissueModel, ToolId, TriangleSource,
};
use glam::{Quat, Vec3};
use parry3d::bounding_volume::Aabb;
use std::sync::{Arc, Mutex};

/// How long a point must stay slow and unloaded before it sleeps, s (a time, not a step
/// count, so that the awake set does not grow with a shorter step).
const SLEEP_TIME_S: f32 = 0.06;
/// An anchored point may sleep (and be put exactly at rest) only while doing so changes the
/// force its foundation and links exert by less than this, newtons: the shear layer carries
/// a load far from where it is applied, and snapping a loaded tail to rest would leak load
/// into sleeping points (a tool would feel less than the body bears).
const SLEEP_FORCE_N: f32 = 1e-5;
/// A point that belongs to no pressure group.
const NO_GROUP: u32 = u32::MAX;
/// A sleeping point nudged less than this by a constraint is put back and stays asleep, m.
const WAKE_DISTANCE_M: f32 = 1e-5;
/// BVH leaves are enlarged by this margin so that small motions need no refit, metres.
const BVH_MARGIN_M: f32 = 1e-3;
/// The fewest points one parallel task takes (normals, rest and load tests).
const POINTS_PER_TASK: usize = 1024;

/// `v` cut at the ascending offsets `cuts` (each at most `v.len()`).
fn split_at_offsets<'a, T>(mut v: &'a mut [T], cuts: &[u32]) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(cuts.len() + 1);
    let mut at = 0;
    for &c in cuts {
        let (head, tail) = v.split_at_mut(c as usize - at);
        out.push(head);
        v = tail;
        at = c as usize;
    }
    out.push(v);
    out
}

mod cg;
mod constraints;
mod contacts;
pub mod crater;
mod drawn;
mod implicit;
mod model;
mod params;
#[cfg(test)]
mod tests;
mod topology;

pub use crate::sim::Fnv;
pub use params::{SoftBodyParams, Tuning};

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
    /// The motion at the start of the previous step: with the current one, how fast a point
    /// carried by the piece moves (a point at rest on a moving piece may sleep).
    prev_rotation: Quat,
    prev_translation: Vec3,
}

impl Default for FreePart {
    fn default() -> Self {
        FreePart {
            points: Vec::new(),
            rotation: Quat::IDENTITY,
            translation: Vec3::ZERO,
            radius_m: 0.0,
            bvh_drift_m: 0.0,
            prev_rotation: Quat::IDENTITY,
            prev_translation: Vec3::ZERO,
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
    /// Shared with snapshots' jobs still building (a cut copies it while one holds it).
    mesh: Arc<SimplexMesh>,
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
    /// Each point's mass, kg, and its rest area, m^2.
    mass: Vec<f32>,
    rest_area: Vec<f32>,
    /// The largest rest area of any point, m^2.
    max_rest_area: f32,
    /// Per point: the shear layer's stiffness to each of its three neighbours (0: no link),
    /// N/m; the live ties per point (CSR); and the density and moduli the masses and links
    /// were built with.
    shear_k: Vec<[f32; 3]>,
    tie_start: Vec<u32>,
    tie_links: Vec<implicit::Link>,
    link_params: [f32; 3],
    /// Per point: 0, or 1 + the tool whose tip holds it this step.
    pinned: Vec<u8>,
    /// The points tips hold this step, and which tool holds each.
    pins: Vec<(u32, ToolId)>,
    /// Per point: its index among this step's unknowns (or `NO_GROUP`).
    slot: Vec<u32>,
    unknowns: Vec<u32>,
    /// The implicit step's system and solver vectors, kept to avoid allocating.
    cg: cg::CgSystem,
    /// Per pressure group: the pressure this step, Pa.
    pressure_now: Vec<f32>,
    /// The Lagrange multipliers from the last projection of the constraints on held points,
    /// (constraint, lambda) sorted by constraint, and that step's dt.
    constraint_lambda: Vec<(u32, f32)>,
    last_dt_s: f32,
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
    checkpoint: Vec<Vec3>,
    // Scratch, reused every step.
    stamp: Vec<u32>,
    stamp_now: u32,
    /// The external forces on points this step, (point, force) in the order applied.
    ext_force: Vec<(u32, Vec3)>,
    touched: Vec<u32>,
    /// The points the instrument tips pushed this step and how far (each point once).
    pushed: Vec<(u32, Vec3)>,
    constraints_now: Vec<u32>,
    moved: Vec<u32>,
    before: Vec<Vec3>,
    lambda: Vec<f32>,
    /// This step's blocks: block b holds the points `block_points[b]..block_points[b + 1]`,
    /// and the listed constraints `constraints_now[block_start[b]..block_start[b + 1]]` touch
    /// its points only; the last run of the list crosses blocks.
    block_points: [u32; constraints::BLOCKS + 1],
    block_start: [u32; constraints::BLOCKS + 2],
    /// The sleeping points this step's constraints touch (each once).
    fringe: Vec<u32>,
    /// Per awake point: at rest this step (the sleep test's scratch).
    at_rest: Vec<bool>,
    /// This step's constraints on held points: (constraint, its place in the list).
    held_slots: Vec<(u32, u32)>,
    /// Scratch: the normals and areas being refreshed.
    normal_scratch: Vec<(Vec3, f32)>,
    /// The normals the last snapshot drew, kept for the next (shared with the snapshot's
    /// job, which may build on another thread).
    drawn: Arc<Mutex<drawn::DrawnNormals>>,
    /// Points whose shear links a cut changed (refreshed with the topology).
    relink: Vec<u32>,
    /// Per region: the running sum of volume terms.
    volume: Vec<f64>,
    steps_since_resum: u32,
    contacting: [bool; 2],
    /// Never let a point sleep (benchmarks of the all-awake cost).
    stay_awake: bool,
    /// Cuts are made by an energy instrument: drawn seared (see `crater`).
    sear_cuts: bool,
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
            mass: vec![0.0; n],
            rest_area: vec![0.0; n],
            max_rest_area: 0.0,
            shear_k: Vec::new(),
            tie_start: Vec::new(),
            tie_links: Vec::new(),
            link_params: [0.0; 3],
            pinned: vec![0; n],
            pins: Vec::new(),
            slot: vec![NO_GROUP; n],
            unknowns: Vec::new(),
            cg: cg::CgSystem::default(),
            pressure_now: Vec::new(),
            constraint_lambda: Vec::new(),
            last_dt_s: 0.0,
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
            checkpoint: x.clone(),
            stamp: vec![0; n],
            stamp_now: 0,
            ext_force: Vec::new(),
            touched: Vec::new(),
            pushed: Vec::new(),
            constraints_now: Vec::new(),
            moved: Vec::new(),
            before: Vec::new(),
            lambda: Vec::new(),
            block_points: [0; constraints::BLOCKS + 1],
            block_start: [0; constraints::BLOCKS + 2],
            fringe: Vec::new(),
            at_rest: Vec::new(),
            held_slots: Vec::new(),
            relink: Vec::new(),
            normal_scratch: Vec::new(),
            drawn: Default::default(),
            volume: Vec::new(),
            steps_since_resum: 0,
            contacting: [false; 2],
            stay_awake: false,
            sear_cuts: false,
            x,
            mesh: Arc::new(mesh),
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
        body.compute_masses();
        body.rebuild_links();
        body
    }

    /// Adds breakable ties (e.g. tumour to its bed).
    /// Says that an energy instrument makes this body's cuts (a laser, a hook): their outlines
    /// are drawn seared.
    pub fn sear_cuts(&mut self, on: bool) {
        self.sear_cuts = on;
    }

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

    /// The normals kept for the next snapshot (a job building elsewhere holds them a while).
    fn drawn_normals(&self) -> std::sync::MutexGuard<'_, drawn::DrawnNormals> {
        self.drawn
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    pub fn positions(&self) -> &[Vec3] {
        &self.x
    }

    /// Changes the tunable parameters from the next step on (points at rest stay asleep:
    /// at rest none of these moves them).
    pub fn tune(&mut self, t: &Tuning) {
        t.apply(&mut self.params);
    }

    /// Each point's mass, kg.
    pub fn masses(&self) -> &[f32] {
        &self.mass
    }

    /// Each point's rest area, m^2.
    pub fn rest_areas(&self) -> &[f32] {
        &self.rest_area
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

    /// Brings the render runs up to date after the faces `removed` were cut: the runs around
    /// them, and around their neighbours (whose normals at rest changed), are made again.
    fn rebuild_render_runs(&mut self, removed: &[u32]) {
        let changed = self.mesh.vertices_around(removed);
        Arc::make_mut(&mut self.mesh).update_render(&self.alive, &changed);
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

    /// The points constraint `id` acts on (a two-point constraint names each twice).
    fn constraint_points(&self, id: u32) -> [u32; 4] {
        match self.kind(id) {
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
        self.set_normal(i, n, a);
    }

    /// Refreshes the normals and areas of the points `list`: computed in parallel, stored
    /// (and the volumes summed) in the list's order, so the bytes do not depend on threads.
    fn refresh_normals(&mut self, list: &[u32]) {
        use rayon::prelude::*;
        let mut found = std::mem::take(&mut self.normal_scratch);
        let (mesh, x, alive) = (&self.mesh, &self.x, &self.alive);
        list.par_iter()
            .with_min_len(POINTS_PER_TASK)
            .map(|&i| mesh.normal_area(x, alive, i as usize))
            .collect_into_vec(&mut found);
        for (&i, &(n, a)) in list.iter().zip(&found) {
            self.set_normal(i as usize, n, a);
        }
        self.normal_scratch = found;
    }

    /// Stores point `i`'s normal and area and brings its part's volume up to date.
    fn set_normal(&mut self, i: usize, n: Vec3, a: f32) {
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
}
