//! The rectum's models coupled in one step: the Cosserat rod (the bowel), the four-layer
//! membrane around it, the skin that carries the membrane's layer 0 on the rod, and the
//! instruments (an L-hook and a grasper) as generalized cylinders. This is the physics the
//! `rectum` procedure will step; it knows no input device, task or score.
//!
//! One step of `dt`:
//! 1. the grasper holds (or takes, or lets go of) the rectum's surface; the hook presses the
//!    rod's bounding spheres; the rod steps;
//! 2. layer 0's targets are placed by the skin where the next membrane step needs them (the
//!    awake tiles and those beside them);
//! 3. the membrane's tiles near each instrument wake; the hook's cylinders are tested against
//!    every node of the awake tiles (the paper's two-step test) and push them by penalty
//!    forces scaled by each node's area; with the cut button held, the dissection-plane
//!    springs inside a sphere at the hook's end are cut (eqs 5-6);
//! 4. the membrane advances in the explicit substeps its stability needs.
//!
//! The hook's reaction is the sum of what the rod and the membrane do to it.

use super::anatomy::Anatomy;
use super::regions::{self, RegionId, RegionKind};
use super::rod::{RectumRod, RectumRodParams, RodModelError};
use super::skin::{Selection, Skin};
use crate::collision::{Instrument, PointCloud, ToolContact, VertexAreas, penalty_forces};
use crate::models::membrane::{
    ActivityParams, Integrator, LAYERS, LayerMaterial, Membrane, MembraneError, MembraneParams,
};
use glam::{Quat, Vec3};

/// The membrane's tissues (documented choices; the paper gives no values):
/// - sheets (layer 0 on the bowel, layers 1-2 the visceral and parietal fasciae, layer 3 the
///   pelvic side): loose connective tissue, E = 5 kPa, 0.5 mm thick, 1000 kg/m^3. Dense
///   fascia is stiffer (MPa); at the paper's 0.25 mm spacing that would need 6 us explicit
///   steps (`docs/rectum.md`);
/// - links 1-2 and 3-4: mesorectal and presacral fat, E = 2 kPa (adipose tissue is 1-3 kPa in
///   indentation); links 2-3: the areolar tissue of the dissection plane, E = 1 kPa;
/// - damping: half of critical along the springs and 20/s at the nodes (tissue is strongly
///   damped); attachments 1e7 Pa/m (the pelvic wall is muscle on bone: 400 Pa of shear from
///   the fat moves it 40 um); eq 5's residual strain 0.1 (the paper's);
/// - no gravity: the anatomy is generated as it lies, carried by the body, and a sheet of
///   0.5 kg/m^2 on 2 kPa of fat 10 mm thick would sag 25 um, below what the active set
///   resolves (its wake distance is 0.2 mm), but enough to keep tiles from sleeping.
pub fn membrane_params() -> MembraneParams {
    let sheet = LayerMaterial {
        youngs_modulus_pa: 5e3,
        thickness_m: 5e-4,
        density_kg_per_m3: 1000.0,
    };
    MembraneParams {
        layers: [sheet; LAYERS],
        link_modulus_pa: [2e3, 1e3, 2e3],
        damping_per_s: 20.0,
        spring_damping_ratio: 0.5,
        attach_pa_per_m: 1e7,
        residual_strain: 0.1,
        gravity: Vec3::ZERO,
        integrator: Integrator::Symplectic,
    }
}

/// The scene's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneParams {
    pub membrane: MembraneParams,
    pub rod: RectumRodParams,
    pub activity: ActivityParams,
    /// The hook's penalty on membrane nodes, per unit of their area, Pa/m.
    pub hook_stiffness_pa_per_m: f32,
    /// Radius of the sphere at the hook's end whose plane springs a cut removes, m.
    pub cut_radius_m: f32,
    /// Explicit substeps at this fraction of the stability limit.
    pub substep_safety: f32,
    /// The part of each instrument that wakes tissue: this far up from its working end, m.
    pub wake_reach_m: f32,
    /// The dissection target: its rows as fractions of the section's length from the top,
    /// and its arc in degrees from the front towards +z ([`regions::Region`]).
    pub target_rows: (f32, f32),
    pub target_arc_deg: (f32, f32),
    /// How near the hook's end a vulnerable structure counts as near, m (the nearest one is
    /// looked for this far).
    pub near_m: f32,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            membrane: membrane_params(),
            // The rectum as generated lies where the body holds it: its weight is carried by
            // the mesorectum and the pelvic floor (the membrane's sleeping tiles, which load
            // the rod with nothing), so the rod is weightless here rather than sagging
            // between its clamps.
            rod: RectumRodParams {
                gravity_m_per_s2: glam::DVec3::ZERO,
                ..RectumRodParams::default()
            },
            activity: ActivityParams::default(),
            hook_stiffness_pa_per_m: 1e6,
            cut_radius_m: 1.5e-3,
            // The bound (stiffness and damping, Gershgorin's) is the grid's at rest; the
            // springs stretched under a grasp are no stiffer along and softer across.
            substep_safety: 0.9,
            wake_reach_m: 0.03,
            target_rows: regions::REGIONS[0].rows,
            target_arc_deg: regions::REGIONS[0].arc_deg,
            near_m: 0.005,
        }
    }
}

