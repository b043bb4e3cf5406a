//! A recorded session input and its decoding: version 3 (checksummed blocks, written while the
//! session runs) here, the monolithic versions 1 and 2 of earlier releases in `legacy`.

use super::blocks::{self, BlockKind, FramingError, MAGIC, Next, PREAMBLE_BYTES};
use super::codec::{FRAME_BYTES, FRAMES_HEAD_BYTES, Reader, read_frame};
use super::legacy::decode_legacy;
use super::stream::{RecordingHeader, RecordingWriter};
use crate::models::Tuning;
use crate::scenario::{InputError, check_procedure};
use crate::sim::InputFrame;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Tissue parameters changed during a session, applied before the frame of step `step`.
#[derive(Debug, Clone, PartialEq)]
pub struct TuningRecord {
    pub step: u64,
    /// The model tuned, as the scenario names it.
    pub model: String,
    /// Each parameter's name and new value.
    pub values: Vec<(String, f32)>,
}

impl TuningRecord {
    /// A soft body's tuning, its values named as in [`Tuning::RANGES`].
    pub fn from_tuning(step: u64, model: &str, t: &Tuning) -> Self {
        Self {
            step,
            model: model.to_string(),
            values: Tuning::RANGES
                .iter()
                .zip(t.values())
                .map(|((name, _, _), v)| (name.to_string(), v))
                .collect(),
        }
    }

    /// The soft-body tuning these values make: each of [`Tuning::RANGES`] exactly once, in
    /// range. `Err` says what is wrong.
    pub fn to_tuning(&self) -> Result<Tuning, TuningRecordError> {
        let model = || self.model.clone();
        let mut v = [f32::NAN; 3];
        let mut seen = [false; 3];
        for (name, value) in &self.values {
            let i = Tuning::RANGES
                .iter()
                .position(|r| r.0 == name)
                .ok_or_else(|| TuningRecordError::UnknownParameter {
                    model: model(),
                    name: name.clone(),
                })?;
            if std::mem::replace(&mut seen[i], true) {
                return Err(TuningRecordError::GivenTwice {
                    model: model(),
                    name: name.clone(),
                });
            }
            v[i] = *value;
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return Err(TuningRecordError::Missing {
                model: model(),
                name: Tuning::RANGES[i].0,
            });
        }
        let t = Tuning {
            foundation_pa_per_m: v[0],
            damping_per_s: v[1],
            offset_m: v[2],
        };
        t.check()
            .map_err(|(name, message)| TuningRecordError::OutOfRange {
                model: model(),
                name,
                message,
            })?;
        Ok(t)
    }
}

/// What is wrong with a tuning record: as a recording's block (the reader refuses it, the
/// writer never writes it), or as a soft-body tuning ([`TuningRecord::to_tuning`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TuningRecordError {
    #[error("step {step} is out of order or past the last frame ({frames})")]
    OutOfOrder { step: u64, frames: u64 },
    #[error("no model named")]
    NoModel,
    #[error("{count} values, at most {}", u16::MAX)]
    TooManyValues { count: usize },
    #[error("value {index}: name {name:?} is empty or repeated")]
    BadName { index: usize, name: String },
    #[error("{name} is not a finite number ({value})")]
    NotFinite { name: String, value: f32 },
    #[error("{model}: no soft-body parameter named {name}")]
    UnknownParameter { model: String, name: String },
    #[error("{model}: {name} is given twice")]
    GivenTwice { model: String, name: String },
    #[error("{model}: {name} is missing")]
    Missing { model: String, name: &'static str },
    /// A value outside its range: `message` says the range and the value.
    #[error("{model}.{name}: {message}")]
    OutOfRange {
        model: String,
        name: &'static str,
        message: String,
    },
}

/// How a recording ends.
#[derive(Debug, Clone, PartialEq)]
pub enum Tail {
    /// The writer finished: `how` the session ended ("completed", "trace_end", "interrupted",
    /// "error"; "legacy" for versions 1 and 2, which do not say).
    Ended { how: String },
    /// The file stops without an end block (the session was killed, or the disk filled): what
    /// is here is every complete block, and `dropped_bytes` of a block being written follow.
    Cut {
        complete_blocks: u32,
        dropped_bytes: u64,
    },
}

