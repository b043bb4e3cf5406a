//! The nephrectomy's anatomy: a kidney with an exophytic, lobulated tumour (one mesh, two
//! regions) and the renal artery, renal vein and ureter as tubes from the hilum.

use super::{REGION_PARENCHYMA, REGION_TUMOUR, Scenario};
use crate::mesh::{KidneyShape, TriMesh, TubeSpec, icosphere, kidney, tube};
use glam::Vec3;

/// A renal mass is not a sphere: its radius in direction `d` (a unit vector) is the mean radius
/// times one plus this, a few smooth lobes of up to about 8 % (1.6 mm on the scenario's 2 cm
/// mass, well inside the 5 mm margin the trainee cuts along).
pub fn lobes(d: Vec3) -> f32 {
    0.035 * (3.1 * d.x + 1.7 * d.y + 0.4).sin()
        + 0.025 * (4.3 * d.y - 2.2 * d.z + 1.1).sin()
        + 0.02 * (5.7 * d.z + 3.1 * d.x + 2.3).sin()
}

/// Builds the anatomy meshes: kidney + tumour as one mesh with regions, and the three tubes.
pub fn anatomy(s: &Scenario) -> (TriMesh, Vec<u8>, Vec<(String, TriMesh)>, Vec3) {
    let a = &s.anatomy;
    let shape = KidneyShape {
        half_length_m: a.kidney_half_length_m,
        half_width_m: a.kidney_half_width_m,
        half_thickness_m: a.kidney_half_thickness_m,
        hilum_depth_m: a.hilum_depth_m,
    };
    let mut organ = kidney(&shape, a.level);
    let dir = Vec3::from(a.tumour_direction).normalize();
    let site = shape.surface(dir);
    let normal = Vec3::new(
        site.x / shape.half_width_m.powi(2),
        site.y / shape.half_length_m.powi(2),
        site.z / shape.half_thickness_m.powi(2),
    )
    .normalize();
    let center = site + normal * (a.tumour_protrusion * a.tumour_radius_m);
    let mut tumour = icosphere(a.level);
    for p in &mut tumour.positions {
        *p = center + *p * (a.tumour_radius_m * (1.0 + lobes(*p)));
    }
    let mut regions = vec![REGION_PARENCHYMA; organ.triangle_count()];
    regions.extend(std::iter::repeat_n(REGION_TUMOUR, tumour.triangle_count()));
    organ.append(&tumour);
    let hilum = Vec3::new(-shape.half_width_m + shape.hilum_depth_m * 0.8, 0.0, 0.0);
    let seg = a.vessel_segments;
    let rings = a.vessel_rings;
    let vessel = |path: Vec<Vec3>, r: f32| {
        tube(&TubeSpec {
            path,
            radius_m: r,
            segments: seg,
            rings,
        })
    };
    let vessels = vec![
        (
            "renal_artery".to_string(),
            vessel(
                vec![
                    hilum + Vec3::new(0.004, 0.006, -0.004),
                    hilum + Vec3::new(-0.03, 0.01, -0.008),
                    hilum + Vec3::new(-0.07, 0.012, -0.01),
                ],
                a.renal_artery_radius_m,
            ),
        ),
        (
            "renal_vein".to_string(),
            vessel(
                vec![
                    hilum + Vec3::new(0.004, 0.0, 0.006),
                    hilum + Vec3::new(-0.03, -0.002, 0.01),
                    hilum + Vec3::new(-0.07, -0.004, 0.012),
                ],
                a.renal_vein_radius_m,
            ),
        ),
        (
            "ureter".to_string(),
            vessel(
                vec![
                    hilum + Vec3::new(0.004, -0.01, 0.0),
                    hilum + Vec3::new(-0.012, -0.035, -0.004),
                    hilum + Vec3::new(-0.02, -0.1, -0.008),
                ],
                a.ureter_radius_m,
            ),
        ),
    ];
    (organ, regions, vessels, center)
}