/// Why the scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("rectum: {0}")]
    Rod(#[from] RodModelError),
    #[error("membrane: {0}")]
    Membrane(#[from] MembraneError),
}

/// Where the instruments are this step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolState {
    /// The L-hook's corner (where the hook leaves the shaft) and orientation (forward -Z, the
    /// hook along +Y).
    pub hook: Option<(Vec3, Quat)>,
    /// The cut button (the hook's current) is held.
    pub cutting: bool,
    /// The left grasper's jaw point and orientation, and whether it is closed.
    pub grasper: Option<(Vec3, Quat, bool)>,
    /// The right hand's grasper when it holds one instead of the hook (the paper's test has
    /// two graspers and a hook): jaw point, orientation, closed.
    pub grasper_right: Option<(Vec3, Quat, bool)>,
}

/// What a step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepOutcome {
    /// Force of the tissue on the hook, on the left grasper and on the right one, N.
    pub hook_n: Vec3,
    pub grasper_n: Vec3,
    pub grasper_right_n: Vec3,
    /// Plane springs cut this step, and of them those inside the target.
    pub cut: u32,
    pub cut_in_target: u32,
    /// Membrane nodes the hook touches.
    pub hook_contacts: usize,
    /// Explicit membrane substeps taken.
    pub substeps: usize,
    /// The membrane's load on the rod through layer 0 (awake tiles), for the next step, N.
    pub membrane_on_rod_n: Vec3,
    /// Vulnerable regions the hook touches now: bit `id` for region id `id`
    /// ([`regions::REGIONS`]).
    pub touching: u32,
    /// The hook touches the rectal wall (layer 0).
    pub on_wall: bool,
    /// The vulnerable region nearest the hook's end among the awake nodes, and its distance, m.
    pub near_vulnerable: Option<(RegionId, f32)>,
    /// Alarms raised this step: bit `id` for a vulnerable region the hook has just touched,
    /// [`ALARM_RECTAL_WALL`] when the hook cuts with the rectum's wall (layer 0) under it.
    pub alarms: u32,
}

/// Alarm bit: the hook's current is on while it touches the rectum's wall (a perforation).
pub const ALARM_RECTAL_WALL: u32 = 1 << 7;

/// The rod, the membrane and the skin between them.
pub struct RectumScene {
    pub params: SceneParams,
    pub rod: RectumRod,
    pub membrane: Membrane,
    /// Layer 0's nodes bound to the rod.
    skin: Skin,
    /// Each node's area, m^2 (mass over density and thickness).
    area: Vec<f32>,
    /// Each node's region (0: none).
    regions: Vec<RegionId>,
    /// Last step's touching bits and wall-cut state (alarms fire on a change to touching).
    touching: u32,
    cutting_wall: bool,
    /// This step's: vulnerable regions touched, and whether the hook touches layer 0.
    touched_now: u32,
    on_wall: bool,
    near_vulnerable: Option<(RegionId, f32)>,
    /// Plane springs in the target, and of them cut so far.
    target_links: u32,
    target_cut: u32,
    /// The grid cells (`i * cols + j`) whose plane springs the last step cut.
    last_cut: Vec<u32>,
    /// Wall-clock seconds spent in the rod, the instruments' collision with the membrane,
    /// and the membrane's step (benchmarks only; never in state or reports).
    pub times: [f64; 3],
    // Scratch, reused every step.
    nodes: Vec<u32>,
    points: Vec<Vec3>,
    areas: Vec<f32>,
    contacts: Vec<ToolContact>,
    forces: Vec<(u32, Vec3)>,
    targets: Vec<Vec3>,
    loads: Vec<(u32, u32, Vec3)>,
    /// Layer 0's anchor stiffness per node (row-major), N/m: cuts never change it (they take
    /// links 1-2 only).
    anchor_k: Vec<f32>,
    tiles: Vec<usize>,
}