/// A recorded session input: the scenario text it ran with, every sampled frame, and the tissue
/// parameters changed during the session (each applied before the frame of its step).
#[derive(Debug, Clone, PartialEq)]
pub struct Recording {
    pub procedure: String,
    /// Which session this was ("" in versions 1 and 2).
    pub session_id: String,
    pub dt_s: f32,
    pub scenario: String,
    pub frames: Vec<InputFrame>,
    /// In step order.
    pub tunings: Vec<TuningRecord>,
    pub tail: Tail,
}

impl Recording {
    /// Writes a version 3 file: to a `.partial` sibling first, renamed over `path` once
    /// complete, so that `path` never holds half a recording. A cut recording is written as
    /// ended "interrupted".
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let tmp = partial_path(path);
        let r = self
            .write_to(&tmp)
            .and_then(|()| std::fs::rename(&tmp, path));
        if r.is_err() {
            // Best effort: the error that matters is the one returned.
            let _ = std::fs::remove_file(&tmp);
        }
        r
    }

    fn write_to(&self, path: &Path) -> std::io::Result<()> {
        let mut w = RecordingWriter::create(
            path,
            &RecordingHeader {
                session_id: &self.session_id,
                procedure: &self.procedure,
                dt_s: self.dt_s,
                scenario: &self.scenario,
            },
        )?
        // Written all at once: blocks of a simulated second each, whatever the wall clock.
        .with_wall_interval(Duration::MAX);
        let mut tunings = self.tunings.iter().peekable();
        for (step, f) in self.frames.iter().enumerate() {
            while let Some(t) = tunings.next_if(|t| t.step == step as u64) {
                w.push_tuning(t)?;
            }
            w.push_frame(f)?;
        }
        // Tunings at the end step; any other left is out of order, which the writer refuses.
        for t in tunings {
            w.push_tuning(t)?;
        }
        w.finish(match &self.tail {
            Tail::Ended { how } => how,
            Tail::Cut { .. } => "interrupted",
        })
    }

    pub fn read(path: &Path) -> Result<Self, InputError> {
        let file = path.display().to_string();
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::decode(&file, &bytes)
    }

    /// Resolves the recording against `catalog`: its procedure must be one of it, and the
    /// tunings of a version 1 or 2 recording (which name no model) go to the model its
    /// procedure names for them. `file` names it in errors.
    pub fn resolve(&mut self, catalog: &crate::sim::Catalog, file: &str) -> Result<(), InputError> {
        let info = catalog.lookup(file, "procedure", &self.procedure)?;
        self.name_legacy_tunings(file, info.options.legacy_tuned_model)
    }

    /// Gives the tunings that name no model (versions 1 and 2) to `model`; an error naming
    /// the first such tuning where there is no model to give them.
    pub fn name_legacy_tunings(
        &mut self,
        file: &str,
        model: Option<&str>,
    ) -> Result<(), InputError> {
        for (j, t) in self.tunings.iter_mut().enumerate() {
            if t.model.is_empty() {
                let model = model.ok_or_else(|| {
                    InputError::new(
                        file,
                        &format!("tuning {j}"),
                        "this procedure's recordings never had tunings",
                    )
                })?;
                t.model = model.to_string();
            }
        }
        Ok(())
    }

    pub fn is_recording(bytes: &[u8]) -> bool {
        bytes.starts_with(MAGIC)
    }

    /// Decodes any version. A version 3 file that stops inside a block decodes to what came
    /// before it ([`Tail::Cut`]); anything that cannot be what the writer wrote is an error.
    pub fn decode(file: &str, bytes: &[u8]) -> Result<Self, InputError> {
        let mut r = Reader::legacy(file, bytes);
        if r.take(MAGIC.len(), "header")? != MAGIC {
            return Err(InputError::new(
                file,
                "header",
                "not a Vesalius recording (magic VSLTRACE missing)",
            ));
        }
        match r.u32("version")? {
            v @ (1 | 2) => decode_legacy(r, v),
            blocks::VERSION => V3::new(file).decode(bytes),
            v => Err(InputError::new(
                file,
                "version",
                format!("unsupported version {v}, expected 1 to {}", blocks::VERSION),
            )),
        }
    }
}

/// Where a whole recording is written before it is renamed: `input.vtrace.partial` for
/// `input.vtrace`.
fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".partial");
    path.with_file_name(name)
}

