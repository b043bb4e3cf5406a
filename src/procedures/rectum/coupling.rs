//! The couplings of the rectum's world: what joins the rod (stage 0) and the membrane
//! (stage 1) within a step, and the instruments' contact with both.
//!
//! Before the rod steps: the graspers hold (or take, or let go of) the rectum's surface and
//! the hook presses the rod's bounding spheres. Before the membrane steps: the tiles near
//! each instrument wake, the skin places layer 0's targets from the rod's new pose where the
//! membrane's step needs them, the hook presses the awake nodes and, with its current on,
//! cuts the dissection plane, the alarms are raised, and the membrane's load on layer 0 is
//! handed to the rod for its next step (what the rod's present pose asks of the membrane).

use super::anatomy::Anatomy;
use super::regions::{self, RegionId, RegionKind};
use super::scene::{
    ALARM_RECTAL_WALL, MEMBRANE, ROD, RectumModel, SceneParams, StepOutcome, ToolState,
};
use crate::collision::{Instrument, PointCloud, ToolContact, VertexAreas, penalty_forces};
use crate::models::cosserat::skin::{Selection, Skin};
use crate::models::cosserat::skinned::SkinnedRod;
use crate::models::membrane::{LAYERS, Membrane};
use crate::sim::{Couplings, EventKind, Models, Phase};
use glam::Vec3;

/// The skin, the regions and what the couplings keep between steps.
pub(super) struct Joints {
    params: SceneParams,
    /// Layer 0's nodes bound to the rod.
    pub(super) skin: Skin,
    /// Each node's area, m^2 (mass over density and thickness).
    area: Vec<f32>,
    /// Each node's region (0: none).
    pub(super) regions: Vec<RegionId>,
    /// Last step's touching bits and wall-cut state (alarms fire on a change to touching).
    touching: u32,
    cutting_wall: bool,
    /// This step's: vulnerable regions touched, and whether the hook touches layer 0.
    touched_now: u32,
    on_wall: bool,
    pub(super) near_vulnerable: Option<(RegionId, f32)>,
    /// Plane springs in the target, and of them cut so far.
    pub(super) target_links: u32,
    pub(super) target_cut: u32,
    /// The grid cells (`i * cols + j`) whose plane springs the last step cut.
    pub(super) last_cut: Vec<u32>,
    /// This step's instruments, and what the step did (read back by the scene).
    tools: ToolState,
    hook: Option<Instrument>,
    pub(super) out: StepOutcome,
    // Scratch, reused every step.
    pub(super) nodes: Vec<u32>,
    points: Vec<Vec3>,
    areas: Vec<f32>,
    pub(super) contacts: Vec<ToolContact>,
    forces: Vec<(u32, Vec3)>,
    targets: Vec<Vec3>,
    loads: Vec<(u32, u32, Vec3)>,
    /// Layer 0's anchor stiffness per node (row-major), N/m: cuts never change it (they take
    /// links 1-2 only).
    anchor_k: Vec<f32>,
    tiles: Vec<usize>,
}

impl Joints {
    pub(super) fn new(
        anatomy: &Anatomy,
        rod: &SkinnedRod,
        membrane: &Membrane,
        params: SceneParams,
    ) -> Joints {
        let skin = Skin::bind(rod, &anatomy.membrane.positions[0]);
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
        Joints {
            params,
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
            tools: ToolState {
                hook: None,
                cutting: false,
                grasper: None,
                grasper_right: None,
            },
            hook: None,
            out: StepOutcome::default(),
            nodes: Vec::new(),
            points: Vec::new(),
            areas: Vec::new(),
            contacts: Vec::new(),
            forces: Vec::new(),
            targets: Vec::new(),
            loads: Vec::new(),
            anchor_k,
            tiles: Vec::new(),
        }
    }

