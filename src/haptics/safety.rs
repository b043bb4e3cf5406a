//! Force safety for one device: pure and clock-injected (every call says what time it is), so
//! the tests drive it for a million ticks without a thread or a device.
//!
//! Each servo tick passes through, in order:
//! 1. **Non-finite guard**: a non-finite stiffness, stylus position or velocity, or rendered
//!    force gives zero force; the hold gain drops to 0 and ramps back once values are finite.
//! 2. **Clamps**: the local stiffness to the device's maximum before the force is rendered with
//!    it, then the force's magnitude to the device's maximum force.
//! 3. **Stall watchdog**: when no new simulation frame has come for `stall_after_s` (10 ms) the
//!    hold gain halves on the tick that sees it and is zero from the next (2 ticks: within
//!    `stall_fade_s`, 2 ms, at 1 kHz); when frames come again it ramps back to 1 over
//!    `recover_s`, so the force returns smoothly.
//! 4. **Start-up ramp**: the start-up gain stays 0 until the stylus has been still (speed below
//!    `still_speed_m_per_s`) with a small force for `still_hold_s`, then rises to 1 over
//!    `ramp_up_s` (2 s), so a stylus held in tissue at start does not kick.
//!
//! The force written is the clamped force times both gains: never above the device's limit,
//! always finite. Every clamp, stall, ramp and non-finite value is an event (raised once when
//! its run of ticks begins, so a held press is one event, not a thousand a second) and a count;
//! a tick with a non-finite value ends every run of clamps.

use super::device::{DeviceLimits, DeviceState};
use crate::sim::{EventKind, Hand};
use glam::DVec3;

/// The safety rules' figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyParams {
    /// The stylus counts as still below this speed, m/s. Default 0.01.
    pub still_speed_m_per_s: f64,
    /// ...held for this long, s, before the start-up ramp begins. Default 0.1.
    pub still_hold_s: f64,
    /// ...and only while the force it would get is below this, N. Default 0.25.
    pub small_force_n: f64,
    /// The start-up ramp's length, gain 0 to 1, s. Default 2.
    pub ramp_up_s: f64,
    /// Forces still held off this long after the first tick (the stylus kept moving, or held
    /// in the tissue) raise one `held_off` ramp event, so the user can be told why, s.
    /// Default 1.
    pub held_off_note_s: f64,
    /// No new frame for this long is a stall, s. Default 0.010.
    pub stall_after_s: f64,
    /// A stall seen this long or more after it began zeroes the force at once (otherwise it
    /// is halved on the tick that sees it and zero from the next), s. Default 0.002.
    pub stall_fade_s: f64,
    /// After a stall or a non-finite value the gain returns 0 to 1 over this long, s: at
    /// 1 kHz the force changes at most `max_force_n * 0.001 / recover_s` a tick from it.
    /// Default 0.25.
    pub recover_s: f64,
    /// Clamped ticks less than this apart are one clamp (a force hovering at the limit is one
    /// event, not one each time it dips under), s. Default 0.05.
    pub clamp_merge_s: f64,
}

impl Default for SafetyParams {
    fn default() -> Self {
        SafetyParams {
            still_speed_m_per_s: 0.01,
            still_hold_s: 0.1,
            small_force_n: 0.25,
            ramp_up_s: 2.0,
            held_off_note_s: 1.0,
            stall_after_s: 0.010,
            stall_fade_s: 0.002,
            recover_s: 0.25,
            clamp_merge_s: 0.05,
        }
    }
}

/// How many times each rule acted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SafetyCounters {
    pub ticks: u64,
    /// Clamp events (runs of clamped ticks, force and stiffness apart; see
    /// [`SafetyParams::clamp_merge_s`]).
    pub clamps: u64,
    /// Ticks whose force or stiffness was clamped.
    pub clamped_ticks: u64,
    /// Stalls begun.
    pub stalls: u64,
    /// Non-finite events (runs of ticks with a non-finite value).
    pub non_finite: u64,
    pub non_finite_ticks: u64,
    /// Ramp events (start-up begun and done, recovery begun and done).
    pub ramps: u64,
}

