//! The keyframed trace format (`assets/traces/*.toml`), shared by the application's headless
//! sessions and the simulated OpenXR runtime, which plays the same file as head and controller
//! motion. Positions are metres in the operating field's frame (see [`crate::stage`]); each
//! hand's instrument points from `position` to `target`; values interpolate linearly between
//! keys and `mark` and `pad` hold until the next key. `pad = "up"` (`"down"`, `"left"`,
//! `"right"`) is the trackpad clicked at that edge (or a thumbstick pushed and pressed): the
//! click is down too, as on the controller. `roll_deg` turns the hand about its pointing
//! direction (the wrist's roll, clockwise as the hand sees it; 0 by default), interpolated
//! like the positions ([`hand_orientation`]). `[[head]]` keys are optional (the runtime's
//! default head is [`crate::stage::DEFAULT_HEAD`]; headless sessions ignore them).
//!
//! Two optional top-level features describe a person's hand motion compactly (see
//! [`motion`]): `interpolation = "smooth"` moves positions and targets along a C1 curve
//! through the keys instead of straight lines, and `[[tremor]]` entries add a small
//! deterministic oscillation to a hand over an interval:
//!
//! ```toml
//! procedure = "nephrectomy"
//! interpolation = "smooth"   # or "linear", the default
//!
//! [[tremor]]
//! hand = "right"
//! amplitude_m = [0.0004, 0.0003, 0.0004]  # per axis, metres, at most 0.02
//! hz = 9.0                                 # at most 30
//! phase = 0.5                              # radians, default 0
//! from_s = 2.0                             # default 0
//! to_s = 6.0                               # default: the trace's last key
//! ```
//!
//! [`sample_hand`] and [`sample_head`] sample keys alone (linear, no tremor);
//! [`KeyframeFile::sample_hand_of`] and [`KeyframeFile::sample_head_of`] apply the file's
//! interpolation and tremor, as both players do.

pub mod motion;
#[cfg(test)]
mod motion_tests;

use glam::Vec3;
use serde::Deserialize;

pub use motion::{Interpolation, Side, TREMOR_FADE_S, Tremor};

/// A whole trace file as written (after [`KeyframeFile::parse`], each tremor's `to_s` is set).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeFile {
    pub procedure: String,
    /// How positions and targets move between keys; linear unless the file says otherwise.
    #[serde(default)]
    pub interpolation: Interpolation,
    #[serde(default)]
    pub left: Vec<HandKey>,
    #[serde(default)]
    pub right: Vec<HandKey>,
    #[serde(default)]
    pub head: Vec<HeadKey>,
    /// Tremor added to the hands, `[[tremor]]` entries.
    #[serde(default)]
    pub tremor: Vec<Tremor>,
}

/// One keyframe of one hand.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandKey {
    /// Time, seconds from the start.
    pub t_s: f64,
    /// Where the instrument (the controller's aim pose) is, metres.
    pub position: [f32; 3],
    /// A point it points at, metres.
    pub target: [f32; 3],
    /// Trigger, 0 to 1.
    #[serde(default)]
    pub trigger: f32,
    /// Grip (squeeze), 0 to 1.
    #[serde(default)]
    pub grip: f32,
    /// The mark button (trackpad click) is down.
    #[serde(default)]
    pub mark: bool,
    /// The trackpad is clicked at one edge (a d-pad press); the click is down with it.
    #[serde(default)]
    pub pad: Option<PadDirection>,
    /// The wrist's roll about the pointing direction, degrees (clockwise as the hand sees
    /// it).
    #[serde(default)]
    pub roll_deg: f32,
}

/// Which edge of the trackpad (or which way the thumbstick) a press is at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PadDirection {
    Up,
    Down,
    Left,
    Right,
}

impl PadDirection {
    pub const ALL: [PadDirection; 4] = [Self::Up, Self::Down, Self::Left, Self::Right];

    /// The trackpad position of a press at this edge (x right, y up, each -1 to 1).
    pub fn axes(self) -> [f32; 2] {
        match self {
            Self::Up => [0.0, 1.0],
            Self::Down => [0.0, -1.0],
            Self::Left => [-1.0, 0.0],
            Self::Right => [1.0, 0.0],
        }
    }

    /// The edge a click at trackpad position `axes` is at: none within half the pad's
    /// radius of its centre (a plain click), else the nearer axis's end.
    pub fn of_click(click: bool, axes: [f32; 2]) -> Option<Self> {
        let [x, y] = axes;
        if !(click && x.is_finite() && y.is_finite()) || x * x + y * y < 0.25 {
            return None;
        }
        Some(if x.abs() > y.abs() {
            if x > 0.0 { Self::Right } else { Self::Left }
        } else if y > 0.0 {
            Self::Up
        } else {
            Self::Down
        })
    }
}