impl RectumScene {
    /// Builds the scene on the anatomy, the membrane at rest with its active set on.
    pub fn new(anatomy: &Anatomy, params: SceneParams) -> Result<RectumScene, SceneError> {
        let axis: Vec<Vec3> = anatomy.axis.iter().map(|f| f.point).collect();
        let rod = RectumRod::new(&axis, &anatomy.rectum, params.rod)?;
        let mut membrane = Membrane::new(anatomy.membrane.clone(), params.membrane)?;
        membrane.use_active_set(params.activity);
        let skin = Skin::bind(&rod, &anatomy.membrane.positions[0]);
        let (rows, cols) = (anatomy.membrane.rows, anatomy.membrane.cols);
        let regions =
            regions::map_for_target(rows, cols, params.target_rows, params.target_arc_deg);
        let target_links = (0..rows * cols)
            .filter(|&t| regions[rows * cols + t] == regions::TARGET)
            .count() as u32;
        let per = membrane.rows() * membrane.cols();
        let area = (0..membrane.len())
            .map(|n| {
                let m = &params.membrane.layers[n / per];
                membrane.mass(n) / (m.density_kg_per_m3 * m.thickness_m)
            })
            .collect();
        let anchor_k = (0..rows * cols)
            .map(|n| membrane.anchor_stiffness(n / cols, n % cols))
            .collect();
        Ok(RectumScene {
            params,
            rod,
            membrane,
            skin,
            area,
            regions,
            touching: 0,
            cutting_wall: false,
            touched_now: 0,
            on_wall: false,
            near_vulnerable: None,
            target_links,
            target_cut: 0,
            last_cut: Vec::new(),
            times: [0.0; 3],
            nodes: Vec::new(),
            points: Vec::new(),
            areas: Vec::new(),
            contacts: Vec::new(),
            forces: Vec::new(),
            targets: Vec::new(),
            loads: Vec::new(),
            anchor_k,
            tiles: Vec::new(),
        })
    }

    /// Sets layer 0's targets on tiles `tiles` from the rod's skin.
    fn place_targets(&mut self, tiles: &[usize]) {
        let cols = self.membrane.cols();
        self.nodes.clear();
        for &t in tiles {
            let ([r0, r1], [c0, c1]) = self.membrane.tile_span(t);
            for i in r0..r1 {
                self.nodes.extend((c0..c1).map(|j| (i * cols + j) as u32));
            }
        }
        self.targets.resize(self.nodes.len(), Vec3::ZERO);
        if self
            .skin
            .place(&self.rod, Selection::List(&self.nodes), &mut self.targets)
            .is_ok()
        {
            for (&k, &p) in self.nodes.iter().zip(&self.targets) {
                let k = k as usize;
                self.membrane.set_target(k / cols, k % cols, p);
            }
        }
    }

    /// Every node where the rod carries it now (before drawing the whole membrane).
    pub fn place_everything(&mut self) {
        let (tr, tc) = self.membrane.tiles();
        let all: Vec<usize> = (0..tr * tc).collect();
        self.place_targets(&all);
        self.membrane.place_sleeping();
    }

    /// The box around the part of `tool` within the wake reach of its working end `end`.
    fn wake_box(&self, tool: &Instrument, end: Vec3) -> (Vec3, Vec3) {
        let reach = self.params.wake_reach_m;
        let (mut lo, mut hi) = (end, end);
        for c in tool.cylinders() {
            let r = Vec3::splat(c.max_radius_m());
            for p in [c.p0(), c.p1()] {
                // Clip the segment to the ball of the reach around the end.
                let q = if p.distance(end) > reach {
                    end + (p - end).normalize_or_zero() * reach
                } else {
                    p
                };
                lo = lo.min(q - r);
                hi = hi.max(q + r);
            }
        }
        (lo, hi)
    }

