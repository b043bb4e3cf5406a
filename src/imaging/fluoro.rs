//! The fluoroscope around the X-ray projector (`xray`): the C-arm's pose about the patient
//! (LAO/RAO and cranial/caudal angulation, the table's pan, the field size a zoom selects),
//! the pulses while the pedal is down, the dose they give (the reference air kerma and the
//! dose-area product an interventional system displays), the collimators, the quantum noise
//! the dose sets, the roadmap (the last contrast run's vessels over the live image) and the
//! grey picture the monitor shows, dense dark.
//!
//! Units: metres, seconds; kerma in microgray (uGy) per pulse at the interventional reference
//! point (15 cm from the isocentre towards the source, IEC 60601-2-43), the dose-area product
//! in Gy cm^2 as the consoles show it. The dose-area product is the same at every distance
//! from the source (the kerma falls with the square of the distance as the field's area
//! grows with it), so it is taken at the reference point.

use super::xray::{CArm, Frame, Scene, expose_within};
use glam::DVec3;
use serde::Serialize;

/// The interventional reference point's distance from the isocentre towards the source, m.
pub const REFERENCE_POINT_M: f64 = 0.15;
/// The grey of the collimators' shadow on the monitor.
const BLADES_GREY: u8 = 24;
/// Contrast over the mask below this line integral (a tenth less transmission) is taken as
/// noise and left out of the roadmap.
pub const ROADMAP_MIN: f64 = 0.1;

/// The patient on the table, in the field's frame: unit vectors towards the head and
/// anterior (up from a supine patient's back); the patient's left is `head x anterior`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patient {
    pub head: DVec3,
    pub anterior: DVec3,
}

impl Patient {
    pub fn left(&self) -> DVec3 {
        self.head.cross(self.anterior)
    }
}

/// Where the C-arm stands: its angulation and the table's pan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Pose {
    /// Left anterior oblique, degrees (negative: right anterior oblique): the detector
    /// turned about the patient's long axis towards the patient's left.
    pub lao_deg: f64,
    /// Cranial, degrees (negative: caudal): the detector tilted towards the head.
    pub cranial_deg: f64,
    /// The table moved under the isocentre, m: towards the head, towards the patient's left
    /// (the arm then looks at the patient that much further the other way).
    pub pan_m: [f64; 2],
    /// Which of the field sizes is selected (0: the largest).
    pub zoom: usize,
}

/// How far the arm turns and the table pans.
pub const MAX_LAO_DEG: f64 = 90.0;
pub const MAX_CRANIAL_DEG: f64 = 45.0;
pub const MAX_PAN_M: f64 = 0.3;

/// The fluoroscope's fixed settings (the scenario's).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    pub patient: Patient,
    /// The point the arm turns about with the table at rest, m.
    pub isocentre: DVec3,
    pub source_to_isocentre_m: f64,
    pub source_to_detector_m: f64,
    /// The detector field's side at each zoom, largest first, m.
    pub fields_m: Vec<f64>,
    /// Pixels along the picture's side.
    pub pixels: usize,
    pub pulse_hz: f64,
    /// Air kerma a pulse gives at the reference point, uGy.
    pub kerma_ugy_per_pulse: f64,
    /// Photons reaching the detector per mm^2 per uGy of air kerma there (sets the noise).
    pub photons_per_mm2_per_ugy: f64,
    /// The collimated field's share of the picture's width and height, (0, 1].
    pub collimation: [f64; 2],
}

/// What the fluoroscope gave the patient, as a console counts it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Dose {
    /// Time with the pedal down, s.
    pub fluoro_time_s: f64,
    /// Times the pedal went down.
    pub runs: u32,
    pub pulses: u32,
    /// Air kerma at the reference point, mGy.
    pub reference_kerma_mgy: f64,
    /// Dose-area product, Gy cm^2.
    pub dap_gy_cm2: f64,
}

