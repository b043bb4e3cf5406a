//! Headless frames: render captured snapshots for both eyes, save them as PNGs and write one
//! row of profiler counters per frame.

use super::Renderer;
use super::camera::{DEFAULT_IPD_M, EyeView, field_eyes};
use super::gpu::{EYE_FORMAT, EyeTarget, Gpu, RenderError, write_png};
use super::optics::{Optics, scope_eyes};
use crate::profiler::FrameCounters;
use crate::sim::Snapshot;
use crate::sim::field::OperativeField;
use crate::sim::{ProcedureInfo, Viewpoint};
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

/// How a set of frames looks at the field.
#[derive(Debug, Clone)]
pub struct Look {
    pub view: Viewpoint,
    /// The field around the models, with its scope (`None`: the models alone).
    pub field: Option<OperativeField>,
    /// A laparoscope's monitor image (its angle of view and image circle) rather than a
    /// headset's eyes.
    pub monitor: bool,
}

impl Look {
    /// The procedure's field as its laparoscope's monitor shows it.
    pub fn monitor(info: &ProcedureInfo) -> Self {
        Look {
            view: info.view,
            field: Some((info.field)()),
            monitor: true,
        }
    }

    /// The procedure's field in a headset's eyes at its viewpoint.
    pub fn headset(info: &ProcedureInfo) -> Self {
        Look {
            monitor: false,
            ..Self::monitor(info)
        }
    }

    /// The models alone from `view`, lit by a plain headlight, in a headset's eyes.
    pub fn bare(view: Viewpoint) -> Self {
        Look {
            view,
            field: None,
            monitor: false,
        }
    }

    /// The optics: the scope light over a field (and a monitor's circle), a headlight without.
    pub fn optics(&self) -> Optics {
        match (&self.field, self.monitor) {
            (None, _) => Optics::default(),
            (Some(_), true) => Optics::monitor(&self.view),
            (Some(_), false) => Optics::headset(&self.view),
        }
    }

    /// Both eyes looking from `view` in an image of `size`.
    pub fn eyes(&self, view: &Viewpoint, size: (u32, u32)) -> [EyeView; 2] {
        match (&self.field, self.monitor) {
            (Some(f), true) => scope_eyes(view, f.scope.fov_deg, size, DEFAULT_IPD_M),
            _ => field_eyes(view, DEFAULT_IPD_M),
        }
    }

    /// A renderer for these frames: the field uploaded, the optics set.
    pub fn renderer(&self, gpu: &Gpu) -> Result<Renderer, RenderError> {
        let mut renderer = Renderer::new(gpu, EYE_FORMAT)?;
        renderer.set_field(self.field.as_ref().map(|f| f.mesh()).as_ref());
        renderer.set_optics(self.optics());
        Ok(renderer)
    }
}

/// Stereo frames drawn one at a time into one pair of eye targets: each frame is timed from
/// the snapshot's upload to the GPU's finishing it.
pub struct EyeFrames<'a> {
    gpu: &'a Gpu,
    look: &'a Look,
    renderer: Renderer,
    target: EyeTarget,
    eyes: [EyeView; 2],
    eye_size: (u32, u32),
}

impl<'a> EyeFrames<'a> {
    /// A renderer and eye targets of `eye_size` for frames seen as `look` says.
    pub fn new(gpu: &'a Gpu, look: &'a Look, eye_size: (u32, u32)) -> Result<Self, RenderError> {
        gpu.check_eye_size(eye_size)?;
        let renderer = look.renderer(gpu)?;
        let target = EyeTarget::new(gpu, eye_size);
        gpu.check()?;
        Ok(EyeFrames {
            gpu,
            look,
            renderer,
            target,
            eyes: look.eyes(&look.view, eye_size),
            eye_size,
        })
    }

    /// Draws `snap` for both eyes and waits for the GPU: the frame's counters and its wall
    /// time (upload, render, the GPU's finish), ms. A rejected command or a lost device is
    /// that error, not a panic.
    pub fn draw(&mut self, snap: &Snapshot) -> Result<(FrameCounters, f64), RenderError> {
        let t0 = Instant::now();
        self.renderer.update(snap);
        // A laparoscope the trainee moved shows the field from its place.
        let eyes = match snap.scope {
            Some(s) => self.look.eyes(
                &Viewpoint {
                    eye: s.eye,
                    target: s.target,
                },
                self.eye_size,
            ),
            None => self.eyes,
        };
        let c = self.renderer.render(
            self.target.target(self.renderer.multiview()),
            self.eye_size,
            &eyes,
        );
        self.gpu
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        self.gpu.check()?;
        Ok((c, t0.elapsed().as_secs_f64() * 1e3))
    }

