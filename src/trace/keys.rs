//! Keyframed TOML traces: written by hand, sampled once per step with the file's
//! interpolation and tremor (see `xr_bindings::keyframes`).

use crate::scenario::{InputError, check_procedure};
use crate::sim::{Buttons, Hand, HandInput, InputFrame, Pose};
use std::path::Path;

/// One keyframe of one hand (the format is shared with the simulated XR runtime).
pub use xr_bindings::keyframes::HandKey as Key;
use xr_bindings::keyframes::{HeadKey, Interpolation, KeyframeFile, Tremor};

/// A validated keyframed trace.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyTrace {
    pub procedure: String,
    pub keys: [Vec<Key>; 2],
    /// Head keys: played by the simulated XR runtime; headless sessions keep their camera.
    pub head: Vec<HeadKey>,
    /// How positions and targets move between keys (the file's `interpolation`).
    pub interpolation: Interpolation,
    /// The hands' tremor (`[[tremor]]`), each with its end set (the file's last key unless
    /// it gives `to_s`).
    pub tremor: Vec<Tremor>,
}

impl KeyTrace {
    /// Parses a trace no longer than the default longest session (4 hours).
    pub fn parse(file: &str, text: &str) -> Result<Self, InputError> {
        Self::parse_within(file, text, xr_bindings::keyframes::DEFAULT_MAX_SESSION_S)
    }

    /// Parses a trace whose keys all lie within `max_s` seconds.
    pub fn parse_within(file: &str, text: &str, max_s: f64) -> Result<Self, InputError> {
        let t = KeyframeFile::parse_within(text, max_s)
            .map_err(|e| InputError::new(file, &e.key, e.message))?;
        check_procedure(file, "procedure", &t.procedure)?;
        Ok(Self {
            procedure: t.procedure,
            keys: [t.left, t.right],
            head: t.head,
            interpolation: t.interpolation,
            tremor: t.tremor,
        })
    }

    pub fn load(path: &Path) -> Result<Self, InputError> {
        Self::load_within(path, xr_bindings::keyframes::DEFAULT_MAX_SESSION_S)
    }

    /// Reads and parses a trace whose keys all lie within `max_s` seconds.
    pub fn load_within(path: &Path, max_s: f64) -> Result<Self, InputError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::parse_within(&file, &text, max_s)
    }

    /// Drops every keyframe after `t_s` (each hand keeps at least its first) and every
    /// tremor that starts after it; one under way at `t_s` keeps its end, so the tremor up to
    /// `t_s` is unchanged.
    pub fn truncate_to(&mut self, t_s: f64) {
        for keys in &mut self.keys {
            let keep = keys.iter().filter(|k| k.t_s <= t_s).count().max(1);
            keys.truncate(keep);
        }
        self.head.retain(|k| k.t_s <= t_s);
        self.tremor.retain(|tr| tr.from_s <= t_s);
    }

    /// Time of the last hand keyframe, seconds.
    pub fn duration_s(&self) -> f64 {
        self.keys
            .iter()
            .filter_map(|k| k.last())
            .map(|k| k.t_s)
            .fold(0.0, f64::max)
    }

    /// The input at time `t_s`, with the trace's interpolation and tremor (as the simulated
    /// XR runtime plays the same file).
    pub fn sample(&self, t_s: f64) -> InputFrame {
        let mut frame = InputFrame::default();
        for hand in Hand::BOTH {
            let i = hand.index();
            let sample = xr_bindings::keyframes::sample_hand_with(
                &self.keys[i],
                self.interpolation,
                &self.tremor,
                i,
                t_s,
            );
            if let Some(h) = sample {
                frame.hands[i] = HandInput {
                    pose: Pose {
                        position: h.position,
                        orientation: xr_bindings::keyframes::hand_orientation(
                            h.position, h.target, h.roll_deg,
                        ),
                    },
                    buttons: Buttons {
                        trigger: h.trigger,
                        grip: h.grip,
                        mark: h.mark,
                        pad: h.pad,
                    },
                };
            }
        }
        frame
    }
}
