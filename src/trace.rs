//! Input traces. A keyframed TOML trace is written by hand and sampled once per step; every
//! session records what it sampled in a compact binary file that replays bit for bit.

use crate::models::Tuning;
use crate::scenario::{InputError, check_procedure};
use crate::sim::{Buttons, Hand, HandInput, InputFrame, Pose};
use glam::{Quat, Vec3};
use std::io::{Read, Write};
use std::path::Path;

/// One keyframe of one hand (the format is shared with the simulated XR runtime).
pub use xr_bindings::keyframes::HandKey as Key;
use xr_bindings::keyframes::{HeadKey, KeyframeFile};

/// A validated keyframed trace.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyTrace {
    pub procedure: String,
    pub keys: [Vec<Key>; 2],
    /// Head keys: played by the simulated XR runtime; headless sessions keep their camera.
    pub head: Vec<HeadKey>,
}

impl KeyTrace {
    pub fn parse(file: &str, text: &str) -> Result<Self, InputError> {
        let t = KeyframeFile::parse(text).map_err(|e| InputError::new(file, &e.key, e.message))?;
        check_procedure(file, "procedure", &t.procedure)?;
        Ok(Self {
            procedure: t.procedure,
            keys: [t.left, t.right],
            head: t.head,
        })
    }

    pub fn load(path: &Path) -> Result<Self, InputError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::parse(&file, &text)
    }

    /// Drops every keyframe after `t_s` (each hand keeps at least its first).
    pub fn truncate_to(&mut self, t_s: f64) {
        for keys in &mut self.keys {
            let keep = keys.iter().filter(|k| k.t_s <= t_s).count().max(1);
            keys.truncate(keep);
        }
        self.head.retain(|k| k.t_s <= t_s);
    }

    /// Time of the last hand keyframe, seconds.
    pub fn duration_s(&self) -> f64 {
        self.keys
            .iter()
            .filter_map(|k| k.last())
            .map(|k| k.t_s)
            .fold(0.0, f64::max)
    }

    /// The input at time `t_s`.
    pub fn sample(&self, t_s: f64) -> InputFrame {
        let mut frame = InputFrame::default();
        for hand in Hand::BOTH {
            if let Some(h) = xr_bindings::keyframes::sample_hand(&self.keys[hand.index()], t_s) {
                frame.hands[hand.index()] = HandInput {
                    pose: Pose::looking_at(h.position, h.target),
                    buttons: Buttons {
                        trigger: h.trigger,
                        grip: h.grip,
                        mark: h.mark,
                    },
                };
            }
        }
        frame
    }
}

const MAGIC: &[u8; 8] = b"VSLTRACE";
/// Version 2 adds the tissue tunings made during the session (version 1 files still read).
const VERSION: u32 = 2;
/// Bytes per tuning: the step (u64) and four floats.
const TUNING_BYTES: usize = 8 + 4 * 4;
/// Bytes per hand per step: 3 + 4 + 2 floats, one flag byte.
const HAND_BYTES: usize = 9 * 4 + 1;

/// A recorded session input: the scenario text it ran with, every sampled frame, and the
/// tissue parameters changed during the session (applied before the step they name).
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    pub procedure: String,
    pub dt_s: f32,
    pub scenario: String,
    pub frames: Vec<InputFrame>,
    pub tunings: Vec<(u64, Tuning)>,
}

impl Recording {
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let mut buf =
            Vec::with_capacity(64 + self.scenario.len() + self.frames.len() * 2 * HAND_BYTES);
        buf.extend_from_slice(MAGIC);
        buf.extend_from_slice(&VERSION.to_le_bytes());
        for s in [self.procedure.as_bytes(), self.scenario.as_bytes()] {
            buf.extend_from_slice(&(s.len() as u32).to_le_bytes());
            buf.extend_from_slice(s);
        }
        buf.extend_from_slice(&self.dt_s.to_le_bytes());
        buf.extend_from_slice(&(self.frames.len() as u64).to_le_bytes());
        for f in &self.frames {
            for h in &f.hands {
                let p = h.pose.position.to_array();
                let q = h.pose.orientation.to_array();
                for v in p
                    .into_iter()
                    .chain(q)
                    .chain([h.buttons.trigger, h.buttons.grip])
                {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
                buf.push(h.buttons.mark as u8);
            }
        }
        buf.extend_from_slice(&(self.tunings.len() as u32).to_le_bytes());
        for (step, t) in &self.tunings {
            buf.extend_from_slice(&step.to_le_bytes());
            for v in t.values() {
                buf.extend_from_slice(&v.to_le_bytes());
            }
        }
        // Write to a temporary file and rename, so a crash never leaves half a recording.
        let tmp = path.with_extension("partial");
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(&buf)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    }

