//! The `rectum` procedure: the scene of [`super::scene`] driven by the trainee's hands (the
//! left holds a grasper, the right an L-hook with its current on the trigger, or a second
//! grasper: its primary button changes one for the other), the task's
//! checklist, the physics metrics of the paper's Table 1 that exist without the assessment
//! layer, and what the renderer draws (the rectum, the fasciae with the dissection showing,
//! the pelvic side with its vulnerable structures, the smoke where the hook cut).

use super::drawn::Drawn;
use super::regions::{self, RegionKind};
use super::scenario::Scenario;
use super::scene::{ALARM_RECTAL_WALL, RectumScene, StepOutcome, ToolState};
use crate::models::membrane::LAYERS;
use crate::procedures::scope::Scope;
use crate::sim::Fnv;
use crate::sim::SnapshotJob;
use crate::sim::TaskStatus;
use crate::sim::{
    EmissionKind, EmissionLog, EventKind, Hand, HandInput, InputFrame, InstrumentShape,
    ProcedureEvent, SimEvent, Snapshot, TissueModel, ToolSnapshot,
};
use glam::Vec3;
use serde::Serialize;

/// The task, in order.
pub const STEPS: [crate::procedures::TaskStep; 4] = [
    crate::procedures::TaskStep {
        id: "expose",
        text: "Grasp the rectum and lift it to put the plane under tension",
    },
    crate::procedures::TaskStep {
        id: "enter",
        text: "Enter the dissection plane with the hook",
    },
    crate::procedures::TaskStep {
        id: "dissect",
        text: "Dissect half of the target plane",
    },
    crate::procedures::TaskStep {
        id: "free",
        text: "Free the section: cut every spring of the target plane",
    },
];

/// A cut that starts this far from where the last one ended is a jump, m.
pub const JUMP_M: f32 = 0.005;

/// Running metrics of one session (Table 1's leaves that the physics measures).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    pub path_length_left_m: f32,
    pub path_length_right_m: f32,
    /// Times the hook came onto the rectal wall (layer 1 of the paper).
    pub wall_collisions: u32,
    /// Times it touched a vulnerable structure.
    pub vulnerable_contacts: u32,
    /// Largest force on the hook and the fastest the hook moved while within `near_m` of a
    /// vulnerable structure, N and m/s.
    pub max_force_near_vulnerable_n: f32,
    pub max_speed_near_vulnerable_m_per_s: f32,
    /// Path of the hook's end over the steps it cut, m.
    pub cutting_length_m: f32,
    /// Mean distance of the hook's end from the middle of the plane across it when cutting
    /// (the plane's depth error), m.
    pub mean_cut_depth_error_m: f32,
    /// Mean angle between the hook's shaft and the plane's normal when cutting, degrees.
    pub mean_cut_angle_deg: f32,
    /// Cuts that began more than [`JUMP_M`] from where the last ended, per minute.
    pub jumps: u32,
    pub jump_frequency_per_min: f32,
    /// Plane springs cut inside and outside the target, and the share inside.
    pub correct_cuts: u32,
    pub incorrect_cuts: u32,
    pub correct_cut_ratio: f32,
    /// Target springs cut over all of them.
    pub target_cut_fraction: f32,
    /// Plane springs cut outside the target over the target's springs (Table 1's
    /// "redundant fabric used": tissue divided beyond what the task needs).
    pub redundant_cut_fraction: f32,
    /// Table 1's exposure, as shares of the cutting steps: directly exposed (the grasper
    /// holding the rectum lifted within `expose_lift_m`-`overexposed_lift_m`), indirectly
    /// (cutting without that traction on a plane once exposed), overexposed (lifted past
    /// `overexposed_lift_m`). Cutting a plane never exposed counts in none of them.
    pub exposure_direct_share: f32,
    pub exposure_indirect_share: f32,
    pub exposure_over_share: f32,
    /// Steps the hook's current was on against the rectal wall (each an alarm): cutting
    /// where no cut belongs.
    pub wall_cuts: u32,
    /// Share of the cutting steps with the grasper holding the rectum (counter-traction).
    pub counter_traction_share: f32,
    pub max_hook_force_n: f32,
    pub max_grasper_force_n: f32,
    pub alarms: u32,
    /// Times the right hand changed instrument (hook for grasper or back).
    pub instrument_changes: u32,
    /// Instrument selection (Table 1): the share of the right hand's working steps (the hook
    /// touching tissue or cutting, the grasper holding) with the instrument the task's step
    /// calls for, graspers to expose the plane, the hook from then on; none before it worked.
    pub instrument_selection: Option<f32>,
    pub steps_done: Vec<String>,
}

