//! The force a device renders between simulation steps, and one servo tick's whole work.
//!
//! The simulation publishes a frame per step (every 2 ms in the sandbox); the device wants a
//! force every millisecond, and one that answers the stylus at once. Between frames the force
//! is the frame's contact force plus the frame's local stiffness times how far the stylus has
//! moved along the contact normal since the frame came: a stylus pressing deeper feels more
//! force before the simulation has caught up, and the next frame takes over from there.
//!
//! [`ServoCore`] is a tick without a thread or a clock of its own: it tracks frames, renders
//! the local model, passes the force through [`Safety`] and stamps the events with the newest
//! simulation step. The servo thread (and a push device's scheduler) calls it each tick.

use super::device::{DeviceKind, DeviceLimits, DeviceState};
use super::safety::{Safety, SafetyCounters, SafetyOutput, SafetyParams, TickInput};
use crate::sim::{Hand, HapticFrame, SimEvent, ToolHaptics};
use glam::{DVec3, Vec3};

/// How the device's workspace maps into the procedure's field: `field = offset + scale *
/// device` (axes aligned: x right, y up, z toward the user in both).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Workspace {
    /// Field metres per device metre. Default 1: forces and stiffnesses are felt as they are.
    pub scale: f64,
    /// Where the device's origin (its workspace centre) lands in the field, m. Default
    /// (0, 0.045, 0): 15 mm above the sandbox block's top centre.
    pub offset_m: Vec3,
}

impl Default for Workspace {
    fn default() -> Self {
        Workspace {
            scale: 1.0,
            offset_m: Vec3::new(0.0, 0.045, 0.0),
        }
    }
}

impl Workspace {
    /// A device position in the field, m.
    pub fn to_field(&self, device_m: DVec3) -> Vec3 {
        self.offset_m + (device_m * self.scale).as_vec3()
    }
}

/// The local force model: `tool`'s frame force plus `stiffness_n_per_m` times how much deeper
/// (against the frame's normal) the stylus is than when the frame came (`moved_m`, device
/// metres). A pushing contact never turns into a pull: the normal part stays at or above 0.
/// Without contact, or with no normal, the frame's force as it is.
pub fn local_force(tool: &ToolHaptics, stiffness_n_per_m: f64, moved_m: DVec3) -> DVec3 {
    let f = tool.force_n.as_dvec3();
    let n = tool.normal.as_dvec3();
    if !tool.in_contact || n == DVec3::ZERO {
        return f;
    }
    // A normal that is not unit (or not finite) is made unit (or poisons the force, which the
    // non-finite guard then zeroes).
    let n = n / n.length();
    let deeper_m = -moved_m.dot(n);
    let along = f.dot(n);
    let mut wanted = along + stiffness_n_per_m * deeper_m;
    if along >= 0.0 {
        wanted = wanted.max(0.0);
    }
    f + (wanted - along) * n
}

/// The most events one servo run keeps (a session drains them far more often than this).
pub const MAX_EVENTS: usize = 100_000;

/// One device's servo tick, clock-injected.
#[derive(Debug, Clone)]
pub struct ServoCore {
    hand: Hand,
    scale: f64,
    safety: Safety,
    /// The frame being rendered: its step and time (bits), and the stylus position when it
    /// came (none while the stylus reads non-finite).
    frame_key: Option<(u64, u64)>,
    anchor_m: Option<DVec3>,
    newest_step: u64,
    events: Vec<SimEvent>,
    dropped_events: u64,
    max_force_n: f64,
    last: Option<SafetyOutput>,
    /// The device whose clutch, while held, makes the wanted force zero (none: no clutch).
    clutch: Option<DeviceKind>,
}

impl ServoCore {
    /// The servo for the instrument in `hand`, on a device with `limits`, its workspace
    /// scaled by `scale` (field metres per device metre).
    pub fn new(limits: DeviceLimits, hand: Hand, scale: f64, params: SafetyParams) -> ServoCore {
        ServoCore {
            hand,
            scale: if scale.is_finite() && scale > 0.0 {
                scale
            } else {
                1.0
            },
            safety: Safety::new(limits, hand, params),
            frame_key: None,
            anchor_m: None,
            newest_step: 0,
            events: Vec::new(),
            dropped_events: 0,
            max_force_n: 0.0,
            last: None,
            clutch: None,
        }
    }

