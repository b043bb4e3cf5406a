//! The `catheter` procedure: the skeleton-spring catheter of [`crate::models::skeleton`] in
//! its bifurcating vessel, driven from its handle. The right hand holds the handle: where it
//! is along the vessel's entry axis is how far the catheter is in, its trigger bends the tip
//! (0 to the largest bend), its grip twists the catheter (to `device.twist_deg` at full
//! grip), which turns the direction the tip bends to; between them they choose the branch. The
//! force on the catheter (the sum of the wall's contact forces on its balls) is its reaction
//! for the haptic device. The task's checklist, the metrics (time, path, wall contacts, peak
//! force, force-time integral, the force over time as the paper's Fig. 15), the events and
//! what the renderer draws.

use super::fluoroscopy::{Console, Imaging};
use super::scenario::Scenario;
use crate::models::skeleton::catheter::Drive;
use crate::models::skeleton::in_vessel::CatheterInVessel;
use crate::procedures::TaskStep;
use crate::sim::Fnv;
use crate::sim::TaskStatus;
use crate::sim::{
    EventKind, Hand, InputFrame, ModelSnapshot, ProcedureEvent, SimEvent, Snapshot, SurfaceRole,
    ToolSnapshot,
};
use glam::{DVec3, Vec3};
use serde::Serialize;

/// The task, in order.
pub const STEPS: [TaskStep; 3] = [
    TaskStep {
        id: "advance",
        text: "Advance the catheter 20 mm into the vessel",
    },
    TaskStep {
        id: "bifurcation",
        text: "Bring the tip to the bifurcation",
    },
    TaskStep {
        id: "branch",
        text: "Bend and twist the tip into the target branch and advance along it without \
               puncturing the wall",
    },
];

/// The first step's depth into the trunk, m.
const ADVANCE_M: f64 = 0.020;
/// The tip is at the bifurcation within this of the trunk's end, m.
const AT_BIFURCATION_M: f64 = 0.005;
/// The tip is in a branch once this far along it, m.
const IN_BRANCH_M: f64 = 0.010;
/// The head is off the wall this long before its next touch counts as a new contact, s.
const CONTACT_GAP_S: f64 = 0.05;
/// The force trace's sample period, s.
const TRACE_EVERY_S: f64 = 0.02;

/// Running metrics of one session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    /// The handle's and the tip's paths, m.
    pub handle_path_m: f64,
    pub tip_path_m: f64,
    /// Times the head came onto the wall, and the steps it was on it.
    pub wall_contacts: u32,
    pub contact_steps: u32,
    /// The largest force on the catheter, N, and its integral over time, N s.
    pub peak_force_n: f64,
    pub force_time_n_s: f64,
    /// The head's largest normal force, N.
    pub peak_head_normal_n: f64,
    pub punctures: u32,
    /// Times the tip went into the other branch.
    pub wrong_branch: u32,
    /// How far the tip has gone into the target branch at most, m.
    pub reach_m: f64,
    pub errors: u32,
    pub steps_done: Vec<String>,
    /// The force on the catheter over the session (the paper's Fig. 15): `[t s, |F|, Fx, Fy,
    /// Fz]` every 20 ms, N.
    pub force_trace: Vec<[f64; 5]>,
    /// What the interventional console counted: fluoroscopy time, runs, pulses, the dose,
    /// the contrast.
    pub fluoroscopy: Console,
}

pub struct Catheterisation {
    pub scenario: Scenario,
    pub scene: CatheterInVessel,
    pub metrics: Metrics,
    reaction: DVec3,
    tool: ToolSnapshot,
    prev: Option<(Vec3, DVec3)>,
    touching: bool,
    /// Steps since the head last touched the wall.
    off_steps: u32,
    /// The tip is in the wrong branch now.
    astray: bool,
    triangles: Vec<[u32; 3]>,
    /// The fluoroscope and the contrast, under the left hand.
    pub imaging: Imaging,
}

impl Catheterisation {
    pub fn new(scenario: Scenario, scene: CatheterInVessel) -> Catheterisation {
        let triangles = scene.vessel().triangles();
        let imaging = Imaging::new(scenario.fluoroscopy, &scene, f64::from(scenario.dt_s));
        Catheterisation {
            imaging,
            scenario,
            scene,
            metrics: Metrics::default(),
            reaction: DVec3::ZERO,
            tool: ToolSnapshot::default(),
            prev: None,
            touching: false,
            off_steps: u32::MAX,
            astray: false,
            triangles,
        }
    }

    pub fn is_completed(&self) -> bool {
        self.metrics.steps_done.len() == STEPS.len()
    }

    /// The force on the catheter after the last step, N (the device feels it).
    pub fn reaction(&self) -> DVec3 {
        self.reaction
    }

    pub fn tool(&self) -> &ToolSnapshot {
        &self.tool
    }

    fn time_s(&self, steps: u64) -> f64 {
        steps as f64 * f64::from(self.scenario.dt_s)
    }