/// Sums behind the means.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    cut_steps: u32,
    held_cut_steps: u32,
    /// Cutting steps directly exposed, indirectly exposed and overexposed.
    exposure: [u32; 3],
    depth: f64,
    angle: f64,
    /// Where the last cut ended, and whether the last step cut.
    last_cut_at: Option<Vec3>,
    cutting: bool,
    /// The right hand's working steps, and of them those with the called-for instrument.
    right_work_steps: u32,
    right_apt_steps: u32,
}

/// The instrument in the right hand.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum RightTool {
    #[default]
    Hook,
    Grasper,
}

pub struct Rectum {
    pub scenario: Scenario,
    pub scene: RectumScene,
    tools: [ToolSnapshot; 2],
    prev_hook_end: Option<Vec3>,
    /// Where each hand's grasp took the rectum, and how far a grasp has lifted it at most, m.
    grasp_from: [Option<Vec3>; 2],
    max_lift_m: f32,
    /// How far the left grasper holds the rectum lifted now, m (none: not holding).
    lift_now_m: Option<f32>,
    last: StepOutcome,
    on_wall: bool,
    sums: Sums,
    /// Smoke given off where the hook cut (drawn by the renderer, not simulated).
    smoke: EmissionLog,
    /// The laparoscope the left device drives while its primary button is held.
    scope: Scope,
    /// The instruments' places last step (left, right), for their path lengths.
    prev_tools: Option<[Vec3; 2]>,
    /// The right hand's instrument, and whether its primary button was down last step (a
    /// press changes the instrument).
    right: RightTool,
    right_button: bool,
    pub metrics: Metrics,
    /// The membrane's drawn grids.
    drawn: Drawn,
}

impl Rectum {
    pub fn new(scenario: Scenario, anatomy: &super::Anatomy) -> Result<Self, super::SceneError> {
        let mut scene = RectumScene::new(anatomy, scenario.scene_params())?;
        scene.place_everything();
        if let Some(gpu) = crate::gpu::Gpu::for_compute(scenario.compute)? {
            match scene.membrane_mut().use_gpu(&gpu) {
                Ok(()) => {}
                // `auto` stays on the CPU where the device refuses the membrane.
                Err(e) if scenario.compute == crate::scenario::Compute::Auto => {
                    tracing::warn!("compute auto: the membrane stays on the CPU ({e})");
                }
                Err(e) => return Err(e.into()),
            }
        }
        Ok(Rectum {
            drawn: Drawn::new(&scene),
            scenario,
            scene,
            tools: [ToolSnapshot::default(); 2],
            prev_hook_end: None,
            grasp_from: [None; 2],
            max_lift_m: 0.0,
            lift_now_m: None,
            last: StepOutcome::default(),
            on_wall: false,
            sums: Sums::default(),
            smoke: EmissionLog::smoke(),
            scope: Scope::new(super::plugin::INFO.view),
            prev_tools: None,
            right: RightTool::Hook,
            right_button: false,
            metrics: Metrics::default(),
        })
    }

    pub fn is_completed(&self) -> bool {
        self.metrics.steps_done.len() == STEPS.len()
    }

    /// Force of the tissue on each instrument (left grasper, right hook or grasper) after the
    /// last step.
    pub fn reactions(&self) -> [Vec3; 2] {
        [
            self.last.grasper_n,
            self.last.hook_n + self.last.grasper_right_n,
        ]
    }

    /// The right hand's instrument now.
    pub fn right_tool(&self) -> RightTool {
        self.right
    }

    /// Where instrument `k` (0 left, 1 right) works: a grasper's jaw, the hook's end.
    pub fn tool_tip(&self, k: usize) -> Vec3 {
        self.tools[k.min(1)].tip
    }

    /// The vulnerable structure nearest the hook's end after the last step, and how far.
    pub fn near_now(&self) -> Option<(&'static str, f32)> {
        let (id, d) = self.last.near_vulnerable?;
        regions::region(id).map(|r| (r.label, d))
    }

