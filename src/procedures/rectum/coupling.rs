//! The couplings of the rectum's world: what joins the rod (stage 0) and the membrane
//! (stage 1) within a step, and the instruments' contact with both.
//!
//! Before the rod steps: the graspers hold (or take, or let go of) the rectum's surface and
//! the hook presses the rod's bounding spheres. Before the membrane steps: the tiles near
//! each instrument wake, the rod's new pose goes to the membrane (whose chain, the skin's
//! bindings, places layer 0's targets from it where its step needs them), the hook presses
//! the awake nodes and, with its current on, cuts the dissection plane and the alarms are
//! raised. The membrane sums its load on layer
//! 0 by the rod's element each node is bound to, at the start of its step (what the rod's
//! present pose asks of it); before the next rod step the sums load the rod.

use super::anatomy::Anatomy;
use super::regions::{self, RegionId, RegionKind};
use super::scene::{
    ALARM_RECTAL_WALL, MEMBRANE, ROD, RectumModel, SceneParams, StepOutcome, ToolState,
};
use crate::collision::{
    Instrument, PointBlocks, PointCloud, ToolContact, VertexAreas, penalty_forces,
};
use crate::models::cosserat::skin::{RodPose, Skin};
use crate::models::cosserat::skinned::SkinnedRod;
use crate::models::membrane::{ChainBinding, LAYERS, Membrane, MembraneError};
use crate::sim::{Couplings, EventKind, Models, Phase};
use glam::Vec3;

/// The skin, the regions and what the couplings keep between steps.
pub(super) struct Joints {
    params: SceneParams,
    /// Layer 0's nodes bound to the rod (the membrane holds their bindings; tests read them
    /// here).
    #[cfg(test)]
    pub(super) skin: Skin,
    /// Each node's area, m^2 (mass over density and thickness).
    area: Vec<f32>,
    /// Each node's region (0: none).
    pub(super) regions: Vec<RegionId>,
    /// Per tile of the membrane's active set: whether it holds a node of a vulnerable
    /// region (the only tiles the search for the nearest one reads).
    vulnerable_tiles: Vec<bool>,
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
    /// The gathered nodes' coordinates, one vector per axis (the membrane's layout), and the
    /// broad phase's boxes over them.
    xyz: [Vec<f32>; 3],
    blocks: PointBlocks,
    areas: Vec<f32>,
    pub(super) contacts: Vec<ToolContact>,
    forces: Vec<(u32, Vec3)>,
    /// Each rod element's point, about which the membrane takes the moments of its loads
    /// (the element's middle at rest), m.
    about: Vec<Vec3>,
    tiles: Vec<usize>,
}