/// One keyframe of the head: where the eyes' midpoint is and a point it looks at, metres.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeadKey {
    pub t_s: f64,
    pub position: [f32; 3],
    pub target: [f32; 3],
}

/// What is wrong with a trace: the key (`right[3].t_s`, `toml`) and why.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyError {
    pub key: String,
    pub message: String,
}

impl KeyError {
    fn new(key: String, message: impl Into<String>) -> Self {
        Self {
            key,
            message: message.into(),
        }
    }
}

/// Time, position and target of any keyframe, for the checks both kinds share.
trait Timed {
    fn t_s(&self) -> f64;
    fn ends(&self) -> ([f32; 3], [f32; 3]);
}

impl Timed for HandKey {
    fn t_s(&self) -> f64 {
        self.t_s
    }
    fn ends(&self) -> ([f32; 3], [f32; 3]) {
        (self.position, self.target)
    }
}

impl Timed for HeadKey {
    fn t_s(&self) -> f64 {
        self.t_s
    }
    fn ends(&self) -> ([f32; 3], [f32; 3]) {
        (self.position, self.target)
    }
}

/// The longest session a trace may describe unless told otherwise, seconds (4 hours).
pub const DEFAULT_MAX_SESSION_S: f64 = 4.0 * 3600.0;

fn check_keys<K: Timed>(name: &str, keys: &[K], max_s: f64) -> Result<(), KeyError> {
    let mut last = f64::NEG_INFINITY;
    for (i, k) in keys.iter().enumerate() {
        let key = |f: &str| format!("{name}[{i}].{f}");
        let t = k.t_s();
        if !t.is_finite() || t < 0.0 {
            return Err(KeyError::new(
                key("t_s"),
                format!("must be a finite time >= 0 s, got {t}"),
            ));
        }
        if t > max_s {
            return Err(KeyError::new(
                key("t_s"),
                format!(
                    "{t} s is past the longest session allowed, {max_s} s ({:.1} h; \
                     `--max-session S` allows longer)",
                    max_s / 3600.0
                ),
            ));
        }
        if t < last {
            return Err(KeyError::new(
                key("t_s"),
                format!("time goes backwards: {t} s after {last} s"),
            ));
        }
        last = t;
        let (position, target) = k.ends();
        for (f, v) in [("position", position), ("target", target)] {
            if v.iter().any(|c| !c.is_finite() || c.abs() > 10.0) {
                return Err(KeyError::new(
                    key(f),
                    format!("must be finite metres within 10 m, got {v:?}"),
                ));
            }
        }
        if Vec3::from(position).distance(Vec3::from(target)) < 1e-6 {
            return Err(KeyError::new(
                key("target"),
                "must differ from position (it sets the pointing direction)",
            ));
        }
    }
    Ok(())
}

impl KeyframeFile {
    /// Parses and checks a trace no longer than [`DEFAULT_MAX_SESSION_S`].
    pub fn parse(text: &str) -> Result<Self, KeyError> {
        Self::parse_within(text, DEFAULT_MAX_SESSION_S)
    }

    /// Parses and checks a trace: both hands have keys, times run forward from 0 to at most
    /// `max_s`, positions are finite and within 10 m, targets differ from positions, trigger
    /// and grip are in [0, 1], `interpolation` is `"linear"` or `"smooth"`, and each tremor
    /// names a hand and has amplitudes in [0, 0.02] m, a frequency in (0, 30] Hz, a finite
    /// phase and `from_s <= to_s` within `max_s`. A tremor without `to_s` gets the time of the
    /// trace's last key (of any kind), so that it ends with the trace.
    pub fn parse_within(text: &str, max_s: f64) -> Result<Self, KeyError> {
        let mut t: KeyframeFile = toml::from_str(text).map_err(|e| {
            motion::named_error(text).unwrap_or_else(|| {
                KeyError::new("toml".into(), e.to_string().trim_end().replace('\n', " | "))
            })
        })?;
        for (name, keys) in [("left", &t.left), ("right", &t.right)] {
            if keys.is_empty() {
                return Err(KeyError::new(
                    name.into(),
                    format!("needs at least one [[{name}]] keyframe"),
                ));
            }
            check_keys(name, keys, max_s)?;
            for (i, k) in keys.iter().enumerate() {
                for (f, v) in [("trigger", k.trigger), ("grip", k.grip)] {
                    if !v.is_finite() || !(0.0..=1.0).contains(&v) {
                        return Err(KeyError::new(
                            format!("{name}[{i}].{f}"),
                            format!("must be between 0 and 1, got {v}"),
                        ));
                    }
                }
                if !k.roll_deg.is_finite() || k.roll_deg.abs() > 720.0 {
                    return Err(KeyError::new(
                        format!("{name}[{i}].roll_deg"),
                        format!("must be between -720 and 720 degrees, got {}", k.roll_deg),
                    ));
                }
            }
        }
        check_keys("head", &t.head, max_s)?;
        let end_s = t.duration_s();
        motion::check_tremor(&mut t.tremor, end_s, max_s)?;
        Ok(t)
    }

