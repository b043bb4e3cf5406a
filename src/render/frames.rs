//! Headless frames: render captured snapshots for both eyes, save them as PNGs and write one
//! row of profiler counters per frame.

use super::Renderer;
use super::camera::{DEFAULT_IPD_M, field_eyes};
use super::gpu::{EYE_FORMAT, EyeTarget, Gpu, RenderError, write_png};
use crate::procedures::Viewpoint;
use crate::profiler::FrameCounters;
use crate::sim::Snapshot;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// What rendering a set of frames produced.
pub struct FramesOut {
    pub counters: Vec<FrameCounters>,
    /// Wall time per frame (update + render + GPU finish), milliseconds.
    pub frame_ms: Vec<f64>,
    pub device: String,
}

/// Renders every snapshot, waits for the GPU, and returns the counters. `save` names the
/// folder that gets `left_NNNN.png`, `right_NNNN.png` (and nothing is read back without it).
pub fn render_snapshots(
    gpu: &Gpu,
    view: &Viewpoint,
    snaps: &[Snapshot],
    repeat: usize,
    eye_size: (u32, u32),
    sim_ms_per_frame: f64,
    save: Option<&Path>,
) -> Result<FramesOut, RenderError> {
    gpu.check_eye_size(eye_size)?;
    let mut renderer = Renderer::new(gpu, EYE_FORMAT);
    let target = EyeTarget::new(gpu, eye_size);
    gpu.check()?;
    let eyes = field_eyes(view, DEFAULT_IPD_M);
    let mut counters = Vec::with_capacity(snaps.len());
    let mut frame_ms = Vec::with_capacity(snaps.len());
    if let Some(dir) = save {
        std::fs::create_dir_all(dir).map_err(|e| RenderError::Write {
            path: dir.display().to_string(),
            message: e.to_string(),
        })?;
    }
    let each = snaps
        .iter()
        .flat_map(|s| std::iter::repeat_n(s, repeat.max(1)));
    for (k, snap) in each.enumerate() {
        let t0 = Instant::now();
        renderer.update(snap);
        // A laparoscope the trainee moved shows the field from its place.
        let eyes = match snap.scope {
            Some(s) => field_eyes(
                &Viewpoint {
                    eye: s.eye,
                    target: s.target,
                },
                DEFAULT_IPD_M,
            ),
            None => eyes,
        };
        let mut c = renderer.render(target.target(renderer.multiview()), eye_size, &eyes);
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        // A rejected command or a lost device ends the run with that error, not a panic.
        gpu.check()?;
        frame_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        c.cpu.simulation_ms = sim_ms_per_frame;
        if let Some(dir) = save {
            let [l, r] = target.read(gpu)?;
            write_png(&dir.join(format!("left_{k:04}.png")), eye_size, &l)?;
            write_png(&dir.join(format!("right_{k:04}.png")), eye_size, &r)?;
        }
        counters.push(c);
    }
    Ok(FramesOut {
        counters,
        frame_ms,
        device: gpu.describe(),
    })
}

/// Renders one snapshot `times` times (no readback): for timing and counters.
pub fn render_repeated(
    gpu: &Gpu,
    view: &Viewpoint,
    snap: &Snapshot,
    times: usize,
    eye_size: (u32, u32),
    sim_ms_per_frame: f64,
) -> Result<FramesOut, RenderError> {
    render_snapshots(
        gpu,
        view,
        std::slice::from_ref(snap),
        times,
        eye_size,
        sim_ms_per_frame,
        None,
    )
}

/// Writes `profiler.csv`: a header and one row per frame.
pub fn write_profiler_csv(path: &Path, counters: &[FrameCounters]) -> Result<(), RenderError> {
    let err = |e: std::io::Error| RenderError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    let mut text = String::from(FrameCounters::CSV_HEADER);
    text.push('\n');
    for c in counters {
        text += &c.csv_row();
        text.push('\n');
    }
    let tmp = path.with_extension("csv.partial");
    let mut f = std::fs::File::create(&tmp).map_err(err)?;
    f.write_all(text.as_bytes()).map_err(err)?;
    std::fs::rename(&tmp, path).map_err(err)
}
