//! Streams a version 3 recording to disk while a session runs, so that a session killed (or a
//! machine that loses power) keeps all but its last second of input.

use super::blocks::{self, BlockKind};
use super::codec::{FRAME_BYTES, FRAMES_HEAD_BYTES, encode_frame};
use super::recording::{TuningRecord, check_header, check_tuning};
use crate::sim::InputFrame;
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What a recording is of, written first.
#[derive(Debug, Clone, Copy)]
pub struct RecordingHeader<'a> {
    pub session_id: &'a str,
    pub procedure: &'a str,
    pub dt_s: f32,
    /// The scenario text the session runs; its `dt_s` must be `dt_s`.
    pub scenario: &'a str,
}

/// Where a writer's bytes go: a file, or (in tests) something that can fail on demand.
pub trait RecordingSink: Write {
    /// Makes everything written durable (a file's `fsync`): called once, by
    /// [`RecordingWriter::finish`], since a sync per block would stall the session.
    fn sync_all(&mut self) -> io::Result<()>;
}

impl RecordingSink for File {
    fn sync_all(&mut self) -> io::Result<()> {
        File::sync_all(self)
    }
}

impl RecordingSink for Vec<u8> {
    fn sync_all(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Writes a recording block by block. Frames are kept in memory and written as one block at
/// least once per simulated second and once per wall second (whichever comes first), each block
/// handed to the OS at once; tunings are written as they come. A session that stops without
/// [`finish`](Self::finish) leaves a file that reads as [`Tail::Cut`](super::Tail::Cut);
/// dropping the writer writes nothing more (a drop is a kill: its pending frames, at most a
/// second, are lost), so error paths should call `finish("error")`.
///
/// After a write error every call fails and nothing more is written, so that the file stays a
/// prefix of a valid recording rather than a block cut short followed by sound ones.
pub struct RecordingWriter<W: RecordingSink = File> {
    out: W,
    path: PathBuf,
    next_seq: u32,
    frames_written: u64,
    /// Encoded frames not yet in a block.
    pending: Vec<u8>,
    pending_frames: u32,
    /// When the oldest pending frame was pushed.
    pending_since: Option<Instant>,
    /// Frames in one simulated second: a block is due when this many are pending.
    frames_per_block: u32,
    /// A block is due when the oldest pending frame is this old.
    wall_interval: Duration,
    last_tuning_step: Option<u64>,
    /// The block being framed (kept to reuse its allocation).
    block: Vec<u8>,
    failed: bool,
}

impl RecordingWriter<File> {
    /// Creates (or truncates) `path` and writes the magic, the version and the header block.
    /// A header the reader would reject is refused before `path` is touched.
    pub fn create(path: &Path, h: &RecordingHeader) -> io::Result<Self> {
        check(path, h)?;
        let file = File::create(path)?;
        Self::with_sink(file, path, h)
    }
}

fn check(path: &Path, h: &RecordingHeader) -> io::Result<()> {
    check_header(&path.display().to_string(), h)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))
}

/// Frames in one simulated second, `ceil(1 s / dt)`: a frames block is due when this many are
/// pending. The relative allowance keeps a step that is not exact in binary (10 ms is stored as
/// 9.99999978 ms) at 100 frames rather than 101.
pub(super) fn frames_per_block(dt_s: f32) -> u32 {
    (1.0 / f64::from(dt_s) * (1.0 - 1e-6)).ceil().max(1.0) as u32
}

fn invalid(m: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, m)
}

/// Encodes a string as its u32 length and UTF-8 bytes.
fn put_str(out: &mut Vec<u8>, s: &str) -> io::Result<()> {
    let n =
        u32::try_from(s.len()).map_err(|_| invalid(format!("a string of {} bytes", s.len())))?;
    out.extend_from_slice(&n.to_le_bytes());
    out.extend_from_slice(s.as_bytes());
    Ok(())
}

impl<W: RecordingSink> RecordingWriter<W> {
    /// A writer into `out`, which `path` names in messages; writes the magic, the version and
    /// the header block.
    pub fn with_sink(out: W, path: &Path, h: &RecordingHeader) -> io::Result<Self> {
        check(path, h)?;
        let frames_per_block = frames_per_block(h.dt_s);
        let mut w = Self {
            out,
            path: path.to_path_buf(),
            next_seq: 0,
            frames_written: 0,
            pending: Vec::with_capacity(frames_per_block as usize * FRAME_BYTES),
            pending_frames: 0,
            pending_since: None,
            frames_per_block,
            wall_interval: Duration::from_secs(1),
            last_tuning_step: None,
            block: Vec::new(),
            failed: false,
        };
        let mut payload = Vec::with_capacity(32 + h.scenario.len());
        put_str(&mut payload, h.session_id)?;
        put_str(&mut payload, h.procedure)?;
        payload.extend_from_slice(&h.dt_s.to_le_bytes());
        put_str(&mut payload, h.scenario)?;
        w.guard(|w| w.out.write_all(&blocks::preamble()))?;
        w.write_block(BlockKind::Header, &[&payload])?;
        Ok(w)
    }