/// A grey picture for the monitor, rows from the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    pub width: usize,
    pub height: usize,
    pub grey: Vec<u8>,
}

/// A pulse to expose: everything the projection needs but the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shot {
    pub arm: CArm,
    pub photons_per_pixel: f64,
    pub seed: u64,
    pub open: [usize; 4],
}

impl Shot {
    /// The frame of `scene` (the same bytes wherever and on however many threads it runs).
    pub fn develop(&self, scene: &Scene) -> Frame {
        expose_within(
            scene,
            &self.arm,
            self.photons_per_pixel,
            Some(self.seed),
            self.open,
        )
    }
}

/// The fluoroscope: settings, pose, pedal and dose, the last frame and the roadmap.
#[derive(Debug, Clone)]
pub struct Fluoroscope {
    pub settings: Settings,
    pub pose: Pose,
    pub dose: Dose,
    pub roadmap_on: bool,
    pedal: bool,
    /// Time until the next pulse while the pedal is down, s.
    next_pulse_s: f64,
    last: Option<Frame>,
    /// The last frame without contrast (the mask), and each pixel's most contrast over it
    /// through the run (the roadmap: peak opacification), as line integrals; whether the
    /// next frame with contrast starts a new roadmap.
    mask: Option<Vec<f64>>,
    roadmap: Option<Vec<f64>>,
    new_roadmap: bool,
}

impl Fluoroscope {
    pub fn new(settings: Settings) -> Fluoroscope {
        Fluoroscope {
            settings,
            pose: Pose::default(),
            dose: Dose::default(),
            roadmap_on: false,
            pedal: false,
            next_pulse_s: 0.0,
            last: None,
            mask: None,
            roadmap: None,
            new_roadmap: true,
        }
    }

    /// The detector field's side at the selected zoom, m.
    pub fn field_m(&self) -> f64 {
        let f = &self.settings.fields_m;
        f.get(self.pose.zoom.min(f.len().saturating_sub(1)))
            .copied()
            .unwrap_or(0.3)
    }

    /// Turns the arm and pans the table by the given amounts, within their ranges. A move
    /// loses the roadmap and its mask: they no longer lie over the picture.
    pub fn move_by(&mut self, d_lao_deg: f64, d_cranial_deg: f64, d_pan_m: [f64; 2]) {
        let before = self.pose;
        let p = &mut self.pose;
        p.lao_deg = (p.lao_deg + d_lao_deg).clamp(-MAX_LAO_DEG, MAX_LAO_DEG);
        p.cranial_deg = (p.cranial_deg + d_cranial_deg).clamp(-MAX_CRANIAL_DEG, MAX_CRANIAL_DEG);
        for (at, d) in p.pan_m.iter_mut().zip(d_pan_m) {
            *at = (*at + d).clamp(-MAX_PAN_M, MAX_PAN_M);
        }
        if self.pose != before {
            self.lose_registration();
        }
    }

    /// The next field size (after the smallest, the largest again); the roadmap is lost.
    pub fn next_zoom(&mut self) {
        self.pose.zoom = (self.pose.zoom + 1) % self.settings.fields_m.len().max(1);
        self.lose_registration();
    }

    fn lose_registration(&mut self) {
        self.mask = None;
        self.roadmap = None;
        self.new_roadmap = true;
    }

    /// The beam's direction (source to detector) at the pose.
    pub fn beam(&self) -> DVec3 {
        let pt = &self.settings.patient;
        let (lao, cran) = (
            self.pose.lao_deg.to_radians(),
            self.pose.cranial_deg.to_radians(),
        );
        let sideways = pt.anterior * lao.cos() + pt.left() * lao.sin();
        (sideways * cran.cos() + pt.head * cran.sin()).normalize_or(pt.anterior)
    }

