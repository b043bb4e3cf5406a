//! Safety against an injected clock: a million adversarial ticks, the stall watchdog, the
//! start-up ramp, clamps and non-finite values. No thread, no timing assertion.

use super::*;
use crate::haptics::device::DeviceKind;

const LIMIT_N: f64 = 3.3;
const LIMIT_K: f64 = 700.0;

fn omni() -> Safety {
    Safety::new(
        DeviceKind::PhantomOmni.table_limits(),
        Hand::Right,
        SafetyParams::default(),
    )
}

/// A small deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }
    fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
    fn vec(&mut self, r: f64) -> DVec3 {
        DVec3::new(self.range(-r, r), self.range(-r, r), self.range(-r, r))
    }
    fn poison(&mut self) -> f64 {
        [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][(self.next() % 3) as usize]
    }
}

fn still() -> DeviceState {
    DeviceState::default()
}

fn input(now_s: f64, new_frame: bool, state: DeviceState, k: f64) -> TickInput {
    TickInput {
        now_s,
        new_frame,
        have_frame: true,
        state,
        stiffness_n_per_m: k,
    }
}

/// Counts of events by kind (and by phase or quantity where they have one).
#[derive(Debug, Default, PartialEq, Eq)]
struct Seen {
    clamp_force: u64,
    clamp_stiffness: u64,
    stall_begin: u64,
    stall_end: u64,
    non_finite: u64,
    ramp_start: u64,
    ramp_full: u64,
    held_off: u64,
    recover: u64,
    recovered: u64,
}

impl Seen {
    fn count(&mut self, s: &mut Safety) {
        for e in s.take_events() {
            match e {
                EventKind::HapticClamp { quantity, .. } if quantity == "force_n" => {
                    self.clamp_force += 1
                }
                EventKind::HapticClamp { .. } => self.clamp_stiffness += 1,
                EventKind::HapticStall { phase, .. } if phase == "begin" => self.stall_begin += 1,
                EventKind::HapticStall { .. } => self.stall_end += 1,
                EventKind::HapticNonFinite { .. } => self.non_finite += 1,
                EventKind::HapticRamp { phase, .. } => match phase.as_str() {
                    "start" => self.ramp_start += 1,
                    "full" => self.ramp_full += 1,
                    "held_off" => self.held_off += 1,
                    "recover" => self.recover += 1,
                    _ => self.recovered += 1,
                },
                other => panic!("not a safety event: {other:?}"),
            }
        }
    }
}

/// Runs `ticks` quiet ticks (still, no force, a frame every other tick) from `t`: the start-up
/// ramp completes if it is long enough. Returns the time after.
fn quiet(s: &mut Safety, seen: &mut Seen, mut t: f64, ticks: u64) -> f64 {
    for k in 0..ticks {
        s.tick(&input(t, k % 2 == 0, still(), 0.0), |_| DVec3::ZERO);
        seen.count(s);
        t += 0.001;
    }
    t
}