    /// One step of `dt_s`.
    pub fn step(&mut self, dt_s: f32, tools: &ToolState) -> StepOutcome {
        let mut out = StepOutcome::default();
        let clock = std::time::Instant::now();
        // 1. The rod: graspers, hook, step.
        for (hand, g) in [tools.grasper, tools.grasper_right].into_iter().enumerate() {
            match g {
                Some((jaw, _, true)) => {
                    if self.rod.grip(hand).is_none() {
                        self.rod.grasp(hand, jaw);
                    }
                    self.rod.hold(hand, jaw);
                }
                _ => self.rod.release(hand),
            }
        }
        let hook = tools
            .hook
            .and_then(|(tip, q)| Instrument::l_hook(tip, q).ok());
        if let Some(h) = &hook {
            out.hook_n += self.rod.press(h, 1);
        }
        let held = self.rod.advance(f64::from(dt_s));
        if let Some(r) = held[0] {
            out.grasper_n = r;
        }
        if tools.grasper_right.is_some()
            && let Some(r) = held[1]
        {
            out.grasper_right_n = r;
        }
        let rod_done = clock.elapsed().as_secs_f64();
        // 2-3. Wake what the instruments reach, place the targets the step needs.
        let mut boxes = Vec::new();
        if let (Some(h), Some((tip, _))) = (&hook, tools.hook) {
            boxes.push(self.wake_box(h, tip));
        }
        for (jaw, q, _) in [tools.grasper, tools.grasper_right].into_iter().flatten() {
            if let Ok(g) = Instrument::grasper(jaw, q, 0.0) {
                boxes.push(self.wake_box(&g, jaw));
            }
        }
        self.membrane.wake_near(&boxes);
        let needed = self.membrane.tiles_needing_targets(false);
        self.place_targets(&needed);
        self.touched_now = 0;
        self.on_wall = false;
        self.near_vulnerable = None;
        if let Some(h) = &hook {
            out.hook_n += self.press_membrane(h);
            out.hook_contacts = self.contacts.len();
            if tools.cutting
                && let Some(end) = h.cylinders().get(1).map(|c| c.p1())
            {
                out.cut =
                    self.membrane
                        .cut_plane_into(end, self.params.cut_radius_m, &mut self.last_cut);
            } else {
                self.last_cut.clear();
            }
        } else {
            self.last_cut.clear();
        }
        let per = self.membrane.rows() * self.membrane.cols();
        out.cut_in_target = self
            .last_cut
            .iter()
            .filter(|&&t| self.regions[per + t as usize] == regions::TARGET)
            .count() as u32;
        self.target_cut += out.cut_in_target;
        // Alarms: a vulnerable region newly touched, the wall newly cut.
        out.touching = self.touched_now;
        out.on_wall = self.on_wall && hook.is_some();
        out.near_vulnerable = self.near_vulnerable;
        out.alarms = self.touched_now & !self.touching;
        let cutting_wall = tools.cutting && self.on_wall && hook.is_some();
        if cutting_wall && !self.cutting_wall {
            out.alarms |= ALARM_RECTAL_WALL;
        }
        self.touching = self.touched_now;
        self.cutting_wall = cutting_wall;
        // 4. The membrane.
        let collided = clock.elapsed().as_secs_f64();
        // The membrane's load on the rod, for the rod's next step (before the membrane moves:
        // it is what the rod's present pose asks of it).
        out.membrane_on_rod_n = self.load_rod();
        out.substeps = self.membrane.advance(dt_s, self.params.substep_safety);
        let done = clock.elapsed().as_secs_f64();
        self.times[0] += rod_done;
        self.times[1] += collided - rod_done;
        self.times[2] += done - collided;
        out
    }

    /// The membrane loads the rod: what the rest of the membrane does to each awake layer-0
    /// node ([`Membrane::anchor_loads`]: at rest, what its attachment hands on) acts on the
    /// rod's surface where the skin binds the node, split onto the element's nodes with its
    /// couple ([`RectumRod::add_surface_force`]), in the next rod step. Sleeping tiles lie
    /// on their anchors at rest and load it with nothing. Returns the sum, N.
    fn load_rod(&mut self) -> Vec3 {
        let cols = self.membrane.cols();
        let (tr, tc) = self.membrane.tiles();
        let awake: Vec<usize> = (0..tr * tc)
            .filter(|&t| self.membrane.tile_awake(t))
            .collect();
        let mut loads = std::mem::take(&mut self.loads);
        self.membrane.anchor_loads(&awake, &mut loads);
        let x = self.rod.rod().positions().to_vec();
        let mut total = glam::DVec3::ZERO;
        for &(i, j, f) in &loads {
            let (i, j) = (i as usize, j as usize);
            let (Some((target, _)), Some((e, u, _))) = (
                self.membrane.anchor_pull(i, j),
                self.skin.binding(i * cols + j),
            ) else {
                continue;
            };
            let (Some(a), Some(b)) = (x.get(e), x.get(e + 1)) else {
                continue;
            };
            let u = f64::from(u);
            let axis = *a + (*b - *a) * u;
            let f = f.as_dvec3();
            let k = f64::from(self.anchor_k[i * cols + j]);
            self.rod
                .add_surface_force(e, u, target.as_dvec3() - axis, f, k);
            total += f;
        }
        self.loads = loads;
        total.as_vec3()
    }

