//! How a trace moves between its keys beyond straight lines: smooth interpolation
//! (`interpolation = "smooth"`) and physiological tremor (`[[tremor]]`).
//!
//! # Smooth interpolation
//!
//! Positions and targets (of the hands and of the head) follow a cubic Hermite curve through
//! the keys, each of the two points on its own. Between keys `i` and `i + 1`, with
//! `h = t_{i+1} - t_i` and `s = (t - t_i) / h` in [0, 1],
//!
//! ```text
//! p(t) = p_i + (p_{i+1} - p_i) (3 s^2 - 2 s^3) + h (m_i s (1 - s)^2 + m_{i+1} s^2 (s - 1))
//! ```
//!
//! (the usual `h00 p_i + h10 h m_i + h01 p_{i+1} + h11 h m_{i+1}`, written so that a key and a
//! hold come out exactly). It passes through every key and its velocity is the tangent `m_i`
//! at key `i` from both sides, so it is continuous (C1). The tangent is the non-uniform
//! Catmull-Rom (finite-difference) slope, the mean of the two adjacent segments' velocities,
//!
//! ```text
//! v_- = (p_i - p_{i-1}) / (t_i - t_{i-1}),   v_+ = (p_{i+1} - p_i) / (t_{i+1} - t_i),
//! m_i = (v_- + v_+) / 2,
//! ```
//!
//! except that `m_i = 0`:
//! - at the first and the last key (the motion starts and ends at rest);
//! - where either adjacent segment has zero displacement, less than [`HOLD_M`] (a hold: the
//!   point stops at the key and stays exactly there between two equal keys, no overshoot);
//! - where the two adjacent velocities point in opposite directions, `v_- . v_+ <= 0` (a
//!   reversal stops at its key);
//! - where an adjacent segment takes no time (two keys at one time): the point jumps there,
//!   as it does with linear interpolation, and sampling never falls inside such a segment.
//!
//! Before the first key and after the last the point holds, as with linear interpolation.
//! Trigger, grip and mark are not affected. Like any Catmull-Rom curve it can pass a key
//! between segments of very different speeds (a segment five times faster than the next).
//!
//! # Tremor
//!
//! Each `[[tremor]]` entry adds, to its hand's position and target alike (the instrument
//! shakes without turning), per axis
//!
//! ```text
//! amplitude_m[axis] * sin(2 pi hz t + phase) * w(t)
//! ```
//!
//! where `w` is 1 inside `[from_s, to_s]` except for raised-cosine ramps over the first and
//! last [`TREMOR_FADE_S`] (`w = (1 - cos(pi x)) / 2` with `x` the time from the nearer end
//! over the fade), and 0 outside, so the hand never jumps. Entries on one hand add up.

use super::{KeyError, Timed};
use glam::{DVec3, Vec3};
use serde::Deserialize;

/// How positions and targets move from one key to the next.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Interpolation {
    /// Straight lines at constant speed between keys (the format's original motion).
    #[default]
    Linear,
    /// The C1 cubic Hermite curve of the [module documentation](self).
    Smooth,
}

/// A hand, as a tremor entry names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    Left,
    Right,
}

impl Side {
    /// 0 for the left hand, 1 for the right (the index the samplers take).
    pub fn index(self) -> usize {
        match self {
            Side::Left => 0,
            Side::Right => 1,
        }
    }
}

/// One `[[tremor]]` entry: a sinusoidal shake of one hand over an interval.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tremor {
    pub hand: Side,
    /// Amplitude along x, y and z, metres (each in [0, [`MAX_TREMOR_M`]]).
    pub amplitude_m: [f32; 3],
    /// Frequency, hertz (in (0, [`MAX_TREMOR_HZ`]]).
    pub hz: f64,
    /// Phase at time 0, radians.
    #[serde(default)]
    pub phase: f64,
    /// When it starts, seconds (it fades in from here).
    #[serde(default)]
    pub from_s: f64,
    /// When it ends, seconds (it has faded out here). Parsing sets a missing one to the
    /// trace's last key; `None` (a tremor built otherwise) never ends.
    #[serde(default)]
    pub to_s: Option<f64>,
}