    /// The device's drive from the right hand: its handle's travel along the entry axis, its
    /// trigger and grip.
    pub fn drive(&self, input: &InputFrame) -> Drive {
        let h = input.hand(Hand::Right);
        let c = &self.scene.catheter();
        let length = c.params.length_m;
        let p = h.pose.position.as_dvec3();
        let insertion = if p.is_finite() {
            ((p - c.entry).dot(c.axis) + length).clamp(0.0, length)
        } else {
            0.0
        };
        Drive {
            insertion_m: insertion,
            twist_rad: f64::from(h.buttons.grip.clamp(0.0, 1.0))
                * self.scenario.device.twist_deg.to_radians(),
            bend: f64::from(h.buttons.trigger.clamp(0.0, 1.0)),
        }
    }

    /// Advances one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let dt = f64::from(self.scenario.dt_s);
        let drive = self.drive(input);
        let mut ev: Vec<EventKind> = Vec::new();
        let out = self.scene.step(&drive, self.scenario.dt_s, step, &mut ev);
        self.reaction = out.reaction;
        let now_s = self.time_s(step + 1);
        let hand = input.hand(Hand::Right).pose.position;
        let tip = self.scene.catheter().tip();
        let m = &mut self.metrics;
        if let Some((h0, t0)) = self.prev
            && hand.is_finite()
            && h0.is_finite()
        {
            m.handle_path_m += f64::from(hand.distance(h0));
            m.tip_path_m += tip.distance(t0);
        }
        self.prev = Some((hand, tip));
        let force = out.reaction.length();
        m.peak_force_n = m.peak_force_n.max(force);
        m.force_time_n_s += force * dt;
        m.peak_head_normal_n = m.peak_head_normal_n.max(out.head_normal_n);
        // A contact counts once however the head chatters on the wall: a new one only after
        // `CONTACT_GAP_S` off it.
        self.imaging.step(input, &self.scene, dt, step);
        m.fluoroscopy = self.imaging.console;
        let touching = out.head_normal_n > 0.0;
        if touching {
            m.contact_steps += 1;
            if self.off_steps as f64 * dt >= CONTACT_GAP_S {
                m.wall_contacts += 1;
            }
            self.off_steps = 0;
        } else {
            self.off_steps = self.off_steps.saturating_add(1);
        }
        self.touching = touching;
        let every = (TRACE_EVERY_S / dt).round().max(1.0) as u64;
        if (step + 1).is_multiple_of(every) {
            let f = out.reaction;
            m.force_trace.push([now_s, force, f.x, f.y, f.z]);
        }
        for p in &out.punctures {
            m.punctures += 1;
            m.errors += 1;
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "puncture",
                PunctureEvent {
                    position: p.position.as_vec3().to_array(),
                    force_n: p.force_n,
                    wall_ball: p.wall,
                },
            )));
            ev.push(EventKind::Alarm {
                tool: "catheter".to_string(),
                message: "the catheter has punctured the vessel wall".to_string(),
            });
        }
        // Where the tip is: which branch, how far along.
        let target = self.scenario.task.branch as usize;
        let v = &self.scene.vessel();
        let in_branch = |k: usize| {
            let t = &v.tubes[k];
            let along = t.along(tip);
            (along > IN_BRANCH_M && t.from_axis(tip) < v.mid_radius_m).then_some(along)
        };
        let other = if target == 1 { 2 } else { 1 };
        let astray = in_branch(other).is_some();
        if astray && !self.astray {
            m.wrong_branch += 1;
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "wrong_branch",
                WrongBranch {
                    branch: other as u32,
                },
            )));
        }
        self.astray = astray;
        if let Some(along) = in_branch(target) {
            m.reach_m = m.reach_m.max(along);
        }
        let trunk = &v.tubes[0];
        let done = [
            trunk.along(tip) >= ADVANCE_M || m.reach_m > 0.0,
            trunk.along(tip) >= trunk.length_m - AT_BIFURCATION_M || m.reach_m > 0.0,
            m.reach_m >= self.scenario.task.reach_m,
        ];
        crate::procedures::tick_off(&STEPS, &done, &mut m.steps_done, &mut ev);
        if m.steps_done.len() == STEPS.len() && m.completion_time_s.is_none() {
            m.completion_time_s = Some(now_s);
        }
        let c = &self.scene.catheter();
        self.tool = ToolSnapshot {
            tip: c.balls.x[0].as_vec3(),
            direction: c.axis.as_vec3(),
            beam_end: None,
            beam_reach: None,
            active: touching,
            instrument: 0,
            shape: Default::default(),
            jaw: 0.0,
            up: Vec3::ZERO,
        };
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        let time_s = self.time_s(step);
        Snapshot {
            step,
            time_s,
            models: vec![self.vessel_mesh(), self.catheter_mesh()],
            tools: [ToolSnapshot::default(), self.tool],
            reactions: [Vec3::ZERO, self.reaction.as_vec3()],
            target_found: true,
            emissions: Vec::new(),
            bleeding: Vec::new(),
            scope: None,
            picture: self.imaging.picture.clone(),
        }
    }

    /// The wall through its balls (translucent, as the paper draws it), without the
    /// triangles at punctured balls.
    fn vessel_mesh(&self) -> ModelSnapshot {
        let b = &self.scene.vessel().balls;
        let holes = &self.scene.holes();
        let tris: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|&i| !holes[i as usize]))
            .collect();
        let mut normals = vec![DVec3::ZERO; b.len()];
        for t in &tris {
            let [p, q, r] = t.map(|i| b.x[i as usize]);
            let n = (q - p).cross(r - p);
            for &i in t {
                normals[i as usize] += n;
            }
        }
        ModelSnapshot {
            seared: Vec::new(),
            name: "vessel".to_string(),
            positions: b.x.iter().map(|x| x.as_vec3()).collect(),
            normals: normals
                .iter()
                .map(|n| n.normalize_or(DVec3::Z).as_vec3())
                .collect(),
            indices: tris.iter().flatten().copied().collect(),
            regions: vec![0; tris.len()],
            roles: vec![SurfaceRole::Membrane],
            cut_edge: vec![false; b.len()],
        }
    }

    /// The catheter as a tube through its balls (8 sides), closed at the tip.
    fn catheter_mesh(&self) -> ModelSnapshot {
        const SIDES: usize = 8;
        let c = &self.scene.catheter();
        let x = &c.balls.x;
        let r = 0.5 * c.params.diameter_m;
        let mut m = ModelSnapshot {
            name: "catheter".to_string(),
            roles: vec![SurfaceRole::Duct],
            ..ModelSnapshot::default()
        };
        for i in 0..x.len() {
            let along = if i + 1 < x.len() {
                x[i + 1] - x[i]
            } else {
                x[i] - x[i - 1]
            }
            .normalize_or(c.axis);
            let side = c.up[i].cross(along).normalize_or(DVec3::Z);
            let up = along.cross(side);
            for k in 0..SIDES {
                let a = std::f64::consts::TAU * k as f64 / SIDES as f64;
                let n = side * a.cos() + up * a.sin();
                m.positions.push((x[i] + n * r).as_vec3());
                m.normals.push(n.as_vec3());
            }
        }
        for i in 0..x.len() - 1 {
            for k in 0..SIDES {
                let (a, b) = ((i * SIDES + k) as u32, (i * SIDES + (k + 1) % SIDES) as u32);
                let (c2, d) = (a + SIDES as u32, b + SIDES as u32);
                m.indices.extend([a, b, c2, b, d, c2]);
                m.regions.extend([0, 0]);
            }
        }
        // The tip's cap.
        let last = x.len() - 1;
        let centre = m.positions.len() as u32;
        let tip_dir = (x[last] - x[last - 1]).normalize_or(c.axis);
        m.positions.push((x[last] + tip_dir * r).as_vec3());
        m.normals.push(tip_dir.as_vec3());
        for k in 0..SIDES {
            let a = (last * SIDES + k) as u32;
            let b = (last * SIDES + (k + 1) % SIDES) as u32;
            m.indices.extend([a, b, centre]);
            m.regions.push(0);
        }
        m.cut_edge = vec![false; m.positions.len()];
        m
    }

    /// Digest of the balls, the holes and the task's progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv(self.scene.state_hash());
        h.write(self.metrics.steps_done.len() as u32);
        h.write(self.metrics.errors);
        let c = &self.metrics.fluoroscopy;
        h.write(c.pulses);
        h.write(c.contrast_runs);
        let dap = c.dap_gy_cm2.to_bits();
        h.write(dap as u32);
        h.write((dap >> 32) as u32);
        for angle in [c.lao_deg, c.cranial_deg] {
            let b = angle.to_bits();
            h.write(b as u32);
            h.write((b >> 32) as u32);
        }
        h.0
    }
}