    /// A hand (0 left, 1 right) at time `t_s`, seconds, with the file's interpolation and
    /// tremor; `None` for a hand without keys (or another index).
    pub fn sample_hand_of(&self, hand: usize, t_s: f64) -> Option<HandSample> {
        let keys = match hand {
            0 => &self.left,
            1 => &self.right,
            _ => return None,
        };
        sample_hand_with(keys, self.interpolation, &self.tremor, hand, t_s)
    }

    /// The head (position, looked-at point) at time `t_s` with the file's interpolation: its
    /// keys, or the default head.
    pub fn sample_head_of(&self, t_s: f64) -> (Vec3, Vec3) {
        sample_head_with(&self.head, self.interpolation, t_s)
    }

    /// Time of the last keyframe, seconds.
    pub fn duration_s(&self) -> f64 {
        let last = |k: Option<f64>| k.unwrap_or(0.0);
        last(self.left.last().map(|k| k.t_s))
            .max(last(self.right.last().map(|k| k.t_s)))
            .max(last(self.head.last().map(|k| k.t_s)))
    }
}

/// A hand's state at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandSample {
    pub position: Vec3,
    pub target: Vec3,
    pub trigger: f32,
    pub grip: f32,
    /// The click: the key's mark, or its pad press.
    pub mark: bool,
    pub pad: Option<PadDirection>,
    /// The wrist's roll, degrees.
    pub roll_deg: f32,
}

/// A hand's orientation: its -Z (the instrument's pointing direction) from `position` to
/// `target` by the shortest arc from -Z, then turned by `roll_deg` about that direction
/// (clockwise as the hand sees it, looking along it). The simulated runtime's controllers
/// and the headless sessions both take their poses from here.
pub fn hand_orientation(position: Vec3, target: Vec3, roll_deg: f32) -> glam::Quat {
    let dir = (target - position).normalize_or_zero();
    let arc = if dir == Vec3::ZERO {
        glam::Quat::IDENTITY
    } else {
        glam::Quat::from_rotation_arc(Vec3::NEG_Z, dir)
    };
    if roll_deg == 0.0 {
        arc
    } else {
        // About the local -Z (right-handed about the pointing direction: clockwise seen
        // from behind, looking along it).
        arc * glam::Quat::from_rotation_z(-roll_deg.to_radians())
    }
}

/// The roll `orientation` holds about its own pointing direction, radians in (-pi, pi]: the
/// inverse of [`hand_orientation`]'s turn, for any orientation.
pub fn roll_of(orientation: glam::Quat) -> f32 {
    let dir = orientation * Vec3::NEG_Z;
    let arc = if dir.length_squared() > 0.0 {
        glam::Quat::from_rotation_arc(Vec3::NEG_Z, dir.normalize())
    } else {
        glam::Quat::IDENTITY
    };
    let r = arc.inverse() * orientation;
    // What is left is a turn about Z: (0, 0, sin(a/2), cos(a/2)); the roll is about -Z.
    let a = -2.0 * r.z.atan2(r.w);
    if a > std::f32::consts::PI {
        a - std::f32::consts::TAU
    } else if a <= -std::f32::consts::PI {
        a + std::f32::consts::TAU
    } else {
        a
    }
}

/// The two keys around `t` and how far between them (0 to 1). `keys` must not be empty.
fn around<K: Timed + Copy>(keys: &[K], t: f64) -> (K, K, f32) {
    let i = keys.partition_point(|k| k.t_s() <= t);
    let (a, b) = match i {
        0 => (keys[0], keys[0]),
        i if i >= keys.len() => (keys[keys.len() - 1], keys[keys.len() - 1]),
        i => (keys[i - 1], keys[i]),
    };
    let s = if b.t_s() > a.t_s() {
        ((t - a.t_s()) / (b.t_s() - a.t_s())).clamp(0.0, 1.0) as f32
    } else {
        0.0
    };
    (a, b, s)
}