    /// The projector's C-arm at the pose: the source behind the isocentre (moved by the
    /// table's pan), the picture's up towards the head, its right towards the patient's left
    /// in a frontal view.
    pub fn arm(&self) -> CArm {
        let s = &self.settings;
        let f = self.beam();
        let pt = &s.patient;
        let iso = s.isocentre - pt.head * self.pose.pan_m[0] - pt.left() * self.pose.pan_m[1];
        let up = (pt.head - f * pt.head.dot(f)).normalize_or(pt.anterior.cross(f));
        let pixels = s.pixels.max(1);
        CArm {
            source: iso - f * s.source_to_isocentre_m,
            forward: f,
            right: up.cross(f),
            distance_m: s.source_to_detector_m,
            width: pixels,
            height: pixels,
            pixel_m: self.field_m() / pixels as f64,
        }
    }

    /// The collimated field in pixels (see `Frame::open`): centred, each side its share.
    pub fn open(&self) -> [usize; 4] {
        let n = self.settings.pixels.max(1);
        let side = |share: f64| {
            let w = ((share.clamp(0.0, 1.0) * n as f64).round() as usize).clamp(1, n);
            ((n - w) / 2, (n - w) / 2 + w)
        };
        let ((i0, i1), (j0, j1)) = (
            side(self.settings.collimation[0]),
            side(self.settings.collimation[1]),
        );
        [i0, i1, j0, j1]
    }

    /// The reference point's distance from the source, m.
    fn reference_distance_m(&self) -> f64 {
        (self.settings.source_to_isocentre_m - REFERENCE_POINT_M).max(1e-3)
    }

    /// The collimated field's area at the reference point, cm^2.
    pub fn reference_area_cm2(&self) -> f64 {
        let o = self.open();
        let pixel = self.field_m() / self.settings.pixels.max(1) as f64;
        let at_detector = (o[1] - o[0]) as f64 * pixel * (o[3] - o[2]) as f64 * pixel;
        let scale = self.reference_distance_m() / self.settings.source_to_detector_m;
        at_detector * scale * scale * 1e4
    }

    /// Photons a detector pixel receives from a pulse with nothing in the beam: the kerma
    /// at the detector (the reference point's over the squared distances) times the fluence
    /// per kerma times the pixel's area.
    pub fn photons_per_pixel(&self) -> f64 {
        let s = &self.settings;
        let scale = self.reference_distance_m() / s.source_to_detector_m;
        let kerma = s.kerma_ugy_per_pulse * scale * scale;
        let pixel_mm = 1e3 * self.field_m() / s.pixels.max(1) as f64;
        kerma * s.photons_per_mm2_per_ugy * pixel_mm * pixel_mm
    }

    /// Whether the pedal is down.
    pub fn pedal(&self) -> bool {
        self.pedal
    }

    /// `dt_s` with the pedal as `down`: a press starts a run and a pulse at once, then a
    /// pulse every `1 / pulse_hz` while it stays down. Returns whether a pulse fires in this
    /// step (expose a frame with [`Fluoroscope::expose`]); its dose is counted here.
    pub fn step(&mut self, dt_s: f64, down: bool) -> bool {
        let pressed = down && !self.pedal;
        self.pedal = down;
        if !down {
            return false;
        }
        if pressed {
            self.dose.runs += 1;
            self.next_pulse_s = 0.0;
        }
        self.dose.fluoro_time_s += dt_s;
        let fire = self.next_pulse_s <= 1e-12;
        if fire {
            self.next_pulse_s += 1.0 / self.settings.pulse_hz.max(1e-3);
            let kerma_gy = self.settings.kerma_ugy_per_pulse * 1e-6;
            self.dose.pulses += 1;
            self.dose.reference_kerma_mgy += kerma_gy * 1e3;
            self.dose.dap_gy_cm2 += kerma_gy * self.reference_area_cm2();
        }
        self.next_pulse_s -= dt_s;
        fire
    }