impl Joints {
    /// The couplings of `rod` and `membrane`: the skin bound, and the membrane's layer-0
    /// nodes grouped by the rod element they are bound to, for the loads.
    pub(super) fn new(
        anatomy: &Anatomy,
        rod: &SkinnedRod,
        membrane: &mut Membrane,
        params: SceneParams,
    ) -> Result<Joints, MembraneError> {
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
        let x = rod.rod().positions();
        let about: Vec<Vec3> = (0..x.len().saturating_sub(1))
            .map(|e| ((x[e] + x[e + 1]) * 0.5).as_vec3())
            .collect();
        let members: Vec<(usize, usize, usize, f32)> = (0..rows * cols)
            .filter_map(|n| {
                let (e, u, _) = skin.binding(n)?;
                let u = if u.is_finite() {
                    u.clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (e < about.len()).then_some((n / cols, n % cols, e, u))
            })
            .collect();
        membrane.group_anchor_loads(&members, &about)?;
        // The skin's bindings place layer 0's targets from the rod's pose, in the membrane
        // (on its device where it has one).
        let bound = (0..rows * cols)
            .map(|n| {
                let (segment, t, pair, w, offset) =
                    skin.frame_binding(n)
                        .unwrap_or((0, 0.0, 0, 0.0, Vec3::ZERO));
                ChainBinding {
                    segment,
                    t,
                    pair,
                    w,
                    offset,
                }
            })
            .collect();
        membrane.bind_targets(bound, skin.elements())?;
        let (tr, tc) = membrane.tiles();
        let mut vulnerable_tiles = vec![false; tr * tc];
        for (n, &id) in regions.iter().enumerate().take(membrane.len()) {
            if regions::region(id).is_some_and(|r| r.kind == RegionKind::Vulnerable) {
                let (_, i, j) = membrane.coords(n);
                if let Some(v) = vulnerable_tiles.get_mut(membrane.tile_of(i, j)) {
                    *v = true;
                }
            }
        }
        Ok(Joints {
            params,
            #[cfg(test)]
            skin,
            area,
            regions,
            vulnerable_tiles,
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
            xyz: Default::default(),
            blocks: PointBlocks::default(),
            areas: Vec::new(),
            contacts: Vec::new(),
            forces: Vec::new(),
            about,
            tiles: Vec::new(),
        })
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
        {
            let _span = tracing::debug_span!("rectum_targets").entered();
            Self::pose_targets(rod, membrane);
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

    /// Hands the rod's pose to the membrane, whose chain (the skin's bindings) places layer
    /// 0's targets from it where its step needs them. A pose that is not finite leaves the
    /// last one in place (the rod's quarantine deals with it).
    pub(super) fn pose_targets(rod: &SkinnedRod, membrane: &mut Membrane) {
        let pose = RodPose::of(rod.rod());
        if let Err(e) = membrane.pose_targets(pose.positions, &Skin::frames(pose)) {
            tracing::debug!("the rectum's targets keep their last pose: {e}");
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
    /// couple about the element's axis, in the rod's step that follows. The membrane sums the
    /// loads by element at the start of its step ([`Membrane::anchor_sums`]); the couple of
    /// the loads about the axis point `a + (b - a) u` of each node is their moment about the
    /// element's point `p`, plus `(p - a) x` their sum, minus `(b - a) x` their sum weighted by
    /// `u`. Sleeping tiles lie on their anchors at rest and load it with nothing. Returns the
    /// sum, N.
    pub(super) fn load_rod(&mut self, rod: &mut SkinnedRod, membrane: &Membrane) -> Vec3 {
        let _span = tracing::debug_span!("rectum_load_rod").entered();
        let x = rod.rod().positions();
        let mut total = glam::DVec3::ZERO;
        let mut loads = Vec::with_capacity(self.about.len());
        for (e, s) in membrane.anchor_sums().iter().enumerate() {
            let (Some(&a), Some(&b), Some(p)) = (x.get(e), x.get(e + 1), self.about.get(e)) else {
                continue;
            };
            if !s.is_finite() {
                continue;
            }
            let couple =
                s.moment + (p.as_dvec3() - a).cross(s.force) - (b - a).cross(s.weighted_force);
            let ends = [s.force - s.weighted_force, s.weighted_force];
            let k = [s.stiffness - s.weighted_stiffness, s.weighted_stiffness];
            loads.push((e, ends, couple, k));
            total += s.force;
        }
        for (e, ends, couple, k) in loads {
            rod.add_element_load(e, ends, couple, k);
        }
        total.as_vec3()
    }

    /// The nodes of tiles `tiles` (all layers) with their positions and areas, into
    /// `nodes`, `xyz` and `areas`: a tile's row at a time, each coordinate's stretch copied
    /// as it lies in the membrane's state.
    fn gather(&mut self, m: &Membrane, tiles: &[usize]) {
        self.nodes.clear();
        self.xyz.iter_mut().for_each(Vec::clear);
        self.areas.clear();
        for &t in tiles {
            let ([r0, r1], cols) = m.tile_span(t);
            let [c0, c1] = cols;
            for l in 0..LAYERS {
                for i in r0..r1 {
                    let first = m.node(l, i, c0);
                    self.nodes
                        .extend((first..first + (c1 - c0)).map(|n| n as u32));
                    for (to, from) in self.xyz.iter_mut().zip(m.row_positions(l, i, cols)) {
                        to.extend_from_slice(from);
                    }
                    match self.area.get(first..first + (c1 - c0)) {
                        Some(a) => self.areas.extend_from_slice(a),
                        None => self.areas.resize(self.nodes.len(), 0.0),
                    }
                }
            }
        }
    }

    /// The hook against the nodes of the awake tiles its cylinders may reach (the broad
    /// phase: the cost follows the hook's neighbourhood): penalty forces on the nodes, and
    /// the reaction on the hook. The nearest vulnerable node to the hook's end is looked for
    /// in the awake tiles within `near_m` of it (nearer is what the task measures).
    pub(super) fn press_membrane(&mut self, membrane: &mut Membrane, hook: &Instrument) -> Vec3 {
        let capsules: Vec<(Vec3, Vec3, f32)> = hook
            .cylinders()
            .iter()
            .map(|c| (c.p0(), c.p1(), c.max_radius_m()))
            .collect();
        let mut tiles = std::mem::take(&mut self.tiles);
        membrane.awake_tiles_near_capsules(&capsules, &mut tiles);
        {
            let _span =
                tracing::debug_span!("rectum_press_contacts", tiles = tiles.len()).entered();
            self.gather(membrane, &tiles);
            let [x, y, z] = &self.xyz;
            match PointCloud::from_components(x, y, z) {
                // The nodes of blocks of a few rows a cylinder may reach, against that one.
                Ok(cloud) => {
                    self.blocks.refresh(cloud);
                    if hook
                        .contacts(cloud, &self.blocks, &mut self.contacts)
                        .is_err()
                    {
                        hook.contacts_all(cloud, &mut self.contacts);
                    }
                }
                Err(_) => self.contacts.clear(),
            }
        }
        // The nearest vulnerable node to the hook's end, among the awake ones near it (in the
        // tiles that hold one).
        if let Some(end) = hook.cylinders().get(1).map(|c| c.p1()) {
            membrane.awake_tiles_near_among(
                end,
                end,
                self.params.near_m,
                &self.vulnerable_tiles,
                &mut tiles,
            );
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
                // The membrane's load on the rod, summed at the start of the membrane's last
                // step. A quarantined membrane loads it with nothing.
                if let (Some(RectumModel::Rod(rod)), Some(RectumModel::Membrane(m))) =
                    models.pair_mut(ROD, MEMBRANE)
                {
                    self.out.membrane_on_rod_n = self.load_rod(rod, m);
                }
            }
            1 => {
                if let (Some(RectumModel::Membrane(m)), Some(RectumModel::Rod(rod))) =
                    models.write_read(MEMBRANE, ROD)
                {
                    self.on_membrane(rod, m);
                }
            }
            _ => {}
        }
    }
}
