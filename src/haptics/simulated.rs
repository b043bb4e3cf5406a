//! The simulated stylus: a point mass of a few tens of grams held by a spring-damper "hand"
//! that follows a keyframed script, and pushed by the force the servo loop writes. It stands in
//! for a Phantom in tests, demos and `vesalius haptics --device sim`: deterministic, advanced
//! by each servo tick's dt, so a pressed stylus is pushed back by the tissue as a held one is.

use super::device::{
    DeviceKind, DeviceLimits, DeviceState, Drive, HapticDevice, HapticsError, PullDevice,
};
use glam::DVec3;

/// The stylus and the hand that holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StylusParams {
    /// The stylus' moving mass, kg (a Phantom Omni's arm feels like about 45 g). Default 0.03.
    pub mass_kg: f64,
    /// How stiffly the hand holds it, N/m. Default 200 (a relaxed grip).
    pub hand_stiffness_n_per_m: f64,
    /// The hand's damping on the stylus' motion relative to the hand, N s/m. Default 3.5
    /// (about 0.7 of critical with the defaults above).
    pub hand_damping_n_s_per_m: f64,
    /// The longest integration substep, s: a late servo tick is split so the stylus stays
    /// stable against the stiffest rendered tissue. Default 0.0005.
    pub max_substep_s: f64,
}

impl Default for StylusParams {
    fn default() -> Self {
        StylusParams {
            mass_kg: 0.03,
            hand_stiffness_n_per_m: 200.0,
            hand_damping_n_s_per_m: 3.5,
            max_substep_s: 0.0005,
        }
    }
}

/// One key of the hand's script: where the hand is at `t_s` and the buttons it holds from then
/// on. Positions interpolate linearly between keys.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    pub t_s: f64,
    /// The hand's target in the device's frame, m.
    pub position_m: DVec3,
    pub buttons: u32,
}

/// Why a script was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScriptError {
    #[error("a stylus script needs at least one key")]
    Empty,
    #[error("key {index}: time and position must be finite and times must not go back")]
    BadKey { index: usize },
    #[error("the repeat period must be finite and at least the last key's time")]
    BadRepeat,
}

/// Where the hand goes over time.
#[derive(Debug, Clone, PartialEq)]
pub struct Script {
    keys: Vec<Keyframe>,
    /// Plays again from its start every this many seconds (none: holds the last key).
    repeat_s: Option<f64>,
}

impl Script {
    /// The hand holds still at `position_m`.
    pub fn hold(position_m: DVec3) -> Script {
        Script {
            keys: vec![Keyframe {
                t_s: 0.0,
                position_m,
                buttons: 0,
            }],
            repeat_s: None,
        }
    }

    /// A keyframed script, keys in time order.
    pub fn keyframes(keys: Vec<Keyframe>, repeat_s: Option<f64>) -> Result<Script, ScriptError> {
        let last = keys.last().ok_or(ScriptError::Empty)?.t_s;
        for (index, k) in keys.iter().enumerate() {
            let back = index > 0 && k.t_s < keys[index - 1].t_s;
            if !k.t_s.is_finite() || !k.position_m.is_finite() || back {
                return Err(ScriptError::BadKey { index });
            }
        }
        if repeat_s.is_some_and(|r| !r.is_finite() || r < last || r <= 0.0) {
            return Err(ScriptError::BadRepeat);
        }
        Ok(Script { keys, repeat_s })
    }

    /// The press the `haptics` command plays, in the device's frame: held still 0.15 s (the
    /// start-up ramp waits for that), down 26 mm by 0.85 s, held to 1.05 s, back up by 1.45 s,
    /// again every 1.6 s. With the default workspace the stylus starts 11 mm above the
    /// sandbox's block and the hand goes 15 mm into it (the tissue holds the stylus back).
    pub fn press() -> Script {
        let key = |t_s: f64, y_m: f64| Keyframe {
            t_s,
            position_m: DVec3::new(0.0, y_m, 0.0),
            buttons: 0,
        };
        Script {
            keys: vec![
                key(0.0, 0.0),
                key(0.15, 0.0),
                key(0.55, -0.012),
                key(0.85, -0.026),
                key(1.05, -0.026),
                key(1.45, 0.0),
            ],
            repeat_s: Some(1.6),
        }
    }

