//! The sandbox: one soft block (about 6 x 4 x 3 cm) resting on a table, a ball-tipped probe
//! in the right hand and a grasper in the left. For calibrating devices and models, for
//! tutorials, and as a reference the tests can reason about: flat faces, known depths, no
//! anatomy.
//!
//! The block is the nephrectomy's soft body on a box surface. Its bottom is held on the table
//! by the model's own rest springs (every point has one): the tools act on the top, at least
//! the block's height away along the surface, and a dent decays within a few cells, so the
//! bottom stays on the table (over the demo its points never even wake; a test holds them
//! within 0.5 mm). Pinning the bottom points would need a hook the model does not have.

use crate::models::{Fnv, SimplexMesh, SoftBody};
use crate::sim::TaskStatus;
use crate::sim::{
    Contact, ContactKind, EventKind, Hand, InputFrame, InstrumentShape, ModelId, SimEvent,
    Snapshot, SurfaceRole, TissueModel, ToolSnapshot, World,
};
use glam::Vec3;
use serde::Serialize;

mod field;
mod plugin;
mod scenario;
#[cfg(test)]
mod tests;

pub use crate::mesh::block::{
    BlockShape, REGION_BOTTOM, REGION_SIDES, REGION_TOP, block, divisions,
};
pub use plugin::{ScoreParts, score};
pub use scenario::{Geometry, MODEL, NAME, Scenario, Task, Tools};

use super::{ProcedureInfo, TaskStep};

/// The task, in order.
pub const STEPS: [TaskStep; 4] = [
    TaskStep {
        id: "touch",
        text: "Touch the block with the probe",
    },
    TaskStep {
        id: "press",
        text: "Press the top 5 mm deep",
    },
    TaskStep {
        id: "grasp",
        text: "Grasp the top with the grasper",
    },
    TaskStep {
        id: "lift",
        text: "Lift it 1 cm and let go",
    },
];

/// The registry's entry.
pub const INFO: ProcedureInfo = crate::procedure_info! {
    stem: "sandbox", paper: "none (calibration)",
    title: "Sandbox: one soft block, a probe and a grasper",
    build: |_, s| Sandbox::new(s)?,
    // The top of the 0.5-3.5 N range tissue takes, as for the nephrectomy's grasper.
    tools: [("grasper", Grasper, 3.5), ("probe", Probe, 3.5)],
    // 20 cm from the block's centre, in front and 37 degrees above: the top and the front
    // face both in view.
    view: (0.0, 0.135, 0.16) -> (0.0, 0.015, 0.0),
    // Where the demo trace starts the instruments: over the block's front corners, in view.
    desk_park: [(-0.04, 0.06, 0.03), (0.04, 0.06, 0.03)],
};

/// The role of each region, by region index.
pub const ROLES: [SurfaceRole; 3] = [
    SurfaceRole::Tissue,
    SurfaceRole::Target,
    SurfaceRole::Tissue,
];

/// The block's place in the world.
pub(super) const BLOCK: ModelId = ModelId(0);
/// The most points the soft body's jaws hold (its grasp keeps the nearest this many).
const MAX_HELD: usize = 24;
/// A tip within this many radii of the surface is handed to the model as a contact.
const NEAR_RADII: f32 = 1.5;

/// Running metrics of one session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    pub path_length_left_m: f32,
    pub path_length_right_m: f32,
    /// Deepest the probe's tip reached below the undeformed surface, m.
    pub max_probe_depth_m: f32,
    /// Largest force the tissue pushed the probe back with, N.
    pub max_probe_force_n: f32,
    /// Largest force the tissue pulled the grasper with, N.
    pub max_grasper_force_n: f32,
    /// Highest the grasped tissue was lifted above its rest, m.
    pub lift_height_m: f32,
    /// Times the grasper's force went over its full scale (each time counts once).
    pub grasper_overloads: u32,
    pub steps_done: Vec<String>,
}

/// What the closed jaws hold.
#[derive(Debug, Clone)]
struct Hold {
    /// The points held (the same the model picks: the nearest, up to [`MAX_HELD`]).
    points: Vec<u32>,
    /// The nearest held point is on the top.
    on_top: bool,
    /// Mean height of the held points above their rest, now and at most, m.
    lift_m: f32,
    max_lift_m: f32,
}