#[derive(Serialize)]
struct PunctureEvent {
    position: [f32; 3],
    force_n: f64,
    wall_ball: u32,
}

#[derive(Serialize)]
struct WrongBranch {
    branch: u32,
}

impl Catheterisation {
    /// The panel's live part: the handle's path, the force, the peak force, the wall
    /// contacts and the reach into the branch (nothing here is vulnerable to touch), then
    /// the interventional console's figures.
    pub(super) fn panel(&self, _near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        TaskStatus {
            path_m: [0.0, m.handle_path_m as f32],
            figures: vec![
                (
                    "force".to_string(),
                    format!("{:.2} N", self.reaction().length()),
                ),
                ("peak force".to_string(), format!("{:.2} N", m.peak_force_n)),
                ("wall contacts".to_string(), m.wall_contacts.to_string()),
                (
                    "into the branch".to_string(),
                    format!("{:.0} mm", 1e3 * m.reach_m),
                ),
            ]
            .into_iter()
            .chain(self.imaging.console.figures())
            .collect(),
            ..TaskStatus::default()
        }
    }

    /// Reaction force on each instrument (left, right) after the last step: none on the
    /// introducer, the vessel's on the catheter.
    pub fn reactions(&self) -> [Vec3; 2] {
        [Vec3::ZERO, self.reaction().as_vec3()]
    }
}