/// The largest tremor amplitude on an axis, metres (2 cm: far above a physiological tremor).
pub const MAX_TREMOR_M: f32 = 0.02;

/// The highest tremor frequency, hertz.
pub const MAX_TREMOR_HZ: f64 = 30.0;

/// How long a tremor takes to fade in after `from_s` and out before `to_s`, seconds.
pub const TREMOR_FADE_S: f64 = 0.2;

/// A segment that moves a point less than this is a hold, metres (a micrometre, the
/// tolerance the format already uses for a target that must differ from its position).
pub const HOLD_M: f64 = 1e-6;

/// A clear error for what `toml` refuses in the values this module adds (an unknown
/// interpolation, an unknown or missing tremor hand), naming the key; `None` for the rest.
pub(super) fn named_error(text: &str) -> Option<KeyError> {
    let table: toml::Table = toml::from_str(text).ok()?;
    if let Some(v) = table.get("interpolation")
        && !matches!(v.as_str(), Some("linear" | "smooth"))
    {
        return Some(KeyError::new(
            "interpolation".into(),
            format!("must be \"linear\" or \"smooth\", got {v}"),
        ));
    }
    let entries = table.get("tremor")?.as_array()?;
    for (i, e) in entries.iter().enumerate() {
        let key = format!("tremor[{i}].hand");
        match e.get("hand") {
            Some(h) if matches!(h.as_str(), Some("left" | "right")) => {}
            Some(h) => {
                return Some(KeyError::new(
                    key,
                    format!("must be \"left\" or \"right\", got {h}"),
                ));
            }
            None if e.is_table() => {
                return Some(KeyError::new(key, "is missing: \"left\" or \"right\""));
            }
            None => {}
        }
    }
    None
}

/// Checks the tremor entries and sets each missing `to_s` to `end_s`, the trace's last key.
pub(super) fn check_tremor(tremor: &mut [Tremor], end_s: f64, max_s: f64) -> Result<(), KeyError> {
    for (i, tr) in tremor.iter_mut().enumerate() {
        let key = |f: &str| format!("tremor[{i}].{f}");
        let a = tr.amplitude_m;
        if a.iter()
            .any(|c| !c.is_finite() || !(0.0..=MAX_TREMOR_M).contains(c))
        {
            return Err(KeyError::new(
                key("amplitude_m"),
                format!("each axis must be finite metres between 0 and {MAX_TREMOR_M}, got {a:?}"),
            ));
        }
        if !(tr.hz.is_finite() && tr.hz > 0.0 && tr.hz <= MAX_TREMOR_HZ) {
            return Err(KeyError::new(
                key("hz"),
                format!(
                    "must be above 0 and at most {MAX_TREMOR_HZ} Hz, got {}",
                    tr.hz
                ),
            ));
        }
        if !tr.phase.is_finite() {
            return Err(KeyError::new(
                key("phase"),
                format!("must be finite radians, got {}", tr.phase),
            ));
        }
        for (f, t) in [("from_s", Some(tr.from_s)), ("to_s", tr.to_s)] {
            if let Some(t) = t
                && !(t.is_finite() && (0.0..=max_s).contains(&t))
            {
                return Err(KeyError::new(
                    key(f),
                    format!("must be a finite time from 0 to {max_s} s, got {t}"),
                ));
            }
        }
        match tr.to_s {
            Some(to) if to < tr.from_s => {
                return Err(KeyError::new(
                    key("to_s"),
                    format!(
                        "ends before it starts: {to} s is before from_s = {} s",
                        tr.from_s
                    ),
                ));
            }
            Some(_) => {}
            None if tr.from_s > end_s => {
                return Err(KeyError::new(
                    key("from_s"),
                    format!(
                        "{} s is after the trace's last key at {end_s} s, where a tremor \
                         without to_s ends",
                        tr.from_s
                    ),
                ));
            }
            None => tr.to_s = Some(end_s),
        }
    }
    Ok(())
}