pub struct Sandbox {
    pub scenario: Scenario,
    shape: BlockShape,
    /// The block, the world's one model.
    world: World<SoftBody>,
    hold: Option<Hold>,
    tools: [ToolSnapshot; 2],
    prev_input: Option<InputFrame>,
    /// The probe's depth into the undeformed block after the last step, m.
    probe_depth_m: f32,
    overloaded: bool,
    pub metrics: Metrics,
}

impl Sandbox {
    pub fn new(scenario: Scenario) -> Result<Self, crate::mesh::MeshError> {
        let shape = BlockShape {
            size_m: Vec3::from(scenario.geometry.size_m),
        };
        let (mesh, regions) = block(&shape, scenario.cells());
        let body = SoftBody::new(MODEL, SimplexMesh::dual(&mesh)?, regions, scenario.block);
        let mut world = World::new();
        world.add(body);
        Ok(Self {
            scenario,
            shape,
            world,
            hold: None,
            tools: [ToolSnapshot::default(); 2],
            prev_input: None,
            probe_depth_m: 0.0,
            overloaded: false,
            metrics: Metrics::default(),
        })
    }

    pub fn body(&self) -> &SoftBody {
        self.world.model(BLOCK)
    }

    pub fn world(&self) -> &World<SoftBody> {
        &self.world
    }

    pub fn shape(&self) -> &BlockShape {
        &self.shape
    }

    pub fn is_completed(&self) -> bool {
        self.metrics.steps_done.len() == STEPS.len()
    }

    /// The probe's depth into the undeformed block now, m.
    pub fn probe_depth_m(&self) -> f32 {
        self.probe_depth_m
    }

    /// How high the grasped tissue is lifted now, m (0 when nothing is held).
    pub fn lift_m(&self) -> f32 {
        self.hold.as_ref().map_or(0.0, |h| h.lift_m)
    }

    /// Reaction force on each tool after the last step, newtons.
    pub fn reactions(&self) -> [Vec3; 2] {
        self.world.reactions()
    }

    /// A contact for a tip at `tip` pointing along `forward`, if the block is within reach.
    fn sphere(&self, hand: Hand, tip: Vec3, forward: Vec3, radius_m: f32) -> Option<Contact> {
        let near = self
            .body()
            .collider()
            .nearest_within(tip, radius_m * NEAR_RADII);
        (!near.is_empty()).then_some(Contact {
            tool: hand,
            point: tip,
            // The tissue's side of the tip: the model pushes points on along the tool's axis.
            normal: -forward,
            kind: ContactKind::Sphere { radius_m },
        })
    }

    /// Advances one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let dt = self.scenario.dt_s;
        let tools = self.scenario.tools;
        let jaws = self.scenario.grasper;
        if let Some(prev) = &self.prev_input {
            let [left, right] = input.moved_since(prev);
            self.metrics.path_length_left_m += left;
            self.metrics.path_length_right_m += right;
        }

        // The probe (right hand): a rigid ball tip wherever the hand is.
        let probe = input.hand(Hand::Right).pose;
        let probe_forward = probe.forward();
        self.tools[1] = ToolSnapshot {
            tip: probe.position,
            direction: probe_forward,
            beam_end: None,
            beam_reach: None,
            active: false,
            instrument: 0,
            shape: InstrumentShape::Probe,
            jaw: 0.0,
            up: probe.orientation * Vec3::Y,
        };
        let r_probe = tools.probe_tip_radius_m;
        if let Some(c) = self.sphere(Hand::Right, probe.position, probe_forward, r_probe) {
            self.world.contact(BLOCK, c);
        }

        // The grasper (left hand): a ball tip while open; closed, it holds what is in reach.
        let grasper = input.hand(Hand::Left);
        let tip = grasper.pose.position;
        let gripping = grasper.buttons.grip >= jaws.grip_threshold;
        self.tools[0] = ToolSnapshot {
            tip,
            direction: grasper.pose.forward(),
            beam_end: None,
            beam_reach: None,
            active: gripping,
            instrument: 0,
            shape: InstrumentShape::Grasper,
            jaw: 1.0 - grasper.buttons.grip,
            up: grasper.pose.orientation * Vec3::Y,
        };
        let mut let_go = None;
        if gripping {
            if self.hold.is_none() {
                let found = self
                    .body()
                    .collider()
                    .nearest_within(tip, jaws.grasp_radius_m);
                self.hold = found.first().map(|&(_, nearest)| Hold {
                    points: found.iter().take(MAX_HELD).map(|&(_, f)| f).collect(),
                    on_top: self.body().regions()[nearest as usize] == REGION_TOP,
                    lift_m: 0.0,
                    max_lift_m: 0.0,
                });
            }
            if self.hold.is_some() {
                self.world.contact(
                    BLOCK,
                    Contact::grasp(Hand::Left, &grasper.pose, jaws.grasp_radius_m),
                );
            }
        } else {
            let_go = self.hold.take();
            let r = jaws.tip_radius_m;
            let forward = grasper.pose.forward();
            if let Some(c) = self.sphere(Hand::Left, tip, forward, r) {
                self.world.contact(BLOCK, c);
            }
        }