    /// A pulse's frame of `scene` (noise from `seed`), kept as the last; `contrast` says
    /// whether contrast is in the vessels now: a frame without it is the roadmap's mask, a
    /// frame with it raises each pixel of the roadmap to its contrast over the mask (so a
    /// bolus moving through the vessels paints them all), the first such frame after a mask
    /// starting a new roadmap.
    pub fn expose(&mut self, scene: &Scene, contrast: bool, seed: u64) -> &Frame {
        let frame = self.shot(seed).develop(scene);
        self.receive(frame, contrast)
    }

    /// What a pulse now needs to be exposed elsewhere (another thread): the arm, the dose
    /// and the collimation as they are, and the noise's seed.
    pub fn shot(&self, seed: u64) -> Shot {
        Shot {
            arm: self.arm(),
            photons_per_pixel: self.photons_per_pixel(),
            seed,
            open: self.open(),
        }
    }

    /// A pulse's frame exposed from [`Fluoroscope::shot`], taken in as [`Fluoroscope::expose`]
    /// takes its own: the last frame, the mask or the roadmap.
    pub fn receive(&mut self, frame: Frame, contrast: bool) -> &Frame {
        if contrast {
            if let Some(mask) = &self.mask {
                let over: Vec<f64> = frame
                    .line_integrals
                    .iter()
                    .zip(mask)
                    .map(|(l, m)| if l - m > ROADMAP_MIN { l - m } else { 0.0 })
                    .collect();
                match &mut self.roadmap {
                    Some(road) if !self.new_roadmap => {
                        road.iter_mut().zip(&over).for_each(|(r, o)| *r = r.max(*o));
                    }
                    _ => self.roadmap = Some(over),
                }
                self.new_roadmap = false;
            }
        } else {
            self.mask = Some(frame.line_integrals.clone());
            // The next contrast starts a new roadmap; the old one shows until then.
            self.new_roadmap = true;
        }
        self.last.insert(frame)
    }

    /// The last frame, if the pedal was ever pressed.
    pub fn last(&self) -> Option<&Frame> {
        self.last.as_ref()
    }

    /// Whether a roadmap has been taken.
    pub fn has_roadmap(&self) -> bool {
        self.roadmap.is_some()
    }

    /// What the monitor shows (the last image held when the pedal is up): the line
    /// integrals windowed between the exposed field's 1st and 99th percentiles, dense dark,
    /// with the roadmap's contrast added where it is on (the window stays the live image's);
    /// the collimators' shadow dark grey.
    pub fn picture(&self) -> Option<Picture> {
        let f = self.last.as_ref()?;
        let road = self.roadmap.as_ref().filter(|_| self.roadmap_on);
        let value = |k: usize| f.line_integrals[k] + road.map_or(0.0, |r| r[k]);
        let mut seen: Vec<f64> = (0..f.width * f.height)
            .filter(|k| f.exposed(k % f.width, k / f.width))
            .map(|k| f.line_integrals[k])
            .collect();
        // The two percentiles by selection (linear time), each the value a full sort would
        // put at its rank.
        let mut pick = |q: f64| {
            let rank = ((seen.len() as f64 - 1.0) * q).round() as usize;
            (rank < seen.len()).then(|| *seen.select_nth_unstable_by(rank, f64::total_cmp).1)
        };
        let (lo, hi) = (pick(0.01).unwrap_or(0.0), pick(0.99).unwrap_or(1.0));
        let span = (hi - lo).max(1e-9);
        let grey = (0..f.width * f.height)
            .map(|k| {
                if !f.exposed(k % f.width, k / f.width) {
                    return BLADES_GREY;
                }
                let t = ((value(k) - lo) / span).clamp(0.0, 1.0);
                (255.0 * (1.0 - t)).round() as u8
            })
            .collect();
        Some(Picture {
            width: f.width,
            height: f.height,
            grey,
        })
    }
}

#[cfg(test)]
#[path = "fluoro_tests.rs"]
mod tests;