#[test]
fn a_million_adversarial_ticks_stay_finite_within_the_limit_and_every_rule_is_an_event() {
    let mut s = omni();
    let p = *s.params();
    let mut seen = Seen::default();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    // The start-up ramp completes first, so the chaos meets full gain.
    let mut t = quiet(&mut s, &mut seen, 0.0, 2500);
    assert_eq!((seen.ramp_start, seen.ramp_full), (1, 1));

    // What the rules should do, worked out from the inputs alone.
    let mut want = Seen {
        ramp_start: 1,
        ramp_full: 1,
        ..Seen::default()
    };
    let mut bad_run = false;
    // When the stiffness and the force were last clamped, in the current runs.
    let (mut k_last, mut f_last): (Option<f64>, Option<f64>) = (None, None);
    let new_run = |last: Option<f64>, t: f64| last.is_none_or(|l| t - l >= p.clamp_merge_s);
    let mut last_frame = t;
    let mut stall_ticks = 0u32;
    let mut stall_from: Option<f64> = None;
    let mut silence_left = 0u32;
    let mut position = DVec3::ZERO;
    let mut prev_hold = s
        .tick(&input(t, true, still(), 0.0), |_| DVec3::ZERO)
        .hold_gain;
    seen.count(&mut s);
    let (mut zero_checks, mut max_seen) = (0u64, 0.0f64);

    for _ in 0..1_000_000 {
        // The clock: mostly 1 ms, sometimes a late tick of up to 5 ms.
        let dt = if rng.chance(0.01) {
            rng.range(0.001, 0.005)
        } else {
            0.001
        };
        t += dt;
        // Frames: every tick or two, and now and then a silence of up to 60 ms.
        if silence_left == 0 && rng.chance(1.0 / 1500.0) {
            silence_left = rng.range(1.0, 60.0) as u32;
        }
        let new_frame = if silence_left > 0 {
            silence_left -= 1;
            false
        } else {
            rng.chance(0.6)
        };
        // The stylus: wanders, teleports, goes non-finite.
        position += rng.vec(0.0005);
        if rng.chance(0.002) {
            position = rng.vec(1.0);
        }
        let speed = if rng.chance(0.01) { 1e6 } else { 0.2 };
        let mut state = DeviceState {
            position_m: position,
            velocity_m_per_s: rng.vec(speed),
            buttons: 0,
        };
        if rng.chance(0.001) {
            state.position_m.y = rng.poison();
        }
        if rng.chance(0.001) {
            state.velocity_m_per_s.z = rng.poison();
        }
        // The model: moderate forces, huge ones, non-finite ones; stiffnesses likewise.
        let mut force = rng.vec(4.0);
        if rng.chance(0.005) {
            force *= 10f64.powf(rng.range(2.0, 300.0));
        }
        if rng.chance(0.001) {
            force.x = rng.poison();
        }
        let mut k = rng.range(0.0, 1500.0);
        if rng.chance(0.005) {
            k = 1e30;
        }
        if rng.chance(0.001) {
            k = rng.poison();
        }

        // The reference.
        if new_frame {
            if stall_from.take().is_some() {
                want.stall_end += 1;
            }
            last_frame = t;
        } else if stall_from.is_none() && t - last_frame >= p.stall_after_s {
            stall_from = Some(last_frame + p.stall_after_s);
            want.stall_begin += 1;
            stall_ticks = 0;
        }
        let pose_ok = k.is_finite() && state.is_finite();
        let mut bad = !pose_ok;
        if pose_ok {
            if k > LIMIT_K {
                want.clamp_stiffness += u64::from(new_run(k_last, t));
                k_last = Some(t);
            }
            bad = !force.is_finite();
        }
        if bad {
            want.non_finite += u64::from(!bad_run);
            (k_last, f_last) = (None, None);
        } else if force.length() > LIMIT_N {
            want.clamp_force += u64::from(new_run(f_last, t));
            f_last = Some(t);
        }
        bad_run = bad;

        let mut rendered_with = None;
        let out = s.tick(&input(t, new_frame, state, k), |k| {
            rendered_with = Some(k);
            force
        });
        seen.count(&mut s);

        // Always finite, never above the limit; the stiffness handed on never above its own.
        assert!(out.force_n.is_finite(), "{out:?}");
        let f = out.force_n.length();
        assert!(f <= LIMIT_N, "{f} N at {t}");
        max_seen = max_seen.max(f);
        assert!(rendered_with.is_none_or(|k| (0.0..=LIMIT_K).contains(&k)));
        if bad {
            assert_eq!(out.force_n, DVec3::ZERO);
        }
        // A stall: zero force from its second tick, and from 2 ms after it began.
        if let Some(from) = stall_from {
            assert!(out.stalled);
            stall_ticks += 1;
            if stall_ticks >= 2 || t >= from + p.stall_fade_s {
                assert_eq!(out.force_n, DVec3::ZERO, "{t} s, stall from {from} s");
                zero_checks += 1;
            }
        }
        // The hold gain comes back no faster than the recovery rate.
        assert!(
            out.hold_gain - prev_hold <= dt / p.recover_s + 1e-12,
            "jump {} -> {} at {t}",
            prev_hold,
            out.hold_gain
        );
        prev_hold = out.hold_gain;
    }

    // Every rule acted, and each time it was an event.
    assert!(
        want.clamp_force > 100 && want.clamp_stiffness > 100,
        "{want:?}"
    );
    assert!(want.stall_begin > 100 && want.non_finite > 100, "{want:?}");
    assert!(zero_checks > 1000 && max_seen > 3.0);
    let Seen {
        recover, recovered, ..
    } = seen;
    assert_eq!(
        Seen {
            recover: 0,
            recovered: 0,
            ..seen
        },
        want
    );
    assert!(recover > 100 && recovered > 0 && recovered <= recover);
    let c = s.counters();
    assert_eq!(c.clamps, want.clamp_force + want.clamp_stiffness);
    assert_eq!(c.stalls, want.stall_begin);
    assert_eq!(c.non_finite, want.non_finite);
    assert_eq!(c.ramps, 2 + recover + recovered);
}

