//! Versions 1 and 2: one monolithic record, written at the end of a session by earlier
//! releases. They still read, as ended "legacy". Their tunings name no model: they are read
//! with an empty model, which [`Recording::resolve`] gives the model the procedure names
//! for them (`ProcedureInfo::legacy_tuned_model`).

use super::codec::{FRAME_BYTES, Reader, read_frame};
use super::recording::{Recording, Tail, TuningRecord, check_dt};
use crate::models::Tuning;
use crate::scenario::{InputError, check_procedure};

/// Versions 1 and 2: bytes per tuning, the step (u64) and four floats.
const LEGACY_TUNING_BYTES: usize = 8 + 4 * 4;
/// Versions 1 and 2, after the magic and version: procedure, scenario, dt, frames and (2) the
/// tunings of the one tunable model, all in one record.
pub(super) fn decode_legacy(mut r: Reader, version: u32) -> Result<Recording, InputError> {
    let file = r.file;
    let version_2 = version == 2;
    let procedure = r.string("procedure")?;
    check_procedure(file, "procedure", &procedure)?;
    let scenario = r.string("scenario")?;
    let dt_s = r.f32("dt_s")?;
    check_dt(file, dt_s)?;
    let n = r.u64("frames")? as usize;
    let frame_bytes = n.saturating_mul(FRAME_BYTES);
    if (!version_2 && r.left() != frame_bytes) || r.left() < frame_bytes {
        let m = format!(
            "expected {frame_bytes} bytes of frames for {n} frames, found {}",
            r.left()
        );
        return Err(InputError::new(file, "frames", m));
    }
    let mut frames = Vec::with_capacity(n);
    for step in 0..n {
        frames.push(read_frame(&mut r, step)?);
    }
    let mut tunings: Vec<TuningRecord> = Vec::new();
    if version_2 {
        let k = r.u32("tunings")? as usize;
        let want = k.saturating_mul(LEGACY_TUNING_BYTES);
        if r.left() != want {
            let m = format!("expected {want} bytes for {k} tunings, found {}", r.left());
            return Err(InputError::new(file, "tunings", m));
        }
        for j in 0..k {
            let step = r.u64("tunings")?;
            let mut v = [0f32; 4];
            for c in &mut v {
                *c = r.f32("tunings")?;
            }
            let t = Tuning {
                foundation_pa_per_m: v[0],
                damping_per_s: v[1],
                // v[2] was a tool pressure the model never read; it is dropped.
                offset_m: v[3],
            };
            let key = format!("tuning {j}");
            t.check()
                .map_err(|(name, m)| InputError::new(file, &format!("{key}: {name}"), m))?;
            if step > n as u64 || tunings.last().is_some_and(|p| p.step > step) {
                let m = format!("step {step} is out of order or past the last frame ({n})");
                return Err(InputError::new(file, &key, m));
            }
            tunings.push(TuningRecord::from_tuning(step, "", &t));
        }
    }
    Ok(Recording {
        procedure,
        session_id: String::new(),
        dt_s,
        scenario,
        frames,
        tunings,
        tail: Tail::Ended {
            how: "legacy".into(),
        },
    })
}