    /// The same servo, wanting no force while `kind`'s clutch is held (see
    /// [`super::clutch`]): the instrument is decoupled from the hand.
    pub fn with_clutch(mut self, kind: DeviceKind) -> ServoCore {
        self.clutch = Some(kind);
        self
    }

    /// One tick at `now_s` with the stylus' `state` and the newest `frame`: the force to write.
    pub fn tick(&mut self, now_s: f64, state: &DeviceState, frame: &HapticFrame) -> DVec3 {
        // The slot's default frame (step 0 at time 0) is no frame; the first step's has its
        // time after the step.
        let have_frame = !(frame.step == 0 && frame.time_s == 0.0);
        let key = (frame.step, frame.time_s.to_bits());
        let new_frame = have_frame && self.frame_key != Some(key);
        let position = state.position_m;
        if new_frame {
            self.frame_key = Some(key);
            self.newest_step = frame.step;
            self.anchor_m = position.is_finite().then_some(position);
        } else if self.anchor_m.is_none() && position.is_finite() {
            self.anchor_m = Some(position);
        }
        let tool = frame.tools[self.hand.index()];
        let coupled = !self.clutch.is_some_and(|k| k.clutched(state.buttons));
        let render = have_frame && coupled;
        let stiffness = if render && tool.in_contact {
            f64::from(tool.stiffness_n_per_m) * self.scale
        } else {
            0.0
        };
        let input = TickInput {
            now_s,
            new_frame,
            have_frame,
            state: *state,
            stiffness_n_per_m: stiffness,
        };
        let anchor = self.anchor_m.unwrap_or(position);
        let out = self.safety.tick(&input, |k| {
            if render {
                local_force(&tool, k, position - anchor)
            } else {
                DVec3::ZERO
            }
        });
        let step = self.newest_step;
        for kind in self.safety.take_events() {
            if self.events.len() < MAX_EVENTS {
                self.events.push(SimEvent { step, kind });
            } else {
                self.dropped_events += 1;
            }
        }
        self.max_force_n = self.max_force_n.max(out.force_n.length());
        self.last = Some(out);
        out.force_n
    }

    /// The last tick's output, gains included.
    pub fn last(&self) -> Option<&SafetyOutput> {
        self.last.as_ref()
    }

    pub fn hand(&self) -> Hand {
        self.hand
    }

    /// Forces are still off at start-up (see [`Safety::held_off`]).
    pub fn held_off(&self) -> bool {
        self.safety.held_off()
    }

    pub fn limits(&self) -> DeviceLimits {
        self.safety.limits()
    }

    pub fn counters(&self) -> SafetyCounters {
        self.safety.counters()
    }

    /// The largest force written so far, N.
    pub fn max_force_n(&self) -> f64 {
        self.max_force_n
    }

    /// The events so far, each stamped with the newest simulation step at its tick; the
    /// session puts them in its stream.
    pub fn take_events(&mut self) -> Vec<SimEvent> {
        std::mem::take(&mut self.events)
    }

