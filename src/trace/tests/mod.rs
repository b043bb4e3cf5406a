//! Recording tests: the shared samples and hand-made blocks; the format's tests in `decode`,
//! the streaming writer's in `writer`.

mod decode;
mod writer;

use super::blocks::{self, BlockKind, Next, PREAMBLE_BYTES};
use super::codec::encode_frame;
use super::{
    Recording, RecordingHeader, RecordingSink, RecordingWriter, Tail, TuningRecord,
    TuningRecordError,
};
use crate::models::Tuning;
use crate::sim::{Buttons, HandInput, InputFrame, Pose};
use crate::testing::Scratch;
use glam::{Quat, Vec3};
use std::io::{self, Write};
use std::path::Path;
use std::time::Duration;

/// The procedure the samples are of (recordings name one; which are registered is the
/// session's business).
fn procedure() -> &'static str {
    "drill"
}

/// The model its recordings' tunings belong to.
fn tuned_model() -> &'static str {
    "tissue"
}

fn scenario(dt_s: &str) -> String {
    format!(
        "procedure = \"{}\"\ndt_s = {dt_s}\n\n[{}]\nfoundation_pa_per_m = 1.6e6\n",
        procedure(),
        tuned_model()
    )
}

/// A frame unlike its neighbours, so that a frame out of place is seen.
fn frame(i: usize) -> InputFrame {
    let x = i as f32;
    let hand = |k: f32| HandInput {
        pose: Pose {
            position: Vec3::new(0.001 * x, -0.002 * x + k, 0.2),
            orientation: Quat::from_rotation_y(0.01 * x + k),
        },
        buttons: Buttons {
            trigger: (i % 10) as f32 / 10.0,
            grip: (i % 3) as f32 / 3.0 + k * 0.1,
            mark: i.is_multiple_of(7),
            // Every press, and none, in turn.
            pad: crate::sim::PadDirection::ALL.get(i % 6).copied(),
        },
    };
    InputFrame {
        hands: [hand(0.0), hand(1.0)],
    }
}

fn tuned(step: u64, foundation_pa_per_m: f32) -> TuningRecord {
    let t = Tuning {
        foundation_pa_per_m,
        damping_per_s: 4.0,
        offset_m: 0.002,
    };
    TuningRecord::from_tuning(step, tuned_model(), &t)
}

fn recording(dt_s: &str, frames: usize) -> Recording {
    let end = frames as u64;
    Recording {
        procedure: procedure().into(),
        session_id: "2024-05-01T10-00-00-ab12".into(),
        dt_s: dt_s.parse().expect("dt"),
        scenario: scenario(dt_s),
        frames: (0..frames).map(frame).collect(),
        tunings: vec![
            tuned(0, 6.0e6),
            tuned(end / 2, 8.0e6),
            TuningRecord {
                step: end / 2,
                model: "fat".into(),
                values: vec![("pressure_pa".into(), 10.0), ("damping_per_s".into(), 2.5)],
            },
            tuned(end, 9.0e6),
        ],
        tail: Tail::Ended {
            how: "completed".into(),
        },
    }
}

/// The test's own scratch folder, removed when it passes (keep it to the test's end).
fn dir(name: &str) -> Scratch {
    Scratch::new("trace", name)
}

fn header<'a>(r: &'a Recording) -> RecordingHeader<'a> {
    RecordingHeader {
        session_id: &r.session_id,
        procedure: &r.procedure,
        dt_s: r.dt_s,
        scenario: &r.scenario,
    }
}

/// The file's bytes of `r` as `Recording::write` makes them, and the folder it is in.
fn bytes_of(r: &Recording, name: &str) -> (Vec<u8>, Scratch) {
    let dir = dir(name);
    let path = dir.join("input.vtrace");
    r.write(&path).expect("write");
    (std::fs::read(&path).expect("read"), dir)
}

/// (start, end) of each block of a sound version 3 file.
fn block_spans(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut at = PREAMBLE_BYTES;
    let mut spans = Vec::new();
    while let Ok(Next::Block(b)) = blocks::next_block(&bytes[at..]) {
        spans.push((at, at + b.file_bytes()));
        at += b.file_bytes();
    }
    assert_eq!(at, bytes.len(), "the sample file is sound");
    spans
}

/// A version 3 file of hand-made blocks (numbered in order unless `seq` says otherwise).
fn v3(blocks_: &[(u32, BlockKind, Vec<u8>)]) -> Vec<u8> {
    let mut out = blocks::preamble().to_vec();
    let mut b = Vec::new();
    for (seq, kind, payload) in blocks_ {
        blocks::encode(*seq, *kind, &[payload], &mut b).expect("encode");
        out.extend_from_slice(&b);
    }
    out
}

fn put_str(out: &mut Vec<u8>, s: &[u8]) {
    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
    out.extend_from_slice(s);
}

fn header_payload(dt_s: f32, scenario: &str) -> Vec<u8> {
    let mut p = Vec::new();
    put_str(&mut p, b"id");
    put_str(&mut p, procedure().as_bytes());
    p.extend_from_slice(&dt_s.to_le_bytes());
    put_str(&mut p, scenario.as_bytes());
    p
}

fn frames_payload(first_step: u64, frames: &[InputFrame]) -> Vec<u8> {
    let mut p = first_step.to_le_bytes().to_vec();
    p.extend_from_slice(&(frames.len() as u32).to_le_bytes());
    for f in frames {
        encode_frame(f, &mut p);
    }
    p
}

fn end_payload(total: u64, how: &str) -> Vec<u8> {
    let mut p = total.to_le_bytes().to_vec();
    put_str(&mut p, how.as_bytes());
    p
}

fn tuning_payload(step: u64, values: &[(&[u8], f32)]) -> Vec<u8> {
    let mut p = step.to_le_bytes().to_vec();
    put_str(&mut p, tuned_model().as_bytes());
    p.extend_from_slice(&(values.len() as u16).to_le_bytes());
    for (name, v) in values {
        put_str(&mut p, name);
        p.extend_from_slice(&v.to_le_bytes());
    }
    p
}