#[test]
fn a_stall_zeroes_the_force_within_two_ticks_and_it_comes_back_smoothly() {
    let mut s = omni();
    let p = *s.params();
    let mut seen = Seen::default();
    let two_n = DVec3::new(0.0, 2.0, 0.0);
    // Frames every 2 ms, a still stylus, a 0.1 N press: the ramp runs to full.
    let mut t = 0.0;
    for k in 0..2500 {
        s.tick(&input(t, k % 2 == 0, still(), 0.0), |_| two_n * 0.05);
        t += 0.001;
    }
    seen.count(&mut s);
    assert_eq!(seen.ramp_full, 1);
    // Pressing with 2 N, frames coming: 2 N out.
    let mut last_frame = 0.0;
    for k in 0..100 {
        let new = k % 2 == 0;
        if new {
            last_frame = t;
        }
        let out = s.tick(&input(t, new, still(), 0.0), |_| two_n);
        assert!((out.force_n - two_n).length() < 1e-6);
        t += 0.001;
    }
    // The simulation goes silent for 50 ms.
    let mut stalled_ticks = 0;
    let mut before = two_n;
    for _ in 0..50 {
        let out = s.tick(&input(t, false, still(), 0.0), |_| two_n);
        if t - last_frame >= p.stall_after_s {
            stalled_ticks += 1;
            assert!(out.stalled);
            // The first stalled tick halves it, the second is zero: within 2 ms.
            if stalled_ticks >= 2 {
                assert_eq!(
                    out.force_n,
                    DVec3::ZERO,
                    "tick {stalled_ticks} of the stall"
                );
            }
        } else {
            assert_eq!(out.force_n, before);
        }
        // Fading, never rising.
        assert!(out.force_n.length() <= before.length() + 1e-12);
        before = out.force_n;
        t += 0.001;
    }
    seen.count(&mut s);
    assert_eq!(seen.stall_begin, 1);
    // Frames again: back to 2 N over recover_s, by at most max_force * dt / recover_s a tick.
    let bound = LIMIT_N * 0.001 / p.recover_s;
    let mut ticks_to_full = None;
    for k in 0..400 {
        let out = s.tick(&input(t, k % 2 == 0, still(), 0.0), |_| two_n);
        let step = out.force_n.length() - before.length();
        assert!((0.0..=bound + 1e-12).contains(&step), "tick {k}: {step} N");
        if ticks_to_full.is_none() && (out.force_n - two_n).length() < 1e-9 {
            ticks_to_full = Some(k);
        }
        before = out.force_n;
        t += 0.001;
    }
    let full = ticks_to_full.expect("recovers");
    assert!((249..=251).contains(&full), "{full} ticks");
    seen.count(&mut s);
    assert_eq!(
        (seen.stall_end, seen.recover, seen.recovered),
        (1, 1, 1),
        "{seen:?}"
    );
}

#[test]
fn the_start_up_ramp_waits_for_a_still_stylus_and_a_small_force_then_takes_two_seconds() {
    let mut s = omni();
    let p = *s.params();
    let mut seen = Seen::default();
    let press = DVec3::new(0.0, 0.1, 0.0);
    let mut t = 0.0;
    // A second of a moving stylus (5 cm/s), frames coming, a small force: nothing.
    let moving = DeviceState {
        velocity_m_per_s: DVec3::new(0.05, 0.0, 0.0),
        ..still()
    };
    for k in 0..1000 {
        let out = s.tick(&input(t, k % 2 == 0, moving, 0.0), |_| press);
        assert_eq!(out.force_n, DVec3::ZERO);
        assert_eq!(out.startup_gain, 0.0);
        t += 0.001;
    }
    // Still, but pressed with 1 N (over the 0.25 N a start allows): still nothing.
    for k in 0..1000 {
        let out = s.tick(&input(t, k % 2 == 0, still(), 0.0), |_| press * 10.0);
        assert_eq!(out.force_n, DVec3::ZERO);
        t += 0.001;
    }
    seen.count(&mut s);
    assert_eq!(seen.ramp_start, 0);
    // Held off for 2 s: said once, a second after the first tick.
    assert_eq!(seen.held_off, 1);
    assert!(s.held_off());
    // Still with a small force from `t0`: after still_hold_s the gain rises over 2 s.
    let t0 = t;
    let (mut started, mut full) = (None, None);
    let mut gain = 0.0;
    for k in 0..2500 {
        let out = s.tick(&input(t, k % 2 == 0, still(), 0.0), |_| press);
        assert!(out.startup_gain >= gain, "the ramp only rises");
        gain = out.startup_gain;
        assert!((out.force_n - press * gain).length() < 1e-12);
        seen.count(&mut s);
        if seen.ramp_start == 1 && started.is_none() {
            started = Some(t - t0);
        }
        if seen.ramp_full == 1 && full.is_none() {
            full = Some(t - t0);
            assert_eq!(out.force_n, press);
        }
        t += 0.001;
    }
    let (started, full) = (started.expect("ramp starts"), full.expect("ramp ends"));
    assert!(!s.held_off(), "forces are on");
    assert_eq!(seen.held_off, 1);
    assert!((started - p.still_hold_s).abs() < 1.5e-3, "{started}");
    assert!((full - started - p.ramp_up_s).abs() < 1.5e-3, "{full}");
    // Once running, moving the stylus changes nothing.
    let out = s.tick(&input(t, true, moving, 0.0), |_| press);
    assert_eq!(out.force_n, press);
}