/// What one tick brings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickInput {
    /// The injected clock, s (non-decreasing; a step back counts as no time passing).
    pub now_s: f64,
    /// Whether a frame newer than the last tick's has come from the simulation.
    pub new_frame: bool,
    /// Whether any frame has come yet (before the first there is no stall, only no force).
    pub have_frame: bool,
    pub state: DeviceState,
    /// The frame's local stiffness as the device feels it, N/m of stylus motion.
    pub stiffness_n_per_m: f64,
}

/// What one tick gives the device, and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyOutput {
    /// The force to write, N: finite, at most the device's maximum.
    pub force_n: DVec3,
    /// The start-up gain, 0-1.
    pub startup_gain: f64,
    /// The stall and non-finite hold gain, 0-1.
    pub hold_gain: f64,
    /// No new frame for `stall_after_s` (or none yet).
    pub stalled: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Startup {
    /// Gain 0 until the stylus is still (since when, if it is); waiting since `from_s` (the
    /// first tick), and whether that was said (`held_off`).
    Waiting {
        still_since_s: Option<f64>,
        from_s: Option<f64>,
        noted: bool,
    },
    /// Gain rising since `from_s`.
    Ramping {
        from_s: f64,
    },
    Running,
}

/// The safety state of one device.
#[derive(Debug, Clone)]
pub struct Safety {
    params: SafetyParams,
    limits: DeviceLimits,
    hand: Hand,
    startup: Startup,
    hold_gain: f64,
    last_tick_s: Option<f64>,
    last_frame_s: Option<f64>,
    /// When the current stall began (its frame's time plus `stall_after_s`).
    stall_from_s: Option<f64>,
    /// The hold gain was cut by a stall or a non-finite value: `recover` is announced when it
    /// starts rising again, `recovered` when it is back at 1.
    recovering: bool,
    recover_announced: bool,
    /// When the force and the stiffness were last clamped (none: not in a run of clamps).
    force_clamped_s: Option<f64>,
    stiffness_clamped_s: Option<f64>,
    non_finite_run: bool,
    events: Vec<EventKind>,
    counters: SafetyCounters,
}

/// Forces are clamped a hair under the limit, so rounding in the gains never lifts the
/// written magnitude above it.
const UNDER: f64 = 1.0 - 1e-9;

/// `v` limited to `max` in magnitude: the result, the magnitude asked for, and whether it was
/// limited. Safe for huge finite components (no overflow on the way).
pub fn clamp_magnitude(v: DVec3, max: f64) -> (DVec3, f64, bool) {
    let big = v.abs().max_element();
    if big == 0.0 || !big.is_finite() {
        return (v, big, false);
    }
    let unit = v / big;
    let len = big * unit.length();
    if len <= max * UNDER {
        (v, len, false)
    } else {
        (unit.normalize_or_zero() * (max * UNDER), len, true)
    }
}

/// An f64 for an event field (f32), saturating instead of going infinite.
fn field(x: f64) -> f32 {
    x.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32
}

impl Safety {
    pub fn new(limits: DeviceLimits, hand: Hand, params: SafetyParams) -> Safety {
        Safety {
            params,
            limits,
            hand,
            startup: Startup::Waiting {
                still_since_s: None,
                from_s: None,
                noted: false,
            },
            hold_gain: 0.0,
            last_tick_s: None,
            last_frame_s: None,
            stall_from_s: None,
            recovering: false,
            recover_announced: false,
            force_clamped_s: None,
            stiffness_clamped_s: None,
            non_finite_run: false,
            events: Vec::new(),
            counters: SafetyCounters::default(),
        }
    }

    pub fn limits(&self) -> DeviceLimits {
        self.limits
    }

    pub fn params(&self) -> &SafetyParams {
        &self.params
    }

    pub fn counters(&self) -> SafetyCounters {
        self.counters
    }