    /// The hand's target, its velocity and the buttons at `t_s`.
    pub fn at(&self, t_s: f64) -> (DVec3, DVec3, u32) {
        let t = match self.repeat_s {
            Some(r) if t_s >= r => t_s.rem_euclid(r),
            _ => t_s,
        };
        let next = self.keys.partition_point(|k| k.t_s <= t);
        match (
            next.checked_sub(1).map(|i| &self.keys[i]),
            self.keys.get(next),
        ) {
            (Some(a), Some(b)) if b.t_s > a.t_s => {
                let s = (t - a.t_s) / (b.t_s - a.t_s);
                let v = (b.position_m - a.position_m) / (b.t_s - a.t_s);
                (a.position_m.lerp(b.position_m, s), v, a.buttons)
            }
            (Some(a), _) => (a.position_m, DVec3::ZERO, a.buttons),
            (None, Some(b)) => (b.position_m, DVec3::ZERO, b.buttons),
            (None, None) => (DVec3::ZERO, DVec3::ZERO, 0),
        }
    }
}

/// The simulated stylus (a pull device).
#[derive(Debug, Clone)]
pub struct SimulatedStylus {
    params: StylusParams,
    script: Script,
    t_s: f64,
    position_m: DVec3,
    velocity_m_per_s: DVec3,
    force_n: DVec3,
}

impl SimulatedStylus {
    /// The stylus at rest in the hand at the script's start.
    pub fn new(script: Script, params: StylusParams) -> SimulatedStylus {
        let (position_m, _, _) = script.at(0.0);
        SimulatedStylus {
            params,
            script,
            t_s: 0.0,
            position_m,
            velocity_m_per_s: DVec3::ZERO,
            force_n: DVec3::ZERO,
        }
    }

    /// Its own time, s (the sum of every dt it advanced by).
    pub fn time_s(&self) -> f64 {
        self.t_s
    }

    pub fn position_m(&self) -> DVec3 {
        self.position_m
    }

    pub fn velocity_m_per_s(&self) -> DVec3 {
        self.velocity_m_per_s
    }

    /// Where the hand wants it now.
    pub fn hand_m(&self) -> DVec3 {
        self.script.at(self.t_s).0
    }

    pub fn params(&self) -> &StylusParams {
        &self.params
    }
}

impl PullDevice for SimulatedStylus {
    fn read(&mut self) -> Result<DeviceState, HapticsError> {
        Ok(DeviceState {
            position_m: self.position_m,
            velocity_m_per_s: self.velocity_m_per_s,
            buttons: self.script.at(self.t_s).2,
        })
    }

    fn write_force(&mut self, force_n: DVec3) -> Result<(), HapticsError> {
        // A device renders nothing it cannot: a non-finite force is no force.
        self.force_n = if force_n.is_finite() {
            force_n
        } else {
            DVec3::ZERO
        };
        Ok(())
    }

    /// Semi-implicit Euler in substeps of at most `max_substep_s`.
    fn advance(&mut self, dt_s: f64) {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return;
        }
        let p = self.params;
        let n = (dt_s / p.max_substep_s.max(1e-6)).ceil().max(1.0);
        let h = dt_s / n;
        for _ in 0..n as u64 {
            let (hand, hand_v, _) = self.script.at(self.t_s + h);
            let pull = p.hand_stiffness_n_per_m * (hand - self.position_m)
                + p.hand_damping_n_s_per_m * (hand_v - self.velocity_m_per_s);
            self.velocity_m_per_s += (self.force_n + pull) / p.mass_kg * h;
            self.position_m += self.velocity_m_per_s * h;
            self.t_s += h;
        }
    }
}