    /// A new step with `tools`.
    pub(super) fn begin(&mut self, tools: ToolState) {
        self.tools = tools;
        self.hook = tools
            .hook
            .and_then(|(tip, q)| Instrument::l_hook(tip, q).ok());
        self.out = StepOutcome::default();
    }

    /// Before the rod steps: the graspers and the hook on the rod.
    fn on_rod(&mut self, rod: &mut SkinnedRod) {
        let tools = self.tools;
        for (hand, g) in [tools.grasper, tools.grasper_right].into_iter().enumerate() {
            match g {
                Some((jaw, _, true)) => {
                    if rod.grip(hand).is_none() {
                        rod.grasp(hand, jaw);
                    }
                    rod.hold(hand, jaw);
                }
                _ => rod.release(hand),
            }
        }
        if let Some(h) = &self.hook {
            self.out.hook_n += rod.press(h, 1);
        }
    }

    /// Before the membrane steps: wake, targets, the hook's press and cut, the alarms.
    fn on_membrane(&mut self, rod: &SkinnedRod, membrane: &mut Membrane) {
        let tools = self.tools;
        let hook = self.hook.clone();
        let mut boxes = Vec::new();
        if let (Some(h), Some((tip, _))) = (&hook, tools.hook) {
            boxes.push(self.wake_box(h, tip));
        }
        for (jaw, q, _) in [tools.grasper, tools.grasper_right].into_iter().flatten() {
            if let Ok(g) = Instrument::grasper(jaw, q, 0.0) {
                boxes.push(self.wake_box(&g, jaw));
            }
        }
        membrane.wake_near(&boxes);
        let needed = membrane.tiles_needing_targets(false);
        {
            let _span = tracing::debug_span!("rectum_targets", tiles = needed.len()).entered();
            self.place_targets(rod, membrane, &needed);
        }
        self.touched_now = 0;
        self.on_wall = false;
        self.near_vulnerable = None;
        if let Some(h) = &hook {
            let _span = tracing::debug_span!("rectum_press").entered();
            let f = self.press_membrane(membrane, h);
            self.out.hook_n += f;
            self.out.hook_contacts = self.contacts.len();
            if tools.cutting
                && let Some(end) = h.cylinders().get(1).map(|c| c.p1())
            {
                self.out.cut =
                    membrane.cut_plane_into(end, self.params.cut_radius_m, &mut self.last_cut);
            } else {
                self.last_cut.clear();
            }
        } else {
            self.last_cut.clear();
        }
        let per = membrane.rows() * membrane.cols();
        let out = &mut self.out;
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
    }

