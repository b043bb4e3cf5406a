use super::*;
use crate::imaging::xray::{Body, Material};

/// A supine patient along z (head +z), anterior +y (so the patient's left is -x), the
/// isocentre at the origin, the source 0.7 m from it and 1.0 m from the detector.
fn settings() -> Settings {
    Settings {
        patient: Patient {
            head: DVec3::Z,
            anterior: DVec3::Y,
        },
        isocentre: DVec3::ZERO,
        source_to_isocentre_m: 0.7,
        source_to_detector_m: 1.0,
        fields_m: vec![0.3, 0.2, 0.15],
        pixels: 64,
        pulse_hz: 7.5,
        kerma_ugy_per_pulse: 10.0,
        photons_per_mm2_per_ugy: 3.0e4,
        collimation: [1.0, 1.0],
    }
}

fn material(name: &str, mu: f64) -> Material {
    Material {
        name: name.into(),
        mu_per_m: mu,
    }
}

/// Bone-like spheres of 1 cm at `centres`.
fn spheres(centres: &[DVec3]) -> Scene {
    Scene {
        materials: vec![material("bone", 50.0)],
        bodies: centres
            .iter()
            .map(|&c| {
                (
                    Body::Sphere {
                        centre: c,
                        radius: 0.01,
                    },
                    0,
                )
            })
            .collect(),
    }
}

/// The darkest pixel's place in the last frame (the densest ray).
fn darkest(f: &Fluoroscope) -> (usize, usize) {
    let frame = f.last().expect("a frame");
    let k = (0..frame.line_integrals.len())
        .max_by(|&a, &b| frame.line_integrals[a].total_cmp(&frame.line_integrals[b]))
        .unwrap_or(0);
    (k % frame.width, k / frame.width)
}

#[test]
fn a_frontal_view_shows_the_patients_right_on_the_left_and_the_head_at_the_top() {
    let mut f = Fluoroscope::new(settings());
    // The beam goes from the back to the front.
    assert!((f.beam() - DVec3::Y).length() < 1e-12);
    assert!(f.arm().source.y < 0.0);
    // On the patient's right (+x) and towards the head (+z).
    let scene = spheres(&[DVec3::new(0.05, 0.0, 0.05)]);
    assert!(f.step(0.001, true));
    f.expose(&scene, false, 1);
    let (i, j) = darkest(&f);
    assert!(i < 32 && j < 32, "right and head at the top left: {i}, {j}");
    // LAO 90: the beam goes from the patient's right to the left, and the picture's right
    // is the back: a sphere in front of the isocentre shows on the left.
    f.move_by(90.0, 0.0, [0.0, 0.0]);
    assert!((f.beam() - f.settings.patient.left()).length() < 1e-12);
    let scene = spheres(&[DVec3::new(0.0, 0.05, 0.0)]);
    f.expose(&scene, false, 2);
    let (i, _) = darkest(&f);
    assert!(i < 32, "anterior on the left in LAO 90: {i}");
    // Cranial 30: the beam leans towards the head.
    f.move_by(-90.0, 30.0, [0.0, 0.0]);
    let b = f.beam();
    assert!((b.dot(DVec3::Z) - 0.5).abs() < 1e-12, "{b}");
    // Angles stop at their limits.
    f.move_by(400.0, 400.0, [1.0, -1.0]);
    assert_eq!(
        (f.pose.lao_deg, f.pose.cranial_deg, f.pose.pan_m),
        (MAX_LAO_DEG, MAX_CRANIAL_DEG, [MAX_PAN_M, -MAX_PAN_M])
    );
}