/// A hand at time `t_s`, seconds; `None` for a hand without keys.
pub fn sample_hand(keys: &[HandKey], t_s: f64) -> Option<HandSample> {
    if keys.is_empty() {
        return None;
    }
    let (a, b, s) = around(keys, t_s);
    Some(HandSample {
        position: Vec3::from(a.position).lerp(Vec3::from(b.position), s),
        target: Vec3::from(a.target).lerp(Vec3::from(b.target), s),
        trigger: a.trigger + (b.trigger - a.trigger) * s,
        grip: a.grip + (b.grip - a.grip) * s,
        mark: a.mark || a.pad.is_some(),
        pad: a.pad,
        roll_deg: a.roll_deg + (b.roll_deg - a.roll_deg) * s,
    })
}

/// The head (position, looked-at point) at time `t_s`: its keys, or the default head.
pub fn sample_head(keys: &[HeadKey], t_s: f64) -> (Vec3, Vec3) {
    if keys.is_empty() {
        let (p, t) = crate::stage::DEFAULT_HEAD;
        return (Vec3::from(p), Vec3::from(t));
    }
    let (a, b, s) = around(keys, t_s);
    (
        Vec3::from(a.position).lerp(Vec3::from(b.position), s),
        Vec3::from(a.target).lerp(Vec3::from(b.target), s),
    )
}

/// A hand at time `t_s` as [`sample_hand`], its position and target moved as `interpolation`
/// says and shaken by the entries of `tremor` for `hand` (0 left, 1 right); trigger, grip and
/// mark are [`sample_hand`]'s. Linear without a tremor on the hand at `t_s` gives
/// [`sample_hand`]'s sample, bit for bit.
pub fn sample_hand_with(
    keys: &[HandKey],
    interpolation: Interpolation,
    tremor: &[Tremor],
    hand: usize,
    t_s: f64,
) -> Option<HandSample> {
    let mut s = sample_hand(keys, t_s)?;
    if interpolation == Interpolation::Smooth {
        (s.position, s.target) = motion::smooth(keys, t_s);
    }
    if let Some(d) = motion::tremor_offset(tremor, hand, t_s) {
        // The same offset on both ends: the instrument shakes without turning.
        s.position += d;
        s.target += d;
    }
    Some(s)
}