    /// Whether the hook touches a vulnerable structure now.
    pub fn touching_now(&self) -> bool {
        self.last.touching != 0
    }

    /// Advances one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let dt = self.scenario.dt_s;
        let hook = input.hand(Hand::Right);
        let left = input.hand(Hand::Left);
        // The left device drives the camera while its button is held; the grasper waits.
        let grasper = HandInput {
            pose: self.scope.update(&left.pose, left.buttons.mark),
            buttons: left.buttons,
        };
        let grasper = &grasper;
        // Path lengths are the instruments' (driving the camera is not instrument travel).
        let places = [grasper.pose.position, hook.pose.position];
        if let Some(prev) = self.prev_tools
            && places.iter().chain(&prev).all(|p| p.is_finite())
        {
            self.metrics.path_length_left_m += places[0].distance(prev[0]);
            self.metrics.path_length_right_m += places[1].distance(prev[1]);
        }
        self.prev_tools = Some(places);
        let t = &self.scenario.tools;
        let mut ev: Vec<EventKind> = Vec::new();
        // The right hand's primary button changes its instrument (the one it held lets go).
        let pressed = hook.buttons.mark && !self.right_button;
        self.right_button = hook.buttons.mark;
        if pressed {
            self.right = match self.right {
                RightTool::Hook => RightTool::Grasper,
                RightTool::Grasper => RightTool::Hook,
            };
            self.metrics.instrument_changes += 1;
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "instrument_change",
                InstrumentChange {
                    hand: "right",
                    to: self.right_name(),
                },
            )));
        }
        let with_hook = self.right == RightTool::Hook;
        let cutting = with_hook && hook.buttons.trigger >= t.cut_threshold;
        let closed = grasper.buttons.grip >= t.grip_threshold;
        // The right grasper closes on its trigger or its grip.
        let right_closed = hook.buttons.trigger.max(hook.buttons.grip) >= t.grip_threshold;
        let right_pose = (hook.pose.position, hook.pose.orientation);
        let tools = ToolState {
            hook: with_hook.then_some(right_pose),
            cutting,
            grasper: Some((grasper.pose.position, grasper.pose.orientation, closed)),
            grasper_right: (!with_hook).then_some((right_pose.0, right_pose.1, right_closed)),
        };
        let was_held = [0, 1].map(|h| self.scene.rod().grip(h).is_some());
        let out = self.scene.step(dt, &tools, step, &mut ev);
        let held = [0, 1].map(|h| self.scene.rod().grip(h).is_some());
        self.lift_now_m = None;
        for hand in 0..2 {
            let name = ["grasper", "right grasper"][hand];
            if held[hand] && !was_held[hand] {
                self.grasp_from[hand] = self.scene.rod().held_point(hand);
                ev.push(EventKind::Grasp {
                    tool: name.to_string(),
                    model: "rectum".to_string(),
                    vertices: 1,
                });
            } else if was_held[hand] && !held[hand] {
                self.grasp_from[hand] = None;
                ev.push(EventKind::Release {
                    tool: name.to_string(),
                });
            }
            if let (Some(from), Some(now)) =
                (self.grasp_from[hand], self.scene.rod().held_point(hand))
            {
                let lift = now.distance(from);
                self.max_lift_m = self.max_lift_m.max(lift);
                if hand == 0 {
                    self.lift_now_m = Some(lift);
                }
            }
        }
        self.select(&out, held[1]);
        let held = held[0];
        let end = self.hook_end(&tools);
        self.measure(&out, end, hook.pose.forward(), held, dt, &mut ev);
        let held_right = self.scene.rod().grip(1).is_some();
        self.tools = [
            ToolSnapshot {
                tip: grasper.pose.position,
                direction: grasper.pose.forward(),
                beam_end: None,
                beam_reach: None,
                active: held,
                instrument: 0,
                shape: InstrumentShape::Grasper,
                jaw: 1.0 - grasper.buttons.grip,
                up: grasper.pose.orientation * Vec3::Y,
            },
            ToolSnapshot {
                tip: end.unwrap_or(hook.pose.position),
                direction: hook.pose.forward(),
                beam_end: None,
                beam_reach: None,
                active: if with_hook { cutting } else { held_right },
                instrument: u8::from(!with_hook),
                shape: if with_hook {
                    InstrumentShape::Hook
                } else {
                    InstrumentShape::Grasper
                },
                jaw: if with_hook {
                    0.0
                } else {
                    1.0 - hook.buttons.grip
                },
                up: hook.pose.orientation * Vec3::Y,
            },
        ];
        // Smoke rises where the current cut springs this step, at the hook's end; its time is
        // the end of the step, the time of the snapshot taken after it.
        let now_s = Self::time_s(step + 1, dt);
        match end {
            Some(e) if out.cut > 0 => {
                self.smoke.record(now_s, e, EmissionKind::Smoke);
            }
            _ => self.smoke.forget_before(now_s),
        }
        self.checklist(step, dt, &mut ev);
        self.last = out;
        self.prev_hook_end = end;
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    /// The right hand's instrument's name.
    pub fn right_name(&self) -> &'static str {
        match self.right {
            RightTool::Hook => "hook",
            RightTool::Grasper => "right grasper",
        }
    }

    /// Instrument selection: whether the right hand works with the instrument the task's
    /// next step calls for (graspers to expose, the hook to enter and dissect).
    fn select(&mut self, out: &StepOutcome, held_right: bool) {
        let working = match self.right {
            RightTool::Hook => {
                out.hook_contacts > 0 || out.cut > 0 || out.hook_n.length_squared() > 0.0
            }
            RightTool::Grasper => held_right,
        };
        let next = self.metrics.steps_done.len();
        if !working || next >= STEPS.len() {
            return;
        }
        let called_for = if next == 0 {
            RightTool::Grasper
        } else {
            RightTool::Hook
        };
        self.sums.right_work_steps += 1;
        self.sums.right_apt_steps += u32::from(self.right == called_for);
        self.metrics.instrument_selection =
            Some(self.sums.right_apt_steps as f32 / self.sums.right_work_steps as f32);
    }

    /// Simulation time after `steps` steps of `dt`, s (as the snapshot states it).
    fn time_s(steps: u64, dt: f32) -> f64 {
        steps as f64 * f64::from(dt)
    }

    /// The hook's working end (the tip of its L) for these tools.
    fn hook_end(&self, tools: &ToolState) -> Option<Vec3> {
        let (corner, q) = tools.hook?;
        let h = crate::collision::Instrument::l_hook(corner, q).ok()?;
        h.cylinders().get(1).map(|c| c.p1())
    }

    /// Metrics and events from one step's outcome.
    fn measure(
        &mut self,
        out: &StepOutcome,
        end: Option<Vec3>,
        axis: Vec3,
        held: bool,
        dt: f32,
        ev: &mut Vec<EventKind>,
    ) {
        let m = &mut self.metrics;
        m.max_hook_force_n = m.max_hook_force_n.max(out.hook_n.length());
        m.max_grasper_force_n = m.max_grasper_force_n.max(out.grasper_n.length());
        // The wall: counted when the hook comes onto it.
        if out.on_wall && !self.on_wall {
            m.wall_collisions += 1;
        }
        self.on_wall = out.on_wall;
        // Near a vulnerable structure: force and speed.
        let speed = match (end, self.prev_hook_end) {
            (Some(a), Some(b)) => a.distance(b) / dt,
            _ => 0.0,
        };
        if out
            .near_vulnerable
            .is_some_and(|(_, d)| d <= self.scenario.task.near_m)
        {
            m.max_force_near_vulnerable_n = m.max_force_near_vulnerable_n.max(out.hook_n.length());
            m.max_speed_near_vulnerable_m_per_s = m.max_speed_near_vulnerable_m_per_s.max(speed);
        }
        // Alarms: each vulnerable structure newly touched, the wall cut.
        for (k, r) in regions::REGIONS.iter().enumerate() {
            let bit = 1u32 << (k + 1);
            if r.kind == RegionKind::Vulnerable && out.alarms & bit != 0 {
                m.vulnerable_contacts += 1;
                m.alarms += 1;
                ev.push(EventKind::VulnerableContact {
                    tool: "hook".to_string(),
                    model: r.name.to_string(),
                });
                ev.push(EventKind::Alarm {
                    tool: "hook".to_string(),
                    message: format!("the hook touches the {}", r.label),
                });
            }
        }
        if out.alarms & ALARM_RECTAL_WALL != 0 {
            m.alarms += 1;
            m.wall_cuts += 1;
            ev.push(EventKind::Alarm {
                tool: "hook".to_string(),
                message: "the hook's current is on against the rectal wall".to_string(),
            });
        }
        // Cuts.
        if out.cut > 0 {
            let outside = out.cut - out.cut_in_target;
            m.correct_cuts += out.cut_in_target;
            m.incorrect_cuts += outside;
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "spring_cut",
                SpringCut {
                    springs: out.cut,
                    in_target: out.cut_in_target,
                },
            )));
            if let Some(e) = end {
                if !self.sums.cutting {
                    if self
                        .sums
                        .last_cut_at
                        .is_some_and(|p| p.distance(e) > JUMP_M)
                    {
                        m.jumps += 1;
                    }
                } else if let Some(p) = self.prev_hook_end {
                    m.cutting_length_m += p.distance(e);
                }
                self.sums.last_cut_at = Some(e);
                let (depth, angle) = plane_geometry(&self.scene, e, axis, self.scene.last_cut());
                self.sums.depth += f64::from(depth);
                self.sums.angle += f64::from(angle.unwrap_or(0.0));
            }
            self.sums.cut_steps += 1;
            self.sums.held_cut_steps += u32::from(held);
            let task = &self.scenario.task;
            let exposed = match self.lift_now_m.filter(|_| held) {
                Some(l) if l > task.overexposed_lift_m => Some(2),
                Some(l) if l >= task.expose_lift_m => Some(0),
                _ if self.max_lift_m >= task.expose_lift_m => Some(1),
                _ => None,
            };
            if let Some(k) = exposed {
                self.sums.exposure[k] += 1;
            }
        }
        self.sums.cutting = out.cut > 0;
        let n = self.sums.cut_steps.max(1) as f64;
        m.mean_cut_depth_error_m = (self.sums.depth / n) as f32;
        m.mean_cut_angle_deg = (self.sums.angle / n) as f32;
        m.counter_traction_share = (f64::from(self.sums.held_cut_steps) / n) as f32;
        let share = |k: usize| (f64::from(self.sums.exposure[k]) / n) as f32;
        m.exposure_direct_share = share(0);
        m.exposure_indirect_share = share(1);
        m.exposure_over_share = share(2);
        let all = m.correct_cuts + m.incorrect_cuts;
        m.correct_cut_ratio = if all > 0 {
            m.correct_cuts as f32 / all as f32
        } else {
            0.0
        };
        let (cut, total) = self.scene.target_progress();
        (m.target_cut_fraction, m.redundant_cut_fraction) = if total > 0 {
            (
                cut as f32 / total as f32,
                m.incorrect_cuts as f32 / total as f32,
            )
        } else {
            (0.0, 0.0)
        };
    }

    /// The checklist: only the next step can be done, so one done early waits its turn.
    fn checklist(&mut self, step: u64, dt: f32, ev: &mut Vec<EventKind>) {
        let (cut, total) = self.scene.target_progress();
        let m = &mut self.metrics;
        let done = [
            self.max_lift_m >= self.scenario.task.expose_lift_m,
            cut > 0,
            2 * cut >= total,
            total > 0 && cut >= total,
        ];
        crate::procedures::tick_off(&STEPS, &done, &mut m.steps_done, ev);
        let minutes = (step + 1) as f64 * f64::from(dt) / 60.0;
        m.jump_frequency_per_min = (f64::from(m.jumps) / minutes.max(1e-9)) as f32;
        if m.steps_done.len() == STEPS.len() && m.completion_time_s.is_none() {
            m.completion_time_s = Some((step + 1) as f64 * f64::from(dt));
        }
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        // The drawn nodes as the membrane's device left them (see `Membrane::place_drawn`).
        let membrane = self.drawn.meshes_later(self.scene.membrane_mut());
        let rod = self.scene.rod();
        let (rectum, [fascia, pelvis]) = rayon::join(
            || {
                let _span = tracing::debug_span!("rectum_snapshot_rod").entered();
                rod.mesh()
            },
            membrane,
        );
        let mut s = self.snapshot_frame(step);
        s.models = vec![rectum, fascia, pelvis];
        s
    }

    /// [`Rectum::snapshot`] as a job: the rod's pose copied, the membrane's drawn vertices
    /// placed and the rest read now; the meshes (the rod's skin, every normal) built later,
    /// on any thread, to the same snapshot.
    pub fn snapshot_job(&mut self, step: u64) -> SnapshotJob {
        let rod = self.scene.rod().mesh_later();
        let membrane = self.drawn.meshes_later(self.scene.membrane_mut());
        let mut s = self.snapshot_frame(step);
        SnapshotJob::later(move || {
            let (rectum, [fascia, pelvis]) = rayon::join(
                || {
                    let _span = tracing::debug_span!("rectum_snapshot_rod").entered();
                    rod()
                },
                membrane,
            );
            s.models = vec![rectum, fascia, pelvis];
            s
        })
    }

    /// A snapshot at `step` with everything but the models.
    fn snapshot_frame(&mut self, step: u64) -> Snapshot {
        let time_s = Self::time_s(step, self.scenario.dt_s);
        Snapshot {
            step,
            time_s,
            models: Vec::new(),
            tools: self.tools,
            reactions: self.reactions(),
            target_found: true,
            emissions: self.smoke.at(time_s),
            bleeding: Vec::new(),
            scope: self.scope.snapshot_view(),
            picture: None,
        }
    }

    /// Digest of the rod, the membrane and the task's progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        for v in [
            TissueModel::state_hash(self.scene.rod()),
            self.scene.membrane().state_hash(),
        ] {
            h.write(v as u32);
            h.write((v >> 32) as u32);
        }
        let (cut, _) = self.scene.target_progress();
        h.write(cut);
        h.write(self.metrics.steps_done.len() as u32);
        h.write(u32::from(self.right == RightTool::Grasper));
        h.0
    }
}