    pub fn read(path: &Path) -> Result<Self, InputError> {
        let file = path.display().to_string();
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::decode(&file, &bytes)
    }

    pub fn is_recording(bytes: &[u8]) -> bool {
        bytes.starts_with(MAGIC)
    }

    pub fn decode(file: &str, bytes: &[u8]) -> Result<Self, InputError> {
        let mut r = Reader {
            b: bytes,
            at: 0,
            file,
        };
        if r.take(8, "header")? != MAGIC {
            return Err(InputError::new(
                file,
                "header",
                "not a Vesalius recording (magic VSLTRACE missing)",
            ));
        }
        let version = r.u32("version")?;
        if !(1..=VERSION).contains(&version) {
            return Err(InputError::new(
                file,
                "version",
                format!("unsupported version {version}, expected 1 to {VERSION}"),
            ));
        }
        let procedure = r.string("procedure")?;
        check_procedure(file, "procedure", &procedure)?;
        let scenario = r.string("scenario")?;
        let dt_s = r.f32("dt_s")?;
        if !dt_s.is_finite() || !(1e-4..=0.01).contains(&dt_s) {
            return Err(InputError::new(
                file,
                "dt_s",
                format!("must be 1e-4..0.01 s, got {dt_s}"),
            ));
        }
        let n = r.u64("frames")? as usize;
        let left = r.b.len() - r.at;
        let frame_bytes = n.saturating_mul(2 * HAND_BYTES);
        if (version == 1 && left != frame_bytes) || left < frame_bytes {
            return Err(InputError::new(
                file,
                "frames",
                format!("expected {frame_bytes} bytes of frames for {n} frames, found {left}"),
            ));
        }
        let mut frames = Vec::with_capacity(n);
        for step in 0..n {
            let mut frame = InputFrame::default();
            for h in 0..2 {
                let mut v = [0f32; 9];
                for c in &mut v {
                    *c = r.f32("frame")?;
                }
                let mark = r.take(1, "frame")?[0] != 0;
                frame.hands[h] = HandInput {
                    pose: Pose {
                        position: Vec3::new(v[0], v[1], v[2]),
                        orientation: Quat::from_xyzw(v[3], v[4], v[5], v[6]),
                    },
                    buttons: Buttons {
                        trigger: v[7],
                        grip: v[8],
                        mark,
                    },
                };
            }
            if !frame.is_finite() {
                return Err(InputError::new(
                    file,
                    &format!("frame {step}"),
                    "pose or button is not a finite number",
                ));
            }
            frames.push(frame);
        }
        let mut tunings = Vec::new();
        if version >= 2 {
            let k = r.u32("tunings")? as usize;
            let left = r.b.len() - r.at;
            if left != k * TUNING_BYTES {
                return Err(InputError::new(
                    file,
                    "tunings",
                    format!(
                        "expected {} bytes for {k} tunings, found {left}",
                        k * TUNING_BYTES
                    ),
                ));
            }
            for j in 0..k {
                let step = r.u64("tunings")?;
                let mut v = [0f32; 4];
                for c in &mut v {
                    *c = r.f32("tunings")?;
                }
                let t = Tuning {
                    spring_n_per_m: v[0],
                    damping_per_s: v[1],
                    pressure_pa: v[2],
                    offset_m: v[3],
                };
                let key = format!("tuning {j}");
                t.check()
                    .map_err(|(name, m)| InputError::new(file, &format!("{key}: {name}"), m))?;
                if step > n as u64 || tunings.last().is_some_and(|(s, _)| *s > step) {
                    return Err(InputError::new(
                        file,
                        &key,
                        format!("step {step} is out of order or past the last frame ({n})"),
                    ));
                }
                tunings.push((step, t));
            }
        }
        Ok(Self {
            procedure,
            dt_s,
            scenario,
            frames,
            tunings,
        })
    }
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
    file: &'a str,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], InputError> {
        if self.at + n > self.b.len() {
            return Err(InputError::new(
                self.file,
                what,
                "file ends early (truncated recording)",
            ));
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u32(&mut self, what: &str) -> Result<u32, InputError> {
        let s = self.take(4, what)?;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn u64(&mut self, what: &str) -> Result<u64, InputError> {
        Ok(self.u32(what)? as u64 | (self.u32(what)? as u64) << 32)
    }
    fn f32(&mut self, what: &str) -> Result<f32, InputError> {
        Ok(f32::from_bits(self.u32(what)?))
    }
    fn string(&mut self, what: &str) -> Result<String, InputError> {
        let n = self.u32(what)? as usize;
        let s = self.take(n, what)?;
        String::from_utf8(s.to_vec()).map_err(|_| InputError::new(self.file, what, "is not UTF-8"))
    }
}