/// A version 3 header's checks, shared by reader and writer: a procedure's name, a step in
/// range, and a step equal to the embedded scenario's top-level `dt_s` (a replay steps at the
/// scenario's `dt_s`, so a mismatch means the frames are not what ran). The scenario is read as
/// plain TOML: this module does not know any procedure's scenario.
pub(super) fn check_header(file: &str, h: &RecordingHeader) -> Result<(), InputError> {
    check_procedure(file, "procedure", h.procedure)?;
    check_dt(file, h.dt_s)?;
    let table: toml::Table = h.scenario.parse().map_err(|e: toml::de::Error| {
        let e = e.to_string();
        let e = e.trim_end().replace('\n', " | ");
        InputError::new(
            file,
            "scenario",
            format!("embedded scenario is not TOML: {e}"),
        )
    })?;
    let scenario_dt_s = match table.get("dt_s") {
        Some(toml::Value::Float(v)) => Some(*v as f32),
        Some(toml::Value::Integer(v)) => Some(*v as f32),
        _ => None,
    };
    match scenario_dt_s {
        Some(s) if s == h.dt_s => Ok(()),
        Some(s) => Err(InputError::new(
            file,
            "dt_s",
            format!("the header says {} s, its scenario says {s} s", h.dt_s),
        )),
        None => Err(InputError::new(
            file,
            "dt_s",
            format!(
                "the header says {} s, its scenario has no numeric dt_s",
                h.dt_s
            ),
        )),
    }
}

/// The step range every version shares (the scenario's own limits).
pub(super) fn check_dt(file: &str, dt_s: f32) -> Result<(), InputError> {
    if !dt_s.is_finite() || !(1e-4..=0.01).contains(&dt_s) {
        return Err(InputError::new(
            file,
            "dt_s",
            format!("must be 1e-4..0.01 s, got {dt_s}"),
        ));
    }
    Ok(())
}

/// `Err` says why `t` cannot follow `frames` frames and a tuning at `previous_step`; shared by
/// reader and writer so that the writer never writes what the reader rejects.
pub(super) fn check_tuning(
    t: &TuningRecord,
    frames: u64,
    previous_step: Option<u64>,
) -> Result<(), TuningRecordError> {
    if t.step > frames || previous_step.is_some_and(|p| t.step < p) {
        return Err(TuningRecordError::OutOfOrder {
            step: t.step,
            frames,
        });
    }
    if t.model.is_empty() {
        return Err(TuningRecordError::NoModel);
    }
    if t.values.len() > usize::from(u16::MAX) {
        return Err(TuningRecordError::TooManyValues {
            count: t.values.len(),
        });
    }
    for (index, (name, v)) in t.values.iter().enumerate() {
        if name.is_empty() || t.values[..index].iter().any(|(n, _)| n == name) {
            return Err(TuningRecordError::BadName {
                index,
                name: name.clone(),
            });
        }
        if !v.is_finite() {
            return Err(TuningRecordError::NotFinite {
                name: name.clone(),
                value: *v,
            });
        }
    }
    Ok(())
}

/// Decoding state of a version 3 file.
struct V3<'a> {
    file: &'a str,
    header: Option<(String, String, f32, String)>,
    frames: Vec<InputFrame>,
    tunings: Vec<TuningRecord>,
    ended: Option<String>,
}

impl<'a> V3<'a> {
    fn new(file: &'a str) -> Self {
        Self {
            file,
            header: None,
            frames: Vec::new(),
            tunings: Vec::new(),
            ended: None,
        }
    }