/// The raised-cosine ramp: 0 at `x <= 0`, 1 at `x >= 1`, `(1 - cos(pi x)) / 2` between.
fn ramp(x: f64) -> f64 {
    if x >= 1.0 {
        1.0
    } else if x <= 0.0 {
        0.0
    } else {
        0.5 - 0.5 * (std::f64::consts::PI * x).cos()
    }
}

/// How much of a tremor applies at `t_s`: 0 outside `[from, to]`, 1 inside its fades.
pub fn tremor_weight(tr: &Tremor, t_s: f64) -> f64 {
    let to = tr.to_s.unwrap_or(f64::INFINITY);
    if !(tr.from_s <= t_s && t_s <= to) {
        return 0.0;
    }
    ramp((t_s - tr.from_s) / TREMOR_FADE_S) * ramp((to - t_s) / TREMOR_FADE_S)
}

/// The sum of a hand's (0 left, 1 right) tremor entries at `t_s`, metres; `None` where none
/// of them applies (so that an untouched sample stays bit for bit what it was).
pub fn tremor_offset(tremor: &[Tremor], hand: usize, t_s: f64) -> Option<Vec3> {
    let mut sum = DVec3::ZERO;
    let mut any = false;
    for tr in tremor.iter().filter(|tr| tr.hand.index() == hand) {
        let w = tremor_weight(tr, t_s);
        if w > 0.0 {
            let wave = (std::f64::consts::TAU * tr.hz * t_s + tr.phase).sin();
            sum += Vec3::from(tr.amplitude_m).as_dvec3() * (wave * w);
            any = true;
        }
    }
    any.then(|| sum.as_vec3())
}

/// Position (`end` 0) or target (`end` 1) of a key, in f64.
fn point<K: Timed>(k: &K, end: usize) -> DVec3 {
    let (position, target) = k.ends();
    Vec3::from(if end == 0 { position } else { target }).as_dvec3()
}

/// The tangent of the smooth curve at key `j` for one end, metres per second.
fn tangent<K: Timed>(keys: &[K], j: usize, end: usize) -> DVec3 {
    if j == 0 || j + 1 >= keys.len() {
        return DVec3::ZERO;
    }
    let (before, at, after) = (&keys[j - 1], &keys[j], &keys[j + 1]);
    let (h0, h1) = (at.t_s() - before.t_s(), after.t_s() - at.t_s());
    let (d0, d1) = (
        point(at, end) - point(before, end),
        point(after, end) - point(at, end),
    );
    if !(h0 > 0.0 && h1 > 0.0) || d0.length() < HOLD_M || d1.length() < HOLD_M {
        return DVec3::ZERO;
    }
    let (v0, v1) = (d0 / h0, d1 / h1);
    if v0.dot(v1) <= 0.0 {
        return DVec3::ZERO;
    }
    (v0 + v1) * 0.5
}

/// Position and target at `t_s` on the smooth curve through `keys` (not empty).
pub(super) fn smooth<K: Timed>(keys: &[K], t_s: f64) -> (Vec3, Vec3) {
    let i = keys.partition_point(|k| k.t_s() <= t_s);
    let exact = |k: &K| {
        let (p, q) = k.ends();
        (Vec3::from(p), Vec3::from(q))
    };
    if i == 0 {
        return exact(&keys[0]);
    }
    if i >= keys.len() {
        return exact(&keys[keys.len() - 1]);
    }
    // keys[i - 1].t_s <= t_s < keys[i].t_s, so the segment takes time.
    let (a, b) = (i - 1, i);
    let h = keys[b].t_s() - keys[a].t_s();
    let s = ((t_s - keys[a].t_s()) / h).clamp(0.0, 1.0);
    let h01 = s * s * (3.0 - 2.0 * s);
    let h10 = s * (1.0 - s) * (1.0 - s);
    let h11 = s * s * (s - 1.0);
    let at = |end: usize| {
        let (p0, p1) = (point(&keys[a], end), point(&keys[b], end));
        let (m0, m1) = (tangent(keys, a, end), tangent(keys, b, end));
        (p0 + (p1 - p0) * h01 + (m0 * h10 + m1 * h11) * h).as_vec3()
    };
    (at(0), at(1))
}