#[test]
fn panning_the_table_moves_the_picture_and_zoom_magnifies_it() {
    let scene = spheres(&[DVec3::new(0.0, 0.0, 0.0)]);
    let mut f = Fluoroscope::new(settings());
    f.step(0.001, true);
    f.expose(&scene, false, 1);
    // The sphere's centre falls between pixels 31 and 32: the noise picks either.
    let centre = darkest(&f);
    // The table 5 cm towards the head: the patient, and the sphere, move up the picture by
    // 5 cm x 1.0 / 0.7 magnification over 0.3 / 64 m pixels = 15.2 pixels.
    f.move_by(0.0, 0.0, [0.05, 0.0]);
    f.expose(&scene, false, 2);
    let moved = darkest(&f);
    assert!(moved.0.abs_diff(centre.0) <= 1);
    let rows = centre.1 as f64 - moved.1 as f64;
    assert!((rows - 15.2).abs() <= 1.0, "{rows}");
    // Zoom to the 15 cm field: twice the magnification.
    f.next_zoom();
    f.next_zoom();
    assert_eq!(f.field_m(), 0.15);
    f.expose(&scene, false, 3);
    let zoomed = darkest(&f);
    let rows = centre.1 as f64 - zoomed.1 as f64;
    assert!((rows - 30.5).abs() <= 1.5, "{rows}");
    f.next_zoom();
    assert_eq!(f.field_m(), 0.3);
}

#[test]
fn pulses_come_at_the_pulse_rate_while_the_pedal_is_down_whatever_the_step() {
    for dt in [0.001f64, 0.002] {
        let mut f = Fluoroscope::new(settings());
        let steps = (2.0 / dt).round() as usize;
        let pulses = (0..steps).filter(|_| f.step(dt, true)).count();
        // 7.5 a second for 2 s, the first at the press.
        assert_eq!(pulses, 15, "dt {dt}");
        for _ in 0..100 {
            assert!(!f.step(dt, false));
        }
        assert!(f.step(dt, true), "a press fires at once");
        assert_eq!(f.dose.runs, 2);
        assert!((f.dose.fluoro_time_s - (2.0 + dt)).abs() < 1e-9);
        assert_eq!(f.dose.pulses, 16);
    }
}

#[test]
fn the_dose_area_product_is_the_kerma_times_the_collimated_field_at_the_reference_point() {
    let mut f = Fluoroscope::new(settings());
    // The reference point 0.7 - 0.15 = 0.55 m from the source: the 0.3 m field there is
    // 0.3 x 0.55 / 1.0 = 0.165 m across, 272.25 cm^2; a pulse of 10 uGy gives
    // 1e-5 Gy x 272.25 cm^2.
    assert!((f.reference_area_cm2() - 272.25).abs() < 1e-9);
    for _ in 0..1000 {
        f.step(0.001, true);
    }
    // Pulses at 0, 0.133, ..., 0.933 s: 8 in the first second.
    assert_eq!(f.dose.pulses, 8);
    assert!((f.dose.dap_gy_cm2 - 8.0 * 1e-5 * 272.25).abs() < 1e-12);
    assert!((f.dose.reference_kerma_mgy - 0.08).abs() < 1e-12);
    // Collimated to half the width and half the height: a quarter of the area.
    let mut c = settings();
    c.collimation = [0.5, 0.5];
    let f = Fluoroscope::new(c);
    assert_eq!(f.open(), [16, 48, 16, 48]);
    assert!((f.reference_area_cm2() - 272.25 / 4.0).abs() < 1e-9);
    // Photons a pixel gets: 10 uGy x (0.55 / 1.0)^2 at the detector, 3e4 a mm^2 a uGy,
    // (300 / 64 mm)^2 a pixel.
    let want = 10.0 * 0.55f64.powi(2) * 3.0e4 * (300.0f64 / 64.0).powi(2);
    assert!((f.photons_per_pixel() - want).abs() < 1e-6 * want);
}

