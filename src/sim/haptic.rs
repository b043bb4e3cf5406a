//! The haptic channel: every step the simulation publishes a small frame per instrument (the
//! total contact force on it, where and along which normal it touches, and how stiff the
//! tissue feels there) into a slot that never blocks the step. Force-feedback loops at 1 kHz
//! and the Vive's vibration read the newest frame.
//!
//! The slot is a sequence lock over plain atomics ([`SeqWords`], which the servo's stylus
//! slot uses too): the single writer marks the sequence odd, stores the words, marks it even;
//! a reader copies the words and keeps the copy only if the sequence was even and unchanged
//! around it. The writer never waits; a reader retries (a few hundred nanoseconds) when it
//! raced a write.

use glam::Vec3;
use std::sync::atomic::{AtomicU64, Ordering, fence};

/// What one instrument feels after a step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ToolHaptics {
    /// Total force the tissue exerts on the instrument, newtons.
    pub force_n: Vec3,
    /// Where it touches, metres (the tip, or where a beam lands).
    pub point: Vec3,
    /// The tissue's outward normal there (unit, or zero without contact).
    pub normal: Vec3,
    /// How stiff the tissue feels along the normal, N/m: the change of force over the change
    /// of depth between steps, smoothed (0 without contact).
    pub stiffness_n_per_m: f32,
    pub in_contact: bool,
}

/// One step's haptic frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct HapticFrame {
    pub step: u64,
    pub time_s: f64,
    /// Left, right.
    pub tools: [ToolHaptics; 2],
}

/// Words per tool: force, point, normal (3 each), stiffness, contact flag.
const TOOL_WORDS: usize = 11;
/// Words in a frame: the step, the time and both tools.
const WORDS: usize = 2 + 2 * TOOL_WORDS;

/// A sequence lock over `N` words: one writer that never waits, readers that retry when they
/// raced a write. The one mechanism behind [`HapticSlot`] and the servo's stylus slot.
#[derive(Debug)]
pub struct SeqWords<const N: usize> {
    seq: AtomicU64,
    words: [AtomicU64; N],
}

impl<const N: usize> Default for SeqWords<N> {
    fn default() -> Self {
        SeqWords {
            seq: AtomicU64::new(0),
            words: std::array::from_fn(|_| AtomicU64::new(0)),
        }
    }
}

impl<const N: usize> SeqWords<N> {
    /// Stores `w` (one writer at a time). Never waits.
    pub fn write(&self, w: [u64; N]) {
        let s = self.seq.load(Ordering::Relaxed);
        self.seq.store(s.wrapping_add(1), Ordering::Relaxed);
        fence(Ordering::Release);
        for (slot, word) in self.words.iter().zip(w) {
            slot.store(word, Ordering::Relaxed);
        }
        self.seq.store(s.wrapping_add(2), Ordering::Release);
    }

    /// The newest whole set of words; none before the first write.
    pub fn read(&self) -> Option<[u64; N]> {
        loop {
            let before = self.seq.load(Ordering::Acquire);
            if before == 0 {
                return None;
            }
            if before % 2 == 1 {
                std::hint::spin_loop();
                continue;
            }
            let w: [u64; N] = std::array::from_fn(|i| self.words[i].load(Ordering::Relaxed));
            fence(Ordering::Acquire);
            if self.seq.load(Ordering::Relaxed) == before {
                return Some(w);
            }
        }
    }
}

/// The newest haptic frame, written by the simulation and read by any thread.
#[derive(Debug, Default)]
pub struct HapticSlot {
    words: SeqWords<WORDS>,
}

fn encode(f: &HapticFrame) -> [u64; WORDS] {
    let mut w = [0u64; WORDS];
    w[0] = f.step;
    w[1] = f.time_s.to_bits();
    for (k, tool) in f.tools.iter().enumerate() {
        let o = 2 + k * TOOL_WORDS;
        let v = [tool.force_n, tool.point, tool.normal];
        for (j, c) in v.iter().flat_map(|v| v.to_array()).enumerate() {
            w[o + j] = u64::from(c.to_bits());
        }
        w[o + 9] = u64::from(tool.stiffness_n_per_m.to_bits());
        w[o + 10] = u64::from(tool.in_contact);
    }
    w
}

fn decode(w: &[u64; WORDS]) -> HapticFrame {
    // The low half holds an f32's bits (encode wrote no more).
    let f = |i: usize| f32::from_bits(w[i] as u32);
    let v = |i: usize| Vec3::new(f(i), f(i + 1), f(i + 2));
    let tool = |k: usize| {
        let o = 2 + k * TOOL_WORDS;
        ToolHaptics {
            force_n: v(o),
            point: v(o + 3),
            normal: v(o + 6),
            stiffness_n_per_m: f(o + 9),
            in_contact: w[o + 10] != 0,
        }
    };
    HapticFrame {
        step: w[0],
        time_s: f64::from_bits(w[1]),
        tools: [tool(0), tool(1)],
    }
}

impl HapticSlot {
    pub fn new() -> Self {
        Self::default()
    }

    /// Publishes a frame (one writer: the simulation thread). Never waits.
    pub fn publish(&self, f: &HapticFrame) {
        self.words.write(encode(f));
    }

    /// The newest whole frame (the all-zero one before the first publish).
    pub fn latest(&self) -> HapticFrame {
        decode(&self.words.read().unwrap_or([0; WORDS]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(n: u64) -> HapticFrame {
        let x = n as f32;
        let tool = ToolHaptics {
            force_n: Vec3::splat(x),
            point: Vec3::splat(-x),
            normal: Vec3::new(x, 0.5, x),
            stiffness_n_per_m: x * 2.0,
            in_contact: n.is_multiple_of(2),
        };
        HapticFrame {
            step: n,
            time_s: n as f64 * 0.002,
            tools: [tool, tool],
        }
    }

    #[test]
    fn a_frame_reads_back_whole() {
        let slot = HapticSlot::new();
        assert_eq!(slot.latest(), HapticFrame::default());
        slot.publish(&frame(41));
        assert_eq!(slot.latest(), frame(41));
    }

    #[test]
    fn readers_racing_the_writer_never_see_a_torn_frame() {
        let slot = HapticSlot::new();
        let n = 200_000;
        let seen = std::thread::scope(|s| {
            s.spawn(|| {
                for k in 1..=n {
                    slot.publish(&frame(k));
                }
            });
            let reader = s.spawn(|| {
                let mut last = 0;
                let mut distinct = 0;
                while last < n {
                    let f = slot.latest();
                    // Whole: every field agrees with the step it claims; in order.
                    assert!(f.step == 0 || f == frame(f.step), "torn: {f:?}");
                    assert!(f.step >= last, "went back from {last} to {}", f.step);
                    distinct += usize::from(f.step != last);
                    last = f.step;
                }
                distinct
            });
            reader.join().unwrap_or(0)
        });
        assert!(seen > 0);
        assert_eq!(slot.latest(), frame(n));
    }
}