/// The head at time `t_s` as [`sample_head`], moving as `interpolation` says.
pub fn sample_head_with(keys: &[HeadKey], interpolation: Interpolation, t_s: f64) -> (Vec3, Vec3) {
    if interpolation == Interpolation::Smooth && !keys.is_empty() {
        return motion::smooth(keys, t_s);
    }
    sample_head(keys, t_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_KEYS: &str = "procedure = \"nephrectomy\"
[[left]]
t_s = 0.0
position = [0.0, 0.1, 0.1]
target = [0.0, 0.0, 0.0]
[[right]]
t_s = 0.0
position = [0.0, 0.0, 0.1]
target = [0.0, 0.0, 0.0]
[[right]]
t_s = 2.0
position = [0.2, 0.0, 0.1]
target = [0.0, 0.0, 0.0]
trigger = 1.0
mark = true
";

    #[test]
    fn hands_interpolate_and_marks_hold_until_the_next_key() {
        let f = KeyframeFile::parse(TWO_KEYS).expect("valid");
        let h = sample_hand(&f.right, 0.5).expect("keys");
        assert!((h.position.x - 0.05).abs() < 1e-6);
        assert!((h.trigger - 0.25).abs() < 1e-6);
        assert!(!h.mark);
        assert!(sample_hand(&f.right, 3.0).expect("keys").mark);
        assert_eq!(f.duration_s(), 2.0);
        // No head keys: the default head.
        let (p, _) = sample_head(&f.head, 1.0);
        assert_eq!(p, Vec3::from(crate::stage::DEFAULT_HEAD.0));
    }

    /// A pad press holds until the next key and clicks the pad; a press is read back from
    /// the pad's position only at its edges.
    #[test]
    fn a_pad_press_is_a_click_at_an_edge() {
        let f =
            KeyframeFile::parse(&TWO_KEYS.replace("mark = true", "pad = \"left\"")).expect("valid");
        let h = sample_hand(&f.right, 3.0).expect("keys");
        assert_eq!((h.pad, h.mark), (Some(PadDirection::Left), true));
        assert_eq!(sample_hand(&f.right, 1.0).expect("keys").pad, None);
        for d in PadDirection::ALL {
            assert_eq!(PadDirection::of_click(true, d.axes()), Some(d));
            assert_eq!(PadDirection::of_click(false, d.axes()), None);
        }
        assert_eq!(PadDirection::of_click(true, [0.3, -0.3]), None);
        assert_eq!(
            PadDirection::of_click(true, [0.4, -0.6]),
            Some(PadDirection::Down)
        );
        assert_eq!(PadDirection::of_click(true, [f32::NAN, 1.0]), None);
        let bad =
            KeyframeFile::parse(&TWO_KEYS.replace("mark = true", "pad = \"north\"")).unwrap_err();
        assert!(
            bad.message.contains("line 15") && bad.message.contains("expected one of `up`"),
            "{bad:?}"
        );
    }

    #[test]
    fn bad_traces_name_the_key() {
        let backwards = TWO_KEYS.replace("t_s = 2.0", "t_s = -1.0");
        assert_eq!(
            KeyframeFile::parse(&backwards).unwrap_err().key,
            "right[1].t_s"
        );
        let trigger = TWO_KEYS.replace("trigger = 1.0", "trigger = 1.5");
        assert_eq!(
            KeyframeFile::parse(&trigger).unwrap_err().key,
            "right[1].trigger"
        );
        let head = format!(
            "{TWO_KEYS}[[head]]\nt_s = 0.0\nposition = [0.0, 0.0, 0.0]\ntarget = [0.0, 0.0, 0.0]\n"
        );
        assert_eq!(
            KeyframeFile::parse(&head).unwrap_err().key,
            "head[0].target"
        );
        let no_left = TWO_KEYS.replace("[[left]]", "[[head]]");
        assert_eq!(KeyframeFile::parse(&no_left).unwrap_err().key, "left");
        assert_eq!(
            KeyframeFile::parse("procedure = 3").unwrap_err().key,
            "toml"
        );
    }

    #[test]
    fn times_past_the_longest_session_are_refused() {
        let far = TWO_KEYS.replace("t_s = 2.0", "t_s = 1e300");
        let e = KeyframeFile::parse(&far).unwrap_err();
        assert_eq!(e.key, "right[1].t_s");
        assert!(e.message.contains("--max-session"), "{}", e.message);
        let five_h = TWO_KEYS.replace("t_s = 2.0", "t_s = 18000.0");
        assert!(KeyframeFile::parse(&five_h).is_err());
        let f = KeyframeFile::parse_within(&five_h, 6.0 * 3600.0).expect("allowed when asked");
        assert_eq!(f.duration_s(), 18000.0);
    }

    /// A roll turns the hand about where it points, right-handed (pointing along +x, its up
    /// turns from +y to +z at 90 degrees), and `roll_of` reads back the roll from the
    /// orientation for any pointing direction; keys interpolate it and a roll out of range is
    /// named.
    #[test]
    fn a_roll_turns_the_hand_about_where_it_points_and_reads_back() {
        let q = hand_orientation(Vec3::ZERO, Vec3::X, 90.0);
        assert!(
            (q * Vec3::NEG_Z - Vec3::X).length() < 1e-6,
            "{}",
            q * Vec3::NEG_Z
        );
        assert!((q * Vec3::Y - Vec3::Z).length() < 1e-6, "{}", q * Vec3::Y);
        assert_eq!(
            hand_orientation(Vec3::ZERO, Vec3::X, 0.0),
            glam::Quat::from_rotation_arc(Vec3::NEG_Z, Vec3::X)
        );
        for to in [
            Vec3::X,
            Vec3::new(0.2, -1.0, 0.3),
            Vec3::new(1.0, 2.0, -3.0),
        ] {
            for roll in [-170.0f32, -45.0, 0.0, 30.0, 179.0] {
                let got = roll_of(hand_orientation(Vec3::ZERO, to, roll)).to_degrees();
                assert!((got - roll).abs() < 1e-3, "{to} {roll}: {got}");
            }
        }
        let rolled = TWO_KEYS.replacen("mark = true", "mark = true\nroll_deg = 90.0", 1);
        let f = KeyframeFile::parse(&rolled).expect("valid");
        // A quarter of the way from no roll to 90 degrees.
        let mid = sample_hand(&f.right, 0.5).expect("keys").roll_deg;
        assert!((mid - 22.5).abs() < 1e-4, "{mid}");
        let bad = TWO_KEYS.replacen("mark = true", "mark = true\nroll_deg = 1000.0", 1);
        let e = KeyframeFile::parse(&bad).unwrap_err();
        assert_eq!(e.key, "right[1].roll_deg", "{e:?}");
    }
}