impl HapticDevice for SimulatedStylus {
    fn name(&self) -> &str {
        DeviceKind::Simulated.name()
    }

    fn kind(&self) -> DeviceKind {
        DeviceKind::Simulated
    }

    fn limits(&self) -> DeviceLimits {
        DeviceKind::Simulated.table_limits()
    }

    fn drive(&mut self) -> Drive<'_> {
        Drive::Pull(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(s: &mut SimulatedStylus, seconds: f64) {
        for _ in 0..(seconds * 1000.0).round() as u64 {
            s.advance(0.001);
        }
    }

    #[test]
    fn the_hand_follows_its_script_and_holds_the_target() {
        let target = DVec3::new(0.01, -0.02, 0.005);
        let key = |t_s, position_m| Keyframe {
            t_s,
            position_m,
            buttons: 1,
        };
        let script =
            Script::keyframes(vec![key(0.0, DVec3::ZERO), key(0.3, target)], None).expect("keys");
        let mut s = SimulatedStylus::new(script, StylusParams::default());
        // Mid-way the hand is half-way and the stylus trails it by little (it is light).
        run(&mut s, 0.15);
        assert!((s.hand_m() - target * 0.5).length() < 1e-9);
        assert!(s.position_m().distance(s.hand_m()) < 0.002, "{s:?}");
        // After the move it settles on the held target.
        run(&mut s, 0.85);
        assert!(s.position_m().distance(target) < 1e-5, "{s:?}");
        assert!(s.velocity_m_per_s().length() < 1e-4);
        assert_eq!(s.read().map(|r| r.buttons).ok(), Some(1));
        assert!((s.time_s() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_constant_force_displaces_it_by_force_over_hand_stiffness() {
        let mut s = SimulatedStylus::new(Script::hold(DVec3::ZERO), StylusParams::default());
        let f = DVec3::new(0.0, 1.0, -0.5);
        s.write_force(f).expect("write");
        run(&mut s, 2.0);
        let expected = f / s.params().hand_stiffness_n_per_m;
        assert!(
            s.position_m().distance(expected) < 1e-6,
            "{:?} vs {expected:?}",
            s.position_m()
        );
        // A non-finite force is none: it returns to the hand.
        s.write_force(DVec3::new(f64::NAN, 0.0, 0.0))
            .expect("write");
        run(&mut s, 2.0);
        assert!(s.position_m().length() < 1e-6);
    }

    #[test]
    fn a_late_tick_is_integrated_in_stable_substeps() {
        let mut a = SimulatedStylus::new(Script::press(), StylusParams::default());
        let mut b = a.clone();
        for _ in 0..100 {
            a.advance(0.02);
        }
        for _ in 0..4000 {
            b.advance(0.0005);
        }
        assert!(a.position_m().is_finite());
        assert!(a.position_m().distance(b.position_m()) < 1e-9);
        // Same dt, same path: deterministic.
        let mut c = SimulatedStylus::new(Script::press(), StylusParams::default());
        for _ in 0..100 {
            c.advance(0.02);
        }
        assert_eq!(a.position_m(), c.position_m());
    }

    #[test]
    fn scripts_are_checked_and_repeat() {
        let k = |t_s: f64| Keyframe {
            t_s,
            position_m: DVec3::ZERO,
            buttons: 0,
        };
        assert_eq!(Script::keyframes(vec![], None), Err(ScriptError::Empty));
        assert_eq!(
            Script::keyframes(vec![k(1.0), k(0.5)], None),
            Err(ScriptError::BadKey { index: 1 })
        );
        assert_eq!(
            Script::keyframes(vec![k(0.0), k(f64::NAN)], None),
            Err(ScriptError::BadKey { index: 1 })
        );
        assert_eq!(
            Script::keyframes(vec![k(0.0), k(2.0)], Some(1.0)),
            Err(ScriptError::BadRepeat)
        );
        let p = Script::press();
        assert!(p.at(0.7).0.distance(p.at(2.3).0) < 1e-9);
        assert!(p.at(0.95).0.y < -0.02);
    }
}
