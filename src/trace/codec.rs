//! The byte reader and the frame encoding every version shares.

use super::blocks::BlockKind;
use crate::scenario::InputError;
use crate::sim::{Buttons, HandInput, InputFrame, PadDirection, Pose};
use glam::{Quat, Vec3};
use std::fmt::Display;

/// Bytes per hand per step: 3 + 4 + 2 floats, one flag byte.
const HAND_BYTES: usize = 9 * 4 + 1;
/// Bytes per frame: left hand, then right.
pub(super) const FRAME_BYTES: usize = 2 * HAND_BYTES;
/// A frames block's payload before its frames: `first_step` (u64) and `count` (u32).
pub(super) const FRAMES_HEAD_BYTES: usize = 8 + 4;

/// The flag byte's low bit: the mark button (the trackpad's click).
const MARK_BIT: u8 = 1;
/// The flag byte's bits 1 to 3: the pad press (0 none, 1 up, 2 down, 3 left, 4 right).
/// Recordings written before pad presses existed hold 0 there.
const PAD_SHIFT: u8 = 1;
const PAD_MASK: u8 = 0b1110;

fn pad_code(p: Option<PadDirection>) -> u8 {
    match p {
        None => 0,
        Some(PadDirection::Up) => 1,
        Some(PadDirection::Down) => 2,
        Some(PadDirection::Left) => 3,
        Some(PadDirection::Right) => 4,
    }
}

/// The buttons' flag byte: the mark, then the pad press.
fn flags(b: &Buttons) -> u8 {
    (u8::from(b.mark) * MARK_BIT) | (pad_code(b.pad) << PAD_SHIFT)
}

/// One frame: per hand (left, then right) position, orientation (x, y, z, w), trigger and grip
/// as f32, then one byte of flags (the mark button, the pad press).
pub(super) fn encode_frame(f: &InputFrame, out: &mut Vec<u8>) {
    for h in &f.hands {
        let p = h.pose.position.to_array();
        let q = h.pose.orientation.to_array();
        for v in p
            .into_iter()
            .chain(q)
            .chain([h.buttons.trigger, h.buttons.grip])
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.push(flags(&h.buttons));
    }
}

/// One frame, which must be finite: a frame the simulation could not have sampled would replay
/// as something else.
pub(super) fn read_frame(r: &mut Reader, step: usize) -> Result<InputFrame, InputError> {
    let mut frame = InputFrame::default();
    for hand in &mut frame.hands {
        let mut v = [0f32; 9];
        for c in &mut v {
            *c = r.f32("frame")?;
        }
        let flags = r.take(1, "frame")?[0];
        let pad = match (flags & PAD_MASK) >> PAD_SHIFT {
            0 => None,
            code => PadDirection::ALL.get(usize::from(code) - 1).copied(),
        };
        if flags & !(MARK_BIT | PAD_MASK) != 0 || (pad.is_none() && flags & PAD_MASK != 0) {
            return Err(r.fail(
                &format!("frame {step}"),
                format!("button flags {flags:#010b}: only the mark bit and a pad press 0-4 exist"),
            ));
        }
        let mark = flags & MARK_BIT != 0;
        *hand = HandInput {
            pose: Pose {
                position: Vec3::new(v[0], v[1], v[2]),
                orientation: Quat::from_xyzw(v[3], v[4], v[5], v[6]),
            },
            buttons: Buttons {
                trigger: v[7],
                grip: v[8],
                mark,
                pad,
            },
        };
    }
    if !frame.is_finite() {
        return Err(r.fail(
            &format!("frame {step}"),
            "pose or button is not a finite number",
        ));
    }
    Ok(frame)
}

/// Reads little-endian values from a whole file (versions 1 and 2, whose errors are keyed by
/// what was being read) or from one block's payload (keyed by the block).
pub(super) struct Reader<'a> {
    b: &'a [u8],
    at: usize,
    pub(super) file: &'a str,
    /// `block N` and the block's kind, when reading a payload.
    block: Option<(String, BlockKind)>,
}

impl<'a> Reader<'a> {
    pub(super) fn legacy(file: &'a str, b: &'a [u8]) -> Self {
        Self {
            b,
            at: 0,
            file,
            block: None,
        }
    }

    pub(super) fn block(file: &'a str, key: String, kind: BlockKind, payload: &'a [u8]) -> Self {
        Self {
            b: payload,
            at: 0,
            file,
            block: Some((key, kind)),
        }
    }

    pub(super) fn fail(&self, what: &str, message: impl Display) -> InputError {
        match &self.block {
            None => InputError::new(self.file, what, message.to_string()),
            Some((key, kind)) => InputError::new(
                self.file,
                key,
                format!("{} block: {what}: {message}", kind.name()),
            ),
        }
    }

    pub(super) fn left(&self) -> usize {
        self.b.len() - self.at
    }

    /// A payload read in full (its checksum matched, so spare bytes are a writer's bug).
    pub(super) fn finished(&self) -> Result<(), InputError> {
        match self.left() {
            0 => Ok(()),
            n => Err(self.fail("payload", format!("{n} bytes left over"))),
        }
    }

    pub(super) fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], InputError> {
        if n > self.left() {
            return Err(self.fail(
                what,
                match self.block {
                    None => "file ends early (truncated recording)",
                    Some(_) => "payload ends early",
                },
            ));
        }
        let s = &self.b[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }

    pub(super) fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], InputError> {
        let mut a = [0; N];
        a.copy_from_slice(self.take(N, what)?);
        Ok(a)
    }

    pub(super) fn u16(&mut self, what: &str) -> Result<u16, InputError> {
        Ok(u16::from_le_bytes(self.array(what)?))
    }

    pub(super) fn u32(&mut self, what: &str) -> Result<u32, InputError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    pub(super) fn u64(&mut self, what: &str) -> Result<u64, InputError> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }

    pub(super) fn f32(&mut self, what: &str) -> Result<f32, InputError> {
        Ok(f32::from_le_bytes(self.array(what)?))
    }

    pub(super) fn string(&mut self, what: &str) -> Result<String, InputError> {
        let n = self.u32(what)? as usize;
        let s = self.take(n, what)?;
        String::from_utf8(s.to_vec()).map_err(|_| self.fail(what, "is not UTF-8"))
    }
}