    /// Events not kept because more than [`MAX_EVENTS`] waited.
    pub fn dropped_events(&self) -> u64 {
        self.dropped_events
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contact(force_n: Vec3, normal: Vec3, k: f32) -> ToolHaptics {
        ToolHaptics {
            force_n,
            point: Vec3::ZERO,
            normal,
            stiffness_n_per_m: k,
            in_contact: true,
        }
    }

    #[test]
    fn a_millimetre_deeper_adds_stiffness_times_a_millimetre() {
        let n = Vec3::new(0.0, 0.6, 0.8);
        let f = Vec3::new(0.2, 1.1, 0.7);
        let k = 450.0;
        let tool = contact(f, n, k);
        let deeper = -n.as_dvec3() * 0.001;
        let got = local_force(&tool, f64::from(k), deeper);
        let want = f.as_dvec3() + f64::from(k) * 0.001 * n.as_dvec3();
        assert!(got.distance(want) < 1e-9, "{got:?} vs {want:?}");
        // Sideways motion changes nothing; a millimetre out takes it off again.
        let side = DVec3::new(0.001, 0.0, 0.0);
        assert!(local_force(&tool, 450.0, side).distance(f.as_dvec3()) < 1e-9);
        let out = local_force(&tool, 450.0, n.as_dvec3() * 0.001);
        let want = f.as_dvec3() - 0.45 * n.as_dvec3();
        assert!(out.distance(want) < 1e-9);
        // Far out, the push ends at zero along the normal; it never pulls.
        let far = local_force(&tool, 450.0, n.as_dvec3() * 0.05);
        assert!(far.dot(n.as_dvec3()).abs() < 1e-9, "{far:?}");
        // No contact: the frame's force alone.
        let free = ToolHaptics {
            in_contact: false,
            ..tool
        };
        assert_eq!(local_force(&free, 450.0, deeper), f.as_dvec3());
    }

    #[test]
    fn the_servo_renders_the_local_model_through_the_frame_it_tracks() {
        let limits = DeviceLimits {
            max_force_n: 100.0,
            max_stiffness_n_per_m: 1e4,
        };
        let params = SafetyParams {
            still_hold_s: 0.0,
            ramp_up_s: 1e-9,
            recover_s: 1e-9,
            small_force_n: 1.0,
            ..SafetyParams::default()
        };
        let mut servo = ServoCore::new(limits, Hand::Right, 1.0, params);
        let n = Vec3::Y;
        let mut frame = HapticFrame {
            step: 0,
            time_s: 0.002,
            tools: [ToolHaptics::default(); 2],
        };
        frame.tools[1] = contact(Vec3::new(0.0, 0.2, 0.0), n, 300.0);
        let at = |y: f64| DeviceState {
            position_m: DVec3::new(0.0, y, 0.0),
            ..DeviceState::default()
        };
        // Still and small: the ramp starts and completes; the frame's force alone.
        let mut t = 0.0;
        for _ in 0..5 {
            servo.tick(t, &at(0.0), &frame);
            t += 0.001;
        }
        let f = servo.tick(t, &at(0.0), &frame);
        assert!((f.y - 0.2).abs() < 1e-6, "{f:?}");
        // 1 mm deeper in the same frame: 0.3 N more at once.
        t += 0.001;
        let f = servo.tick(t, &at(-0.001), &frame);
        assert!((f.y - 0.5).abs() < 1e-6, "{f:?}");
        // A new frame anchors where the stylus is now.
        frame.step = 1;
        frame.time_s = 0.004;
        frame.tools[1].force_n = Vec3::new(0.0, 0.5, 0.0);
        t += 0.001;
        let f = servo.tick(t, &at(-0.001), &frame);
        assert!((f.y - 0.5).abs() < 1e-6, "{f:?}");
        // The other hand's frame is not this device's.
        frame.tools[0] = contact(Vec3::splat(50.0), n, 1e4);
        t += 0.001;
        let f = servo.tick(t, &at(-0.001), &frame);
        assert!((f.y - 0.5).abs() < 1e-6, "{f:?}");
        assert_eq!(servo.counters().clamps, 0);
        assert!(servo.max_force_n() >= 0.5 - 1e-6);
        // The workspace scale turns field stiffness into device stiffness.
        let mut half = ServoCore::new(limits, Hand::Right, 0.5, params);
        frame.tools[0] = ToolHaptics::default();
        let mut t = 0.0;
        for _ in 0..6 {
            half.tick(t, &at(0.0), &frame);
            t += 0.001;
        }
        let f = half.tick(t, &at(-0.001), &frame);
        assert!((f.y - (0.5 + 0.15)).abs() < 1e-6, "{f:?}");
        // A held clutch decouples the hand: no force, however deep; let go, the force is back.
        let mut clutched =
            ServoCore::new(limits, Hand::Right, 1.0, params).with_clutch(super::DeviceKind::Falcon);
        let press = |buttons| DeviceState {
            buttons,
            ..at(-0.001)
        };
        let mut t = 0.0;
        for _ in 0..6 {
            clutched.tick(t, &at(0.0), &frame);
            t += 0.001;
        }
        let held = crate::haptics::clutch::CLUTCH_BUTTON;
        assert_eq!(clutched.tick(t, &press(held), &frame), DVec3::ZERO);
        t += 0.001;
        let f = clutched.tick(t, &press(0), &frame);
        assert!((f.y - 0.8).abs() < 1e-6, "{f:?}");
    }

    #[test]
    fn the_workspace_maps_device_metres_into_the_field() {
        let w = Workspace::default();
        assert_eq!(w.to_field(DVec3::ZERO), Vec3::new(0.0, 0.045, 0.0));
        let w = Workspace {
            scale: 0.5,
            offset_m: Vec3::new(0.1, 0.0, 0.0),
        };
        assert!(
            w.to_field(DVec3::new(0.02, -0.04, 0.0))
                .distance(Vec3::new(0.11, -0.02, 0.0))
                < 1e-7
        );
    }
}