    /// Layer `l`'s nodes over the top (column 0, the front) of the section's middle row,
    /// `2 half + 1` rows by `2 half + 1` columns (for loads in tests and reference cases).
    pub fn top_patch(&self, l: usize, half: usize) -> Vec<usize> {
        let (rows, cols) = (self.membrane.rows(), self.membrane.cols());
        let mid = rows / 2;
        let (lo, hi) = (mid.saturating_sub(half), (mid + half).min(rows - 1));
        (lo..=hi)
            .flat_map(|i| (0..=2 * half).map(move |k| (i, (k + cols - half % cols) % cols)))
            .map(|(i, j)| self.membrane.node(l, i, j))
            .collect()
    }

    /// The nodes of tiles `tiles` (all layers) with their positions and areas, into
    /// `nodes`, `points` and `areas`.
    fn gather(&mut self, tiles: &[usize]) {
        let m = &self.membrane;
        self.nodes.clear();
        for &t in tiles {
            let ([r0, r1], [c0, c1]) = m.tile_span(t);
            for l in 0..LAYERS {
                for i in r0..r1 {
                    self.nodes.extend((c0..c1).map(|j| m.node(l, i, j) as u32));
                }
            }
        }
        self.points.clear();
        self.points
            .extend(self.nodes.iter().map(|&n| m.position(n as usize)));
        self.areas.clear();
        self.areas
            .extend(self.nodes.iter().map(|&n| self.area[n as usize]));
    }

    /// Plane springs in the target region, and of them cut so far.
    pub fn target_progress(&self) -> (u32, u32) {
        (self.target_cut, self.target_links)
    }

    /// The grid cells (`i * cols + j`) whose plane springs the last step cut.
    pub fn last_cut(&self) -> &[u32] {
        &self.last_cut
    }

    /// The region of membrane node `node` (0: none).
    pub fn region_of(&self, node: usize) -> RegionId {
        self.regions.get(node).copied().unwrap_or(0)
    }

    /// The hook against the nodes of the awake tiles whose boxes reach its own (the broad
    /// phase: the cost follows the hook's neighbourhood): penalty forces on the nodes, and
    /// the reaction on the hook. The nearest vulnerable node to the hook's end is looked for
    /// in the awake tiles within `near_m` of it (nearer is what the task measures).
    fn press_membrane(&mut self, hook: &Instrument) -> Vec3 {
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for c in hook.cylinders() {
            let r = Vec3::splat(c.max_radius_m());
            lo = lo.min(c.p0().min(c.p1()) - r);
            hi = hi.max(c.p0().max(c.p1()) + r);
        }
        let mut tiles = std::mem::take(&mut self.tiles);
        self.membrane.awake_tiles_near(lo, hi, 0.0, &mut tiles);
        self.gather(&tiles);
        hook.contacts_all(PointCloud::from_points(&self.points), &mut self.contacts);
        // The nearest vulnerable node to the hook's end, among the awake ones near it.
        if let Some(end) = hook.cylinders().get(1).map(|c| c.p1()) {
            self.membrane
                .awake_tiles_near(end, end, self.params.near_m, &mut tiles);
            let m = &self.membrane;
            for &t in &tiles {
                let ([r0, r1], [c0, c1]) = m.tile_span(t);
                for l in 0..LAYERS {
                    for i in r0..r1 {
                        for j in c0..c1 {
                            let n = m.node(l, i, j);
                            let id = self.regions[n];
                            if regions::region(id).is_some_and(|r| r.kind == RegionKind::Vulnerable)
                            {
                                let d = m.position(n).distance(end);
                                if self.near_vulnerable.is_none_or(|(_, best)| d < best) {
                                    self.near_vulnerable = Some((id, d));
                                }
                            }
                        }
                    }
                }
            }
        }
        self.tiles = tiles;
        let about = hook.cylinders().first().map_or(Vec3::ZERO, |c| c.p1());
        let Ok(reaction) = penalty_forces(
            &self.contacts,
            VertexAreas::PerVertex(&self.areas),
            self.params.hook_stiffness_pa_per_m,
            about,
            &mut self.forces,
        ) else {
            return Vec3::ZERO;
        };
        let per = self.membrane.rows() * self.membrane.cols();
        for c in &self.contacts {
            let node = self.nodes[c.vertex as usize] as usize;
            let id = self.regions[node];
            if regions::region(id).is_some_and(|r| r.kind == RegionKind::Vulnerable) {
                self.touched_now |= 1 << id;
            }
            self.on_wall |= node < per;
        }
        for &(k, f) in &self.forces {
            let node = self.nodes[k as usize] as usize;
            self.membrane.add_force(node, f);
        }
        reaction.force_n
    }
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