    /// Frames wait at most `interval` of wall time before they are written (1 s by default).
    pub fn with_wall_interval(mut self, interval: Duration) -> Self {
        self.wall_interval = interval;
        self
    }

    /// Records the next step's input; writes a frames block when one is due. A frame that is
    /// not finite is refused (the reader would reject the file), and nothing is recorded.
    pub fn push_frame(&mut self, f: &InputFrame) -> io::Result<()> {
        self.usable()?;
        if !f.is_finite() {
            return Err(invalid(format!(
                "frame {}: pose or button is not a finite number",
                self.frames_written
            )));
        }
        encode_frame(f, &mut self.pending);
        self.pending_frames += 1;
        self.frames_written += 1;
        self.pending_since.get_or_insert_with(Instant::now);
        self.flush_if_due()
    }

    /// Records a tuning made before the frame of `t.step` (which must be the frames pushed so
    /// far or earlier, and not before the previous tuning): the pending frames, then the tuning,
    /// are written at once.
    pub fn push_tuning(&mut self, t: &TuningRecord) -> io::Result<()> {
        self.usable()?;
        check_tuning(t, self.frames_written, self.last_tuning_step)
            .map_err(|m| invalid(format!("tuning at step {}: {m}", t.step)))?;
        let mut payload = Vec::with_capacity(16 + t.model.len() + 16 * t.values.len());
        payload.extend_from_slice(&t.step.to_le_bytes());
        put_str(&mut payload, &t.model)?;
        // `check_tuning` caps the count at u16::MAX.
        payload.extend_from_slice(&(t.values.len() as u16).to_le_bytes());
        for (name, v) in &t.values {
            put_str(&mut payload, name)?;
            payload.extend_from_slice(&v.to_le_bytes());
        }
        self.write_pending()?;
        self.write_block(BlockKind::Tuning, &[&payload])?;
        self.last_tuning_step = Some(t.step);
        Ok(())
    }

    /// Writes the pending frames if a block is due; for callers idle between steps (a paused
    /// session), whose frames would otherwise wait for the next push.
    pub fn flush_if_due(&mut self) -> io::Result<()> {
        self.usable()?;
        let due = self.pending_frames >= self.frames_per_block
            || self
                .pending_since
                .is_some_and(|t| t.elapsed() >= self.wall_interval);
        if due { self.write_pending() } else { Ok(()) }
    }

    /// Writes the pending frames now.
    pub fn flush(&mut self) -> io::Result<()> {
        self.usable()?;
        self.write_pending()
    }

    /// Writes the pending frames and the end block saying `how` the session ended, and syncs
    /// the file to disk.
    pub fn finish(mut self, how: &str) -> io::Result<()> {
        self.usable()?;
        self.write_pending()?;
        let mut payload = Vec::with_capacity(12 + how.len());
        payload.extend_from_slice(&self.frames_written.to_le_bytes());
        put_str(&mut payload, how)?;
        self.write_block(BlockKind::End, &[&payload])?;
        self.guard(|w| w.out.sync_all())
    }

    /// Frames pushed so far (written or pending).
    pub fn frames_written(&self) -> u64 {
        self.frames_written
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    fn usable(&self) -> io::Result<()> {
        if self.failed {
            return Err(io::Error::other(format!(
                "{}: an earlier write failed; the recording stops at block {}",
                self.path.display(),
                self.next_seq
            )));
        }
        Ok(())
    }

    /// Runs a write, and stops the writer for good if it fails.
    fn guard(&mut self, f: impl FnOnce(&mut Self) -> io::Result<()>) -> io::Result<()> {
        let r = f(self);
        self.failed |= r.is_err();
        r
    }

    fn write_pending(&mut self) -> io::Result<()> {
        if self.pending_frames == 0 {
            return Ok(());
        }
        let mut head = [0u8; FRAMES_HEAD_BYTES];
        let first_step = self.frames_written - u64::from(self.pending_frames);
        head[..8].copy_from_slice(&first_step.to_le_bytes());
        head[8..].copy_from_slice(&self.pending_frames.to_le_bytes());
        let pending = std::mem::take(&mut self.pending);
        let r = self.write_block(BlockKind::Frames, &[&head, &pending]);
        self.pending = pending;
        r?;
        self.pending.clear();
        self.pending_frames = 0;
        self.pending_since = None;
        Ok(())
    }

    fn write_block(&mut self, kind: BlockKind, parts: &[&[u8]]) -> io::Result<()> {
        let seq = self.next_seq;
        let next_seq = seq
            .checked_add(1)
            .ok_or_else(|| io::Error::other("more than 2^32 blocks in one recording"))?;
        let mut block = std::mem::take(&mut self.block);
        // A block too large to frame is refused before anything is written: the file stays
        // sound and the writer usable.
        let r = blocks::encode(seq, kind, parts, &mut block).and_then(|()| {
            self.guard(|w| {
                w.out.write_all(&block)?;
                w.out.flush()
            })
        });
        self.block = block;
        r?;
        self.next_seq = next_seq;
        Ok(())
    }
}
