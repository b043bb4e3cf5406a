use super::anatomy::*;
use crate::mesh::{TubeSpec, tube};
use crate::models::membrane::{LAYERS, Membrane};
use glam::Vec3;

/// A coarse anatomy for quick tests: the default shape on a 60 x 48 grid.
fn coarse() -> AnatomyParams {
    AnatomyParams {
        rows: 60,
        cols: 48,
        ..AnatomyParams::default()
    }
}

/// Distance of `q` from the axis line through frame `f` (in its plane).
fn off_axis(f: &AxisFrame, q: Vec3) -> f32 {
    let r = q - f.point;
    (r - f.tangent * r.dot(f.tangent)).length()
}

#[test]
fn a_straight_cylinder_cuts_into_even_circles_starting_at_the_normal() {
    let (r, seg) = (0.02f32, 96u32);
    let path = vec![Vec3::ZERO, Vec3::new(0.1, 0.0, 0.0)];
    let mesh = tube(&TubeSpec {
        path: path.clone(),
        radius_m: r,
        segments: seg,
        rings: 11,
    });
    let axis = frames(&[Vec3::new(0.01, 0.0, 0.0), Vec3::new(0.09, 0.0, 0.0)], 9).expect("axis");
    let cols = 100;
    let rings = cross_sections(&mesh, &axis, cols, 0.05, "test").expect("outlines");
    // The mesh is a 96-gon: its points lie between the inscribed and circumscribed radii.
    let inner = r * (std::f32::consts::PI / seg as f32).cos();
    let side = 2.0 * r * (std::f32::consts::PI / seg as f32).sin();
    for (f, ring) in axis.iter().zip(&rings) {
        assert_eq!(ring.len(), cols);
        for q in ring {
            let d = off_axis(f, *q);
            assert!(d >= inner - 1e-6 && d <= r + 1e-6, "{d}");
            assert!((q - f.point).dot(f.tangent).abs() < 1e-6);
        }
        // Column 0 on the frame's normal (+y here).
        let c0 = (ring[0] - f.point).normalize();
        assert!(c0.dot(f.normal) > 0.9999, "{c0}");
        // Even by length: every gap is the perimeter over the count (the 96-gon's perimeter).
        let want = seg as f32 * side / cols as f32;
        for k in 0..cols {
            let gap = ring[k].distance(ring[(k + 1) % cols]);
            // A gap that straddles a corner of the polygon is a chord, slightly shorter.
            assert!(
                gap <= want * 1.0001 && gap > want * 0.998,
                "{gap} vs {want}"
            );
        }
    }
}

#[test]
fn the_full_size_membrane_has_the_papers_grid_and_ordered_layers() {
    let a = Anatomy::generate(AnatomyParams::default()).expect("anatomy");
    let p = a.params;
    let m = &a.membrane;
    assert_eq!((m.rows, m.cols), (600, 400));
    assert_eq!(LAYERS * m.rows * m.cols, 960_000);
    // Rows a quarter of a millimetre apart along the axis (15 cm over 600 rows).
    let spacing = a.axis[1].point.distance(a.axis[0].point);
    assert!((spacing - p.length_m / 600.0).abs() < 1e-6, "{spacing}");
    let (mut gap_min, mut gap_max) = (f32::MAX, 0.0f32);
    for (i, f) in a.axis.iter().enumerate() {
        for j in 0..m.cols {
            let k = i * m.cols + j;
            let d: [f32; LAYERS] = std::array::from_fn(|l| off_axis(f, m.positions[l][k]));
            assert!(
                d[0] < d[1] && d[1] < d[2] && d[2] < d[3],
                "row {i} col {j}: {d:?}"
            );
            // Links 1-2 and 3-4 at their fixed depths.
            let l12 = m.positions[0][k].distance(m.positions[1][k]);
            let l34 = m.positions[2][k].distance(m.positions[3][k]);
            assert!((l12 - p.fat_depth_m).abs() < 1e-5, "{l12}");
            assert!((l34 - p.wall_depth_m).abs() < 1e-5, "{l34}");
            let g = a.plane_gap(i, j);
            gap_min = gap_min.min(g);
            gap_max = gap_max.max(g);
        }
    }
    // The dissection plane: short (under 2 mm) and variable (thicker behind, the pelvis
    // tube's axis being 0.8 mm back): 34 - 20 - 10 - 2.5 = 1.5 mm -+ 0.8 mm.
    assert!(gap_min > 0.5e-3 && gap_min < 0.8e-3, "{gap_min}");
    assert!(gap_max > 2.2e-3 && gap_max < 2.4e-3, "{gap_max}");
    // The membrane builds from it (no two neighbours coincide), with the scene's tissues.
    let params = crate::procedures::rectum::scene::membrane_params();
    let membrane = Membrane::new(a.membrane.clone(), params);
    assert!(membrane.is_ok(), "{:?}", membrane.err());
}

#[test]
fn layer_four_lines_up_with_layer_one() {
    let a = Anatomy::generate(coarse()).expect("anatomy");
    let m = &a.membrane;
    for (i, f) in a.axis.iter().enumerate() {
        for j in 0..m.cols {
            let k = i * m.cols + j;
            let dir = |q: Vec3| {
                let r = q - f.point;
                (r - f.tangent * r.dot(f.tangent)).normalize()
            };
            // Same direction from the axis within 1.5 degrees (the offset pelvis tube and
            // the even spacing by length on each move columns a little).
            let c = dir(m.positions[0][k]).dot(dir(m.positions[3][k]));
            assert!(c > (1.5f32).to_radians().cos(), "row {i} col {j}: cos {c}");
        }
    }
}

#[test]
fn depths_that_do_not_fit_and_a_mesh_that_ends_short_are_refused() {
    let too_deep = AnatomyParams {
        fat_depth_m: 0.012,
        ..coarse()
    };
    match Anatomy::generate(too_deep) {
        Err(AnatomyError::LayersCross { gap_mm, .. }) => assert!(gap_mm < 14.5, "{gap_mm}"),
        other => panic!("{other:?}"),
    }
    // A rectum mesh that covers only the first half of the axis.
    let p = coarse();
    let axis = medial_axis(&p, 64);
    let half = tube(&TubeSpec {
        path: axis[..32].to_vec(),
        radius_m: p.rectum_radius_m,
        segments: 32,
        rings: 20,
    });
    let pelvis = tube(&TubeSpec {
        path: axis.clone(),
        radius_m: p.pelvis_radius_m,
        segments: 32,
        rings: 40,
    });
    match Anatomy::from_meshes(p, &axis, half, pelvis) {
        Err(AnatomyError::NoOutline { surface, row }) => {
            assert_eq!(surface, "rectum");
            assert!(row > 25 && row < 35, "{row}");
        }
        other => panic!("{other:?}"),
    }
}