        // The block steps, guarded against non-finite states.
        let mut ev: Vec<EventKind> = Vec::new();
        self.world.step(dt, step, &mut ev);

        // Measurements.
        self.probe_depth_m = self.shape.penetration(probe.position, r_probe);
        if let Some(h) = &mut self.hold {
            let body = self.world.model(BLOCK);
            let (x, rest) = (body.positions(), &body.mesh().rest);
            let rise: f32 = h
                .points
                .iter()
                .map(|&i| x[i as usize].y - rest[i as usize].y)
                .sum();
            h.lift_m = rise / h.points.len().max(1) as f32;
            h.max_lift_m = h.max_lift_m.max(h.lift_m);
        }
        let lift_m = self.lift_m();
        let m = &mut self.metrics;
        let [grasper_n, probe_n] = self.world.reactions().map(Vec3::length);
        m.max_probe_depth_m = m.max_probe_depth_m.max(self.probe_depth_m);
        m.max_probe_force_n = m.max_probe_force_n.max(probe_n);
        m.max_grasper_force_n = m.max_grasper_force_n.max(grasper_n);
        m.lift_height_m = m.lift_height_m.max(lift_m);
        let over = grasper_n > INFO.tools[0].full_scale_n;
        if over && !self.overloaded {
            m.grasper_overloads += 1;
        }
        self.overloaded = over;

        // The checklist: only the next step can be done, so one done early waits its turn.
        let k = &self.scenario.task;
        let done = [
            self.probe_depth_m > 0.0 || probe_n > 0.0,
            self.probe_depth_m >= k.probe_depth_m && self.shape.over_top(probe.position),
            self.hold.as_ref().is_some_and(|h| h.on_top),
            let_go.is_some_and(|h| h.on_top && h.max_lift_m >= k.lift_height_m),
        ];
        crate::procedures::tick_off(&STEPS, &done, &mut m.steps_done, &mut ev);
        if self.is_completed() && self.metrics.completion_time_s.is_none() {
            self.metrics.completion_time_s = Some((step + 1) as f64 * f64::from(dt));
        }
        self.prev_input = Some(*input);
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        self.snapshot_job(step).build()
    }

    /// The snapshot as a job: the block's state is read now, its mesh built by the job.
    pub fn snapshot_job(&mut self, step: u64) -> crate::sim::SnapshotJob {
        let meshes = self.world.render_job(|_, _| ROLES.to_vec());
        let rest = Snapshot {
            step,
            time_s: step as f64 * f64::from(self.scenario.dt_s),
            models: Vec::new(),
            tools: self.tools,
            reactions: self.world.reactions(),
            // The target is given, not found: the top is highlighted from the start.
            target_found: true,
            emissions: Vec::new(),
            bleeding: Vec::new(),
            scope: None,
            picture: None,
        };
        crate::sim::SnapshotJob::later(move || Snapshot {
            models: meshes.build(),
            ..rest
        })
    }

    /// Digest of the block's state and the task's progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        let v = self.body().state_hash();
        h.write(v as u32);
        h.write((v >> 32) as u32);
        h.write(self.metrics.steps_done.len() as u32);
        h.0
    }
}

impl Sandbox {
    /// The panel's live part: the paths, the probe's depth and force, and the lift. Nothing
    /// here is vulnerable.
    pub(super) fn panel(&self, _near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let mm = |v: f32| format!("{:.1} mm", v * 1000.0);
        TaskStatus {
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![
                ("probe depth".to_string(), mm(self.probe_depth_m())),
                (
                    "probe force".to_string(),
                    format!("{:.2} N", self.reactions()[1].length()),
                ),
                ("lift".to_string(), mm(self.lift_m())),
            ],
            ..TaskStatus::default()
        }
    }
}