    fn decode(mut self, bytes: &[u8]) -> Result<Recording, InputError> {
        let mut at = PREAMBLE_BYTES;
        let mut n: u32 = 0;
        let tail = loop {
            let key = format!("block {n}");
            let rest = &bytes[at..];
            if self.ended.is_some() && !rest.is_empty() {
                let m = format!("{} bytes follow the end block", rest.len());
                return Err(InputError::new(self.file, &key, m));
            }
            let b = match blocks::next_block(rest) {
                Ok(Next::Block(b)) => b,
                Ok(Next::Eof) => match self.ended.take() {
                    Some(how) => break Tail::Ended { how },
                    None => break self.cut(n, 0),
                },
                Ok(Next::Cut) => break self.cut(n, rest.len()),
                Err(e) => {
                    let m = format!("{e}{}", self.where_(&e));
                    return Err(InputError::new(self.file, &key, m));
                }
            };
            let fail = |m: String| InputError::new(self.file, &key, m);
            if b.seq != n {
                return Err(fail(format!("sequence number {}, expected {n}", b.seq)));
            }
            let kind = BlockKind::from_byte(b.kind)
                .ok_or_else(|| fail(format!("unknown block kind {}", b.kind)))?;
            if (n == 0) != (kind == BlockKind::Header) {
                return Err(fail(format!(
                    "a {} block; the header block comes first, once",
                    kind.name()
                )));
            }
            let mut r = Reader::block(self.file, key.clone(), kind, b.payload);
            match kind {
                BlockKind::Header => self.header(&mut r)?,
                BlockKind::Frames => self.frames(&mut r)?,
                BlockKind::Tuning => self.tuning(&mut r)?,
                BlockKind::End => self.end(&mut r)?,
            }
            r.finished()?;
            at += b.file_bytes();
            n = n
                .checked_add(1)
                .ok_or_else(|| InputError::new(self.file, &key, "more than 2^32 blocks"))?;
        };
        let (session_id, procedure, dt_s, scenario) = self.header.ok_or_else(|| {
            InputError::new(
                self.file,
                "block 0",
                "the file ends before its header block is complete (truncated recording)",
            )
        })?;
        Ok(Recording {
            procedure,
            session_id,
            dt_s,
            scenario,
            frames: self.frames,
            tunings: self.tunings,
            tail,
        })
    }

    fn cut(&self, complete_blocks: u32, dropped_bytes: usize) -> Tail {
        Tail::Cut {
            complete_blocks,
            dropped_bytes: dropped_bytes as u64,
        }
    }

    /// Which part of the session a corrupted block held, as far as its sound header tells.
    fn where_(&self, e: &FramingError) -> String {
        let done = self.frames.len();
        match *e {
            FramingError::PayloadChecksum { kind, len } if kind == BlockKind::Frames as u8 => {
                let count = (len as usize).saturating_sub(FRAMES_HEAD_BYTES) / FRAME_BYTES;
                match count {
                    0 => format!(" (after frame {done})"),
                    c => format!(" (frames {done}..{})", done + c - 1),
                }
            }
            _ => format!(" (after {done} frames)"),
        }
    }

    fn header(&mut self, r: &mut Reader) -> Result<(), InputError> {
        let session_id = r.string("session id")?;
        let procedure = r.string("procedure")?;
        let dt_s = r.f32("dt_s")?;
        let scenario = r.string("scenario")?;
        check_header(
            self.file,
            &RecordingHeader {
                session_id: &session_id,
                procedure: &procedure,
                dt_s,
                scenario: &scenario,
            },
        )?;
        self.header = Some((session_id, procedure, dt_s, scenario));
        Ok(())
    }

    fn frames(&mut self, r: &mut Reader) -> Result<(), InputError> {
        let first_step = r.u64("first step")?;
        let count = r.u32("count")? as usize;
        let want = count.saturating_mul(FRAME_BYTES);
        if r.left() != want {
            let m = format!("{want} bytes for {count} frames, found {}", r.left());
            return Err(r.fail("frames", m));
        }
        let done = self.frames.len() as u64;
        if first_step != done {
            let m = format!("first step {first_step}, expected {done} (frames read so far)");
            return Err(r.fail("frames", m));
        }
        self.frames.reserve(count);
        for _ in 0..count {
            let step = self.frames.len();
            self.frames.push(read_frame(r, step)?);
        }
        Ok(())
    }

    fn tuning(&mut self, r: &mut Reader) -> Result<(), InputError> {
        let step = r.u64("step")?;
        let model = r.string("model")?;
        let n = r.u16("count")?;
        let mut values = Vec::with_capacity(usize::from(n).min(r.left() / 8));
        for _ in 0..n {
            values.push((r.string("name")?, r.f32("value")?));
        }
        let t = TuningRecord {
            step,
            model,
            values,
        };
        let previous = self.tunings.last().map(|t| t.step);
        check_tuning(&t, self.frames.len() as u64, previous).map_err(|m| r.fail("tuning", m))?;
        self.tunings.push(t);
        Ok(())
    }

    fn end(&mut self, r: &mut Reader) -> Result<(), InputError> {
        let total = r.u64("total frames")?;
        let how = r.string("how")?;
        if total != self.frames.len() as u64 {
            let m = format!("says {total} frames, the file has {}", self.frames.len());
            return Err(r.fail("total frames", m));
        }
        self.ended = Some(how);
        Ok(())
    }
}