/// An `instrument_change` event's fields.
#[derive(Serialize)]
struct InstrumentChange {
    hand: &'static str,
    to: &'static str,
}

/// A `spring_cut` event's fields.
#[derive(Serialize)]
struct SpringCut {
    springs: u32,
    in_target: u32,
}

/// The plane where the hook cut (grid cells `cells`): how far the hook's end lies from the
/// middle of the cut links across the plane (along the line from layer 0 to layer 3 there),
/// m, and the angle between the shaft's axis `axis` and that line, degrees (0 to 90; none
/// when no cells were cut).
fn plane_geometry(scene: &RectumScene, end: Vec3, axis: Vec3, cells: &[u32]) -> (f32, Option<f32>) {
    let m = &scene.membrane();
    let cols = m.cols();
    if cells.is_empty() {
        return (0.0, None);
    }
    let (mut mid, mut normal) = (Vec3::ZERO, Vec3::ZERO);
    for &t in cells {
        let (i, j) = (t as usize / cols, t as usize % cols);
        mid += 0.5 * (m.position(m.node(1, i, j)) + m.position(m.node(2, i, j)));
        normal += m.position(m.node(LAYERS - 1, i, j)) - m.position(m.node(0, i, j));
    }
    let mid = mid / cells.len() as f32;
    let normal = normal.normalize_or_zero();
    let depth = (end - mid).dot(normal).abs();
    let a = axis.angle_between(normal).to_degrees();
    let angle =
        (normal != Vec3::ZERO && a.is_finite()).then_some(if a > 90.0 { 180.0 - a } else { a });
    (depth, angle)
}

#[cfg(test)]
#[path = "procedure_tests.rs"]
mod tests;

impl Rectum {
    /// The panel's live part: the paths, the plane cut, the right instrument's force, the
    /// share of correct cuts, what the right instrument touches or nears within `near_m`.
    pub(super) fn panel(&self, near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let (cut, total) = self.scene.target_progress();
        let near = self.near_now().filter(|(_, d)| *d <= near_m);
        TaskStatus {
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![
                ("plane cut".to_string(), format!("{cut} of {total} springs")),
                (
                    format!("{} force", self.right_name()),
                    format!("{:.2} N", self.reactions()[1].length()),
                ),
                (
                    "correct cuts".to_string(),
                    format!("{:.0} %", 100.0 * m.correct_cut_ratio),
                ),
                ("right hand".to_string(), self.right_name().to_string()),
            ],
            touching: [false, self.touching_now()],
            near: [None, near.map(|(n, d)| (n.to_string(), d))],
            ..TaskStatus::default()
        }
    }
}