#[test]
fn collimated_blades_leave_the_field_outside_unexposed_and_dark_grey() {
    let mut s = settings();
    s.collimation = [0.5, 1.0];
    let mut f = Fluoroscope::new(s);
    let scene = spheres(&[DVec3::ZERO]);
    f.step(0.001, true);
    let frame = f.expose(&scene, false, 5).clone();
    for j in 0..64 {
        for i in 0..64 {
            let k = j * 64 + i;
            if (16..48).contains(&i) {
                assert!(frame.counts[k] > 0.0);
            } else {
                assert_eq!(frame.counts[k], 0.0);
            }
        }
    }
    let p = f.picture().expect("a picture");
    assert_eq!(p.grey[0], BLADES_GREY);
    // Dense is dark: the sphere's pixel darker than the open field's mean.
    let (i, j) = darkest(&f);
    let open: Vec<f64> = (0..64 * 64)
        .filter(|k| (20..44).contains(&(k % 64)) && k / 64 < 8)
        .map(|k| f64::from(p.grey[k]))
        .collect();
    let mean = open.iter().sum::<f64>() / open.len() as f64;
    assert!(f64::from(p.grey[j * 64 + i]) < mean - 100.0, "{mean}");
}

#[test]
fn the_roadmap_lays_the_last_runs_contrast_over_the_live_picture() {
    // A slab of 20 cm of soft tissue across the beam, a vessel along z that contrast fills
    // (iodine-like, 300 /m).
    let body = (
        Body::Cylinder {
            a: DVec3::new(0.0, -0.1, 0.0),
            b: DVec3::new(0.0, 0.1, 0.0),
            radius: 1.0,
        },
        0,
    );
    let vessel = (
        Body::Capsule {
            a: DVec3::new(0.03, 0.0, -0.2),
            b: DVec3::new(0.03, 0.0, 0.2),
            radius: 0.004,
        },
        1,
    );
    let clear = Scene {
        materials: vec![material("tissue", 20.0), material("contrast", 300.0)],
        bodies: vec![body],
    };
    let filled = Scene {
        bodies: vec![body, vessel],
        ..clear.clone()
    };
    let mut f = Fluoroscope::new(settings());
    f.step(0.001, true);
    f.expose(&clear, false, 1);
    assert!(!f.has_roadmap());
    f.expose(&filled, true, 2);
    assert!(f.has_roadmap());
    // Contrast gone; the live picture alone shows no vessel, the roadmap shows it.
    f.expose(&clear, false, 3);
    let live = f.picture().expect("live");
    f.roadmap_on = true;
    let road = f.picture().expect("roadmap");
    // The vessel at x = +3 cm (the patient's right: the left of the picture), magnified
    // 1 / 0.7: 4.3 cm left of the centre, 9 pixels of 4.7 mm.
    let column = 32 - 9 - 1;
    let mean =
        |p: &Picture, i: usize| (10..54).map(|j| f64::from(p.grey[j * 64 + i])).sum::<f64>() / 44.0;
    assert!(
        mean(&road, column) < mean(&live, column) - 40.0,
        "roadmap {} live {}",
        mean(&road, column),
        mean(&live, column)
    );
    // Away from the vessel both show the same tissue: the window is the live image's, and
    // the noise between the contrast frame and its mask stays out of the roadmap.
    assert_eq!(mean(&road, 50), mean(&live, 50));
    // Turning the arm loses the roadmap (it no longer lies over the picture); a move that
    // the arm's range stops does not.
    f.move_by(0.0, -100.0, [0.0; 2]);
    assert!(!f.has_roadmap());
    f.expose(&clear, false, 4);
    f.expose(&filled, true, 5);
    assert!(f.has_roadmap());
    f.move_by(0.0, -1.0, [0.0; 2]);
    assert!(f.has_roadmap(), "at the caudal limit already");
    f.next_zoom();
    assert!(!f.has_roadmap());
}

#[test]
fn a_frame_does_not_depend_on_the_threads() {
    let scene = spheres(&[DVec3::ZERO, DVec3::new(0.02, 0.0, 0.0)]);
    let frame = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a pool");
        pool.install(|| {
            let mut f = Fluoroscope::new(settings());
            f.step(0.001, true);
            f.expose(&scene, false, 9).clone()
        })
    };
    assert_eq!(frame(1), frame(2));
}