#[test]
fn clamps_keep_direction_and_non_finite_values_give_zero_once_per_run() {
    let mut s = omni();
    let mut seen = Seen::default();
    let t = quiet(&mut s, &mut seen, 0.0, 2500);
    // 10 N along a direction: 3.3 N along it; the stiffness handed on is at most 700 N/m.
    let dir = DVec3::new(1.0, -2.0, 0.5).normalize();
    let mut handed = 0.0;
    let out = s.tick(&input(t, true, still(), 1e6), |k| {
        handed = k;
        dir * 10.0
    });
    assert_eq!(handed, LIMIT_K);
    assert!((out.force_n.length() - LIMIT_N).abs() < 1e-6);
    assert!(out.force_n.normalize().distance(dir) < 1e-12);
    // Held for three more ticks: still one event each.
    for k in 1..4 {
        s.tick(&input(t + k as f64 * 1e-3, false, still(), 1e6), |_| {
            dir * 10.0
        });
    }
    // Overflowing components are no trouble.
    let huge = DVec3::splat(f64::MAX);
    let out = s.tick(&input(t + 0.004, false, still(), 0.0), |_| huge);
    assert!(out.force_n.is_finite() && out.force_n.length() <= LIMIT_N);
    seen.count(&mut s);
    assert_eq!((seen.clamp_force, seen.clamp_stiffness), (1, 1));
    // A NaN position, then a NaN force: zero, one event for the run.
    let nan_pos = DeviceState {
        position_m: DVec3::new(0.0, f64::NAN, 0.0),
        ..still()
    };
    let a = s.tick(&input(t + 0.005, true, nan_pos, 0.0), |_| dir);
    let b = s.tick(&input(t + 0.006, false, still(), 0.0), |_| dir * f64::NAN);
    assert_eq!((a.force_n, b.force_n), (DVec3::ZERO, DVec3::ZERO));
    seen.count(&mut s);
    assert_eq!(seen.non_finite, 1);
    // Then it ramps back, announced.
    let c = s.tick(&input(t + 0.007, true, still(), 0.0), |_| dir);
    assert!(c.force_n.length() < 0.01 && c.hold_gain < 0.01);
    seen.count(&mut s);
    assert_eq!(seen.recover, 1);
    // A clock that steps back is no time passing.
    let d = s.tick(&input(t - 1.0, false, still(), 0.0), |_| dir);
    assert_eq!(d.hold_gain, c.hold_gain);
}

#[test]
fn safety_events_take_the_streams_json_shape() {
    let mut s = omni();
    let mut t = 0.0;
    for k in 0..2500 {
        s.tick(&input(t, k % 2 == 0, still(), 0.0), |_| DVec3::ZERO);
        t += 0.001;
    }
    s.tick(&input(t, true, still(), 900.0), |_| DVec3::X * 5.0);
    s.tick(&input(t + 0.001, false, still(), f64::NAN), |_| DVec3::ZERO);
    s.tick(&input(t + 0.02, false, still(), 0.0), |_| DVec3::ZERO);
    let lines: Vec<String> = s
        .take_events()
        .map(|kind| serde_json::to_string(&crate::sim::SimEvent { step: 3, kind }))
        .collect::<Result<_, _>>()
        .expect("serialises");
    assert_eq!(
        lines,
        [
            r#"{"step":3,"kind":"haptic_ramp","gain":0.0,"hand":"right","phase":"start"}"#,
            r#"{"step":3,"kind":"haptic_ramp","gain":1.0,"hand":"right","phase":"full"}"#,
            r#"{"step":3,"kind":"haptic_clamp","hand":"right","limit":700.0,"quantity":"stiffness_n_per_m","requested":900.0}"#,
            r#"{"step":3,"kind":"haptic_clamp","hand":"right","limit":3.3,"quantity":"force_n","requested":5.0}"#,
            r#"{"step":3,"kind":"haptic_non_finite","hand":"right","what":"stiffness"}"#,
            r#"{"step":3,"kind":"haptic_stall","hand":"right","phase":"begin","silent_s":0.02}"#,
        ]
    );
}
