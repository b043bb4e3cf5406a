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

/// A kidney is no symmetric bean: how far its surface at `p` (on the bean of `shape`, metres)
/// lies outside the bean, metres. The lower pole is fuller and the upper slimmer, by up to 6 %
/// of the half-width (1.8 mm on the scenario's kidney), and the surface undulates by up to
/// 1.2 mm in broad swells (the fetal lobulation many adult kidneys keep).
pub fn kidney_relief(p: Vec3, shape: &KidneyShape) -> f32 {
    let along = (p.y / shape.half_length_m).clamp(-1.0, 1.0);
    let pole = -0.06 * shape.half_width_m * along;
    let d = p.normalize_or_zero();
    let swells = 0.0012 * (7.0 * d.y + 1.3).sin() * (3.0 * d.x + 5.0 * d.z + 0.7).cos();
    pole + swells
}

/// What [`anatomy`] builds: kidney and tumour (one mesh), each triangle's region, the three
/// tubes by name, and the tumour's centre.
pub type Built = (TriMesh, Vec<u8>, Vec<(String, TriMesh)>, Vec3);

/// Builds the anatomy meshes: kidney + tumour as one mesh with regions, and the three tubes.
pub fn anatomy(s: &Scenario) -> Built {
    build(s, true)
}

/// The same on the scenario's plain bean, without [`kidney_relief`]: a surface whose
/// curvature is known, for the reference cases that compare a press with Hertz's law.
pub fn bean_anatomy(s: &Scenario) -> Built {
    build(s, false)
}

fn build(s: &Scenario, relief: bool) -> Built {
    let a = &s.anatomy;
    let shape = KidneyShape {
        half_length_m: a.kidney_half_length_m,
        half_width_m: a.kidney_half_width_m,
        half_thickness_m: a.kidney_half_thickness_m,
        hilum_depth_m: a.hilum_depth_m,
    };
    let mut organ = kidney(&shape, a.level);
    if relief {
        let indices: Vec<u32> = organ.triangles.iter().flatten().copied().collect();
        let normals = crate::mesh::vertex_normals(&organ.positions, &indices);
        for (p, n) in organ.positions.iter_mut().zip(normals) {
            *p += n * kidney_relief(*p, &shape);
        }
    }
    let dir = Vec3::from(a.tumour_direction).normalize();
    let site = shape.surface(dir);
    let normal = Vec3::new(
        site.x / shape.half_width_m.powi(2),
        site.y / shape.half_length_m.powi(2),
        site.z / shape.half_thickness_m.powi(2),
    )
    .normalize();
    // The tumour sits as far out of the surface as the scenario says, where the relief put
    // the surface.
    let site = if relief {
        site + normal * kidney_relief(site, &shape)
    } else {
        site
    };
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kidney_is_fuller_below_than_above_and_gently_swollen() {
        let text = super::super::INFO
            .scenario
            .replace("level = 5", "level = 3");
        let s = Scenario::parse("coarse", &text).expect("scenario");
        let a = &s.anatomy;
        let (organ, regions, _, _) = anatomy(&s);
        let shape = KidneyShape {
            half_length_m: a.kidney_half_length_m,
            half_width_m: a.kidney_half_width_m,
            half_thickness_m: a.kidney_half_thickness_m,
            hilum_depth_m: a.hilum_depth_m,
        };
        // The parenchyma's vertices: those of its triangles.
        let mut kidney = vec![false; organ.positions.len()];
        for (t, r) in organ.triangles.iter().zip(&regions) {
            if *r == REGION_PARENCHYMA {
                for &v in t {
                    kidney[v as usize] = true;
                }
            }
        }
        let points: Vec<Vec3> = organ
            .positions
            .iter()
            .zip(&kidney)
            .filter(|(_, k)| **k)
            .map(|(p, _)| *p)
            .collect();
        // Across the lateral border (+x) at each pole, a fifth of the length from its tip.
        let lateral = |lower: bool| {
            points
                .iter()
                .filter(|p| {
                    let u = p.y / a.kidney_half_length_m;
                    if lower { u < -0.6 } else { u > 0.6 }
                })
                .map(|p| p.x)
                .fold(f32::MIN, f32::max)
        };
        let (below, above) = (lateral(true), lateral(false));
        assert!(
            (0.0015..0.005).contains(&(below - above)),
            "lower pole reaches {below} m, upper {above} m"
        );
        // Nowhere is it more than the relief's bound off the bean.
        let bound = 0.06 * a.kidney_half_width_m + 0.0012;
        for p in &points {
            assert!(kidney_relief(*p, &shape).abs() <= bound + 1e-6);
        }
        // The swells are there: along the anterior face the relief changes sign.
        let swell: Vec<f32> = (0..9)
            .map(|k| {
                let d = Vec3::new(0.2, -0.8 + 0.2 * k as f32, 0.9).normalize();
                let p = shape.surface(d);
                kidney_relief(p, &shape) + 0.06 * a.kidney_half_width_m * p.y / shape.half_length_m
            })
            .collect();
        assert!(
            swell.iter().any(|v| *v > 3e-4) && swell.iter().any(|v| *v < -3e-4),
            "{swell:?}"
        );
    }
}