    /// The last frame drawn, both eyes' pixels.
    pub fn read(&self) -> Result<[Vec<u8>; 2], RenderError> {
        self.target.read(self.gpu)
    }
}

/// Renders every snapshot, waits for the GPU, and returns the counters. `save` names the
/// folder that gets `left_NNNN.png`, `right_NNNN.png` (and nothing is read back without it).
pub fn render_snapshots(
    gpu: &Gpu,
    look: &Look,
    snaps: &[Snapshot],
    repeat: usize,
    eye_size: (u32, u32),
    sim_ms_per_frame: f64,
    save: Option<&Path>,
) -> Result<FramesOut, RenderError> {
    let mut frames = EyeFrames::new(gpu, look, eye_size)?;
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
        let (mut c, ms) = frames.draw(snap)?;
        frame_ms.push(ms);
        c.cpu.simulation_ms = sim_ms_per_frame;
        if let Some(dir) = save {
            let [l, r] = frames.read()?;
            write_png(&dir.join(format!("left_{k:04}.png")), eye_size, &l)?;
            write_png(&dir.join(format!("right_{k:04}.png")), eye_size, &r)?;
            // The procedure's own picture (a fluoroscope's), at its own size.
            if let Some(p) = &snap.picture {
                let rgba: Vec<u8> = p.grey.iter().flat_map(|&g| [g, g, g, 255]).collect();
                let size = (p.width as u32, p.height as u32);
                write_png(&dir.join(format!("fluoro_{k:04}.png")), size, &rgba)?;
            }
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
    look: &Look,
    snap: &Snapshot,
    times: usize,
    eye_size: (u32, u32),
    sim_ms_per_frame: f64,
) -> Result<FramesOut, RenderError> {
    render_snapshots(
        gpu,
        look,
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

/// Tiles the left-eye frames of `frames_dir` (`left_0000.png` on, all one size) at half size,
/// `cols` across, into one PNG at `out`; returns its size. A frame folder with none is an
/// error naming it.
pub fn contact_sheet(
    frames_dir: &Path,
    out: &Path,
    cols: usize,
) -> Result<(u32, u32), RenderError> {
    let mut frames = Vec::new();
    while let Ok((size, px)) =
        super::gpu::read_png(&frames_dir.join(format!("left_{:04}.png", frames.len())))
    {
        frames.push((size, px));
    }
    let Some(((w, h), _)) = frames.first() else {
        return Err(RenderError::Write {
            path: frames_dir.display().to_string(),
            message: "no left_0000.png to put on a contact sheet".into(),
        });
    };
    let (tw, th) = ((w / 2) as usize, (h / 2) as usize);
    let cols = cols.clamp(1, frames.len());
    let rows = frames.len().div_ceil(cols);
    let (sw, sh) = (tw * cols, th * rows);
    let mut sheet = vec![0u8; sw * sh * 4];
    for (k, ((fw, fh), px)) in frames.iter().enumerate() {
        if (fw, fh) != (w, h) {
            continue;
        }
        let (ox, oy) = ((k % cols) * tw, (k / cols) * th);
        for y in 0..th {
            for x in 0..tw {
                // The mean of the 2 x 2 pixels the thumbnail's pixel stands for.
                let at = |dx: usize, dy: usize| 4 * ((2 * y + dy) * *w as usize + 2 * x + dx);
                let o = 4 * ((oy + y) * sw + ox + x);
                for c in 0..4 {
                    let sum: u32 = [at(0, 0), at(1, 0), at(0, 1), at(1, 1)]
                        .iter()
                        .map(|&i| u32::from(px[i + c]))
                        .sum();
                    sheet[o + c] = (sum / 4) as u8;
                }
            }
        }
    }
    let size = (sw as u32, sh as u32);
    write_png(out, size, &sheet)?;
    Ok(size)
}