    /// Sets layer 0's targets on tiles `tiles` from the rod's skin.
    pub(super) fn place_targets(
        &mut self,
        rod: &SkinnedRod,
        membrane: &mut Membrane,
        tiles: &[usize],
    ) {
        let cols = membrane.cols();
        self.nodes.clear();
        for &t in tiles {
            let ([r0, r1], [c0, c1]) = membrane.tile_span(t);
            for i in r0..r1 {
                self.nodes.extend((c0..c1).map(|j| (i * cols + j) as u32));
            }
        }
        self.targets.resize(self.nodes.len(), Vec3::ZERO);
        if self
            .skin
            .place(rod, Selection::List(&self.nodes), &mut self.targets)
            .is_ok()
        {
            for (&k, &p) in self.nodes.iter().zip(&self.targets) {
                let k = k as usize;
                membrane.set_target(k / cols, k % cols, p);
            }
        }
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

    /// The membrane loads the rod: what the rest of the membrane does to each awake layer-0
    /// node ([`Membrane::anchor_loads`]: at rest, what its attachment hands on) acts on the
    /// rod's surface where the skin binds the node, split onto the element's nodes with its
    /// couple ([`SkinnedRod::add_surface_force`]), in the next rod step. Sleeping tiles lie
    /// on their anchors at rest and load it with nothing. Returns the sum, N.
    pub(super) fn load_rod(&mut self, rod: &mut SkinnedRod, membrane: &mut Membrane) -> Vec3 {
        let _span = tracing::debug_span!("rectum_load_rod").entered();
        let cols = membrane.cols();
        let (tr, tc) = membrane.tiles();
        let awake: Vec<usize> = (0..tr * tc).filter(|&t| membrane.tile_awake(t)).collect();
        let mut loads = std::mem::take(&mut self.loads);
        membrane.anchor_loads(&awake, &mut loads);
        let x = rod.rod().positions().to_vec();
        let mut total = glam::DVec3::ZERO;
        for &(i, j, f) in &loads {
            let (i, j) = (i as usize, j as usize);
            let (Some((target, _)), Some((e, u, _))) =
                (membrane.anchor_pull(i, j), self.skin.binding(i * cols + j))
            else {
                continue;
            };
            let (Some(a), Some(b)) = (x.get(e), x.get(e + 1)) else {
                continue;
            };
            let u = f64::from(u);
            let axis = *a + (*b - *a) * u;
            let f = f.as_dvec3();
            let k = f64::from(self.anchor_k[i * cols + j]);
            rod.add_surface_force(e, u, target.as_dvec3() - axis, f, k);
            total += f;
        }
        self.loads = loads;
        total.as_vec3()
    }

    /// The nodes of tiles `tiles` (all layers) with their positions and areas, into
    /// `nodes`, `points` and `areas`.
    fn gather(&mut self, m: &Membrane, tiles: &[usize]) {
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

    /// The hook against the nodes of the awake tiles whose boxes reach its own (the broad
    /// phase: the cost follows the hook's neighbourhood): penalty forces on the nodes, and
    /// the reaction on the hook. The nearest vulnerable node to the hook's end is looked for
    /// in the awake tiles within `near_m` of it (nearer is what the task measures).
    pub(super) fn press_membrane(&mut self, membrane: &mut Membrane, hook: &Instrument) -> Vec3 {
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for c in hook.cylinders() {
            let r = Vec3::splat(c.max_radius_m());
            lo = lo.min(c.p0().min(c.p1()) - r);
            hi = hi.max(c.p0().max(c.p1()) + r);
        }
        let mut tiles = std::mem::take(&mut self.tiles);
        membrane.awake_tiles_near(lo, hi, 0.0, &mut tiles);
        self.gather(membrane, &tiles);
        hook.contacts_all(PointCloud::from_points(&self.points), &mut self.contacts);
        // The nearest vulnerable node to the hook's end, among the awake ones near it.
        if let Some(end) = hook.cylinders().get(1).map(|c| c.p1()) {
            membrane.awake_tiles_near(end, end, self.params.near_m, &mut tiles);
            let m = &*membrane;
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
        let per = membrane.rows() * membrane.cols();
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
            membrane.add_force(node, f);
        }
        reaction.force_n
    }
}

impl Couplings<RectumModel> for Joints {
    fn couple(
        &mut self,
        phase: Phase,
        _dt_s: f32,
        models: &mut Models<'_, RectumModel>,
        _events: &mut Vec<EventKind>,
    ) {
        match phase.stage {
            0 => {
                if let Some(RectumModel::Rod(rod)) = models.get_mut(ROD) {
                    self.on_rod(rod);
                }
            }
            1 => {
                if let (Some(RectumModel::Membrane(m)), Some(RectumModel::Rod(rod))) =
                    models.write_read(MEMBRANE, ROD)
                {
                    self.on_membrane(rod, m);
                }
                // The membrane's load on the rod, for the rod's next step (before the
                // membrane moves: it is what the rod's present pose asks of it). A
                // quarantined membrane loads it with nothing.
                if let (Some(RectumModel::Rod(rod)), Some(RectumModel::Membrane(m))) =
                    models.pair_mut(ROD, MEMBRANE)
                {
                    self.out.membrane_on_rod_n = self.load_rod(rod, m);
                }
            }
            _ => {}
        }
    }
}