    /// The events raised since the last call, oldest first.
    pub fn take_events(&mut self) -> impl Iterator<Item = EventKind> + '_ {
        self.events.drain(..)
    }

    fn raise(&mut self, kind: EventKind) {
        match kind {
            EventKind::HapticClamp { .. } => self.counters.clamps += 1,
            EventKind::HapticStall { .. } => {}
            EventKind::HapticRamp { .. } => self.counters.ramps += 1,
            EventKind::HapticNonFinite { .. } => self.counters.non_finite += 1,
            _ => {}
        }
        self.events.push(kind);
    }

    fn ramp(&mut self, phase: &str, gain: f64) {
        self.raise(EventKind::HapticRamp {
            hand: self.hand.name().to_string(),
            phase: phase.to_string(),
            gain: field(gain),
        });
    }

    fn clamp_event(&mut self, quantity: &str, requested: f64, limit: f64) {
        self.raise(EventKind::HapticClamp {
            hand: self.hand.name().to_string(),
            quantity: quantity.to_string(),
            requested: field(requested),
            limit: field(limit),
        });
    }

    /// One tick: `render` turns the clamped stiffness (N/m) into the force the model asks
    /// for, N (it is not called when the stylus' state is not finite).
    pub fn tick(&mut self, input: &TickInput, render: impl FnOnce(f64) -> DVec3) -> SafetyOutput {
        self.counters.ticks += 1;
        // The clock: a step back or a non-finite reading is no time passing.
        let now = match (self.last_tick_s, input.now_s.is_finite()) {
            (Some(last), true) => input.now_s.max(last),
            (Some(last), false) => last,
            (None, true) => input.now_s,
            (None, false) => 0.0,
        };
        let dt = self.last_tick_s.map_or(0.0, |last| now - last);
        self.last_tick_s = Some(now);

        let (stalled, stall_began) = self.watch_frames(input, now);

        // Non-finite values: zero force, the hold gain to 0, an event when the run begins.
        let k_in = input.stiffness_n_per_m;
        let bad = if !k_in.is_finite() {
            Some("stiffness")
        } else if !input.state.position_m.is_finite() {
            Some("position")
        } else if !input.state.velocity_m_per_s.is_finite() {
            Some("velocity")
        } else {
            None
        };
        let (requested, bad) = match bad {
            Some(what) => (DVec3::ZERO, Some(what)),
            None => {
                let k = self.clamp_stiffness(k_in, now);
                let f = render(k);
                (f, (!f.is_finite()).then_some("force"))
            }
        };
        if let Some(what) = bad {
            self.counters.non_finite_ticks += 1;
            if !self.non_finite_run {
                self.raise(EventKind::HapticNonFinite {
                    hand: self.hand.name().to_string(),
                    what: what.to_string(),
                });
            }
            self.non_finite_run = true;
            self.hold_gain = 0.0;
            self.cut_hold();
            // A bad tick ends every run of clamps.
            self.force_clamped_s = None;
            self.stiffness_clamped_s = None;
            if let Startup::Waiting { still_since_s, .. } = &mut self.startup {
                *still_since_s = None;
            }
            return SafetyOutput {
                force_n: DVec3::ZERO,
                startup_gain: self.startup_gain(now),
                hold_gain: 0.0,
                stalled,
            };
        }
        self.non_finite_run = false;

        let (force, asked_n, clamped) = clamp_magnitude(requested, self.limits.max_force_n);
        if clamped {
            self.counters.clamped_ticks += 1;
            if self.new_clamp(self.force_clamped_s, now) {
                self.clamp_event("force_n", asked_n, self.limits.max_force_n);
            }
            self.force_clamped_s = Some(now);
        }

        self.hold(stalled, stall_began, now, dt);
        self.start_up(&input.state, force.length(), now);
        let startup_gain = self.startup_gain(now);
        SafetyOutput {
            force_n: force * (startup_gain * self.hold_gain),
            startup_gain,
            hold_gain: self.hold_gain,
            stalled,
        }
    }

    /// Whether a clamp now begins a new run (the last was `clamp_merge_s` or more ago).
    fn new_clamp(&self, last_s: Option<f64>, now: f64) -> bool {
        last_s.is_none_or(|last| now - last >= self.params.clamp_merge_s)
    }

    /// The stiffness limited to the device's: non-negative, at most the maximum.
    fn clamp_stiffness(&mut self, k: f64, now: f64) -> f64 {
        let max = self.limits.max_stiffness_n_per_m;
        if k > max {
            self.counters.clamped_ticks += 1;
            if self.new_clamp(self.stiffness_clamped_s, now) {
                self.clamp_event("stiffness_n_per_m", k, max);
            }
            self.stiffness_clamped_s = Some(now);
        }
        k.clamp(0.0, max)
    }

    /// Tracks frames: whether the simulation is stalled (or has sent nothing yet), and
    /// whether the stall began with this tick.
    fn watch_frames(&mut self, input: &TickInput, now: f64) -> (bool, bool) {
        let p = self.params;
        if input.new_frame && input.have_frame {
            if let (Some(_), Some(last)) = (self.stall_from_s, self.last_frame_s) {
                self.raise(EventKind::HapticStall {
                    hand: self.hand.name().to_string(),
                    phase: "end".to_string(),
                    silent_s: field(now - last),
                });
                self.stall_from_s = None;
            }
            self.last_frame_s = Some(now);
        }
        let Some(last) = self.last_frame_s.filter(|_| input.have_frame) else {
            return (true, false);
        };
        let silent = now - last;
        let begins = silent >= p.stall_after_s && self.stall_from_s.is_none();
        if begins {
            self.stall_from_s = Some(last + p.stall_after_s);
            self.counters.stalls += 1;
            self.cut_hold();
            self.raise(EventKind::HapticStall {
                hand: self.hand.name().to_string(),
                phase: "begin".to_string(),
                silent_s: field(silent),
            });
        }
        (self.stall_from_s.is_some(), begins)
    }

    /// The hold gain. A stall halves it on the tick the stall is seen and zeroes it on the
    /// next, or at once when the stall is seen `stall_fade_s` or more after it began: zero
    /// within 2 ticks, and within 2 ms at 1 kHz. Otherwise it rises over `recover_s`.
    fn hold(&mut self, stalled: bool, began: bool, now: f64, dt: f64) {
        let p = self.params;
        if stalled {
            self.hold_gain = match self.stall_from_s {
                Some(from) if began && now < from + p.stall_fade_s => self.hold_gain.min(0.5),
                _ => 0.0,
            };
        } else if self.hold_gain < 1.0 {
            if self.recovering && !self.recover_announced {
                self.recover_announced = true;
                self.ramp("recover", self.hold_gain);
            }
            self.hold_gain = (self.hold_gain + dt / p.recover_s.max(1e-9)).min(1.0);
            if self.hold_gain >= 1.0 && self.recovering {
                self.recovering = false;
                self.ramp("recovered", 1.0);
            }
        } else {
            // Cut and back within a tick (a stall that ended before its fade began).
            self.recovering = false;
        }
    }

    /// The hold gain is being cut: its recovery will be announced.
    fn cut_hold(&mut self) {
        self.recovering = true;
        self.recover_announced = false;
    }

    /// Advances the start-up ramp: waiting for stillness, ramping, running.
    fn start_up(&mut self, state: &DeviceState, force_n: f64, now: f64) {
        let p = self.params;
        match self.startup {
            Startup::Waiting {
                still_since_s,
                from_s,
                mut noted,
            } => {
                let moving = state.velocity_m_per_s.length() >= p.still_speed_m_per_s;
                let pressing = force_n >= p.small_force_n;
                let since = (!moving && !pressing).then(|| still_since_s.unwrap_or(now));
                let from_s = from_s.unwrap_or(now);
                self.startup = match since {
                    Some(s) if now - s >= p.still_hold_s => {
                        self.ramp("start", 0.0);
                        Startup::Ramping { from_s: now }
                    }
                    _ => {
                        if !noted && now - from_s >= p.held_off_note_s {
                            noted = true;
                            self.ramp("held_off", 0.0);
                        }
                        Startup::Waiting {
                            still_since_s: since,
                            from_s: Some(from_s),
                            noted,
                        }
                    }
                };
            }
            Startup::Ramping { from_s } => {
                if now - from_s >= p.ramp_up_s {
                    self.ramp("full", 1.0);
                    self.startup = Startup::Running;
                }
            }
            Startup::Running => {}
        }
    }

    /// Forces are still off at start-up, past [`SafetyParams::held_off_note_s`]: the
    /// stylus keeps moving or is held in the tissue.
    pub fn held_off(&self) -> bool {
        matches!(self.startup, Startup::Waiting { noted: true, .. })
    }

    fn startup_gain(&self, now: f64) -> f64 {
        match self.startup {
            Startup::Waiting { .. } => 0.0,
            Startup::Ramping { from_s } => ((now - from_s) / self.params.ramp_up_s).clamp(0.0, 1.0),
            Startup::Running => 1.0,
        }
    }
}

#[cfg(test)]
#[path = "safety_tests.rs"]
mod tests;
