use super::*;
use crate::models::bem::{Element, Face, Sector, Surface};

fn esophagus_like() -> Surface {
    Sector {
        inner_m: 0.006,
        outer_m: 0.010,
        length_m: 0.060,
        span_rad: std::f64::consts::TAU,
        around: 30,
        through: 1,
        along: 30,
    }
    .surface()
}

/// The closest outer-wall triangle to `p` (by centroid), as the procedure will find it.
fn closest(inc: &Incision, p: DVec3) -> usize {
    (0..inc.triangles.len())
        .min_by(|&a, &b| {
            let c = |t: usize| {
                let [x, y, z] = inc.triangles[t].map(|i| inc.vertices[i as usize]);
                ((x + y + z) / 3.0 - p).length_squared()
            };
            c(a).total_cmp(&c(b))
        })
        .unwrap_or(0)
}

/// The incised surface as a [`Surface`] (for its watertightness check).
fn as_surface(inc: &Incision) -> Surface {
    Surface {
        vertices: inc.vertices.clone(),
        triangles: inc.triangles.clone(),
        faces: vec![Face::Outer; inc.triangles.len()],
    }
}

fn area(inc: &Incision, t: usize) -> f64 {
    let [a, b, c] = inc.triangles[t].map(|i| inc.vertices[i as usize]);
    0.5 * (b - a).cross(c - a).length()
}

/// The hierarchy holds: every original's pieces cover exactly its area and lie in it.
fn check_hierarchy(inc: &Incision, originals: &[Element]) {
    let mut sums = vec![0.0; originals.len()];
    for t in 0..inc.triangles.len() {
        let o = inc.origin(t);
        sums[o] += area(inc, t);
        let [a, b, c] = inc.triangles[t].map(|i| inc.vertices[i as usize]);
        let e = &originals[o];
        for p in [a, b, c, (a + b + c) / 3.0] {
            // In the original's plane, and inside it (barycentric coordinates >= 0).
            assert!(
                (p - e.centroid).dot(e.normal).abs() < 1e-12,
                "piece {t} off its plane"
            );
            let [x, y, z] = e.corners;
            let n = (y - x).cross(z - x);
            for (u, w) in [(x, y), (y, z), (z, x)] {
                assert!((w - u).cross(p - u).dot(n) >= -1e-9 * n.length_squared());
            }
        }
    }
    for (o, e) in originals.iter().enumerate() {
        assert!(
            (sums[o] - e.area_m2).abs() <= 1e-9 * e.area_m2,
            "original {o}: pieces {} m^2 of {} m^2",
            sums[o],
            e.area_m2
        );
        assert!(!inc.pieces(o).is_empty());
    }
}

#[test]
fn a_cut_along_the_anterior_wall_keeps_the_surface_watertight_and_the_hierarchy_whole() {
    let s = esophagus_like();
    let originals = s.elements();
    let mut inc = Incision::new(s.vertices.clone(), s.triangles.clone());
    // Along the anterior wall, slightly oblique, from z = 12 mm to 48 mm in 0.25 mm steps.
    let r = 0.010;
    let (z0, z1) = (0.012, 0.048);
    let steps = 144;
    for k in 0..=steps {
        let f = k as f64 / steps as f64;
        let angle = std::f64::consts::FRAC_PI_2 + 0.15 * f;
        let p = DVec3::new(r * angle.cos(), r * angle.sin(), z0 + (z1 - z0) * f);
        let t = closest(&inc, p);
        inc.advance(t, p);
    }
    assert!(as_surface(&inc).is_watertight());
    check_hierarchy(&inc, &originals);
    // The path's length on the cylinder, from its start to where it was last divided
    // (within the last triangle it has not crossed yet).
    let arc = ((z1 - z0).powi(2) + (0.15 * r).powi(2)).sqrt();
    let cut = inc.cut_length_m();
    assert!(
        cut > 0.9 * arc && cut < 1.05 * arc,
        "cut {cut} m of a {arc} m path"
    );
    // Every passed triangle borders a cut edge, and both sides of every cut edge passed.
    let passed: Vec<usize> = (0..inc.triangles.len())
        .filter(|&t| inc.passed(t))
        .collect();
    assert!(passed.len() >= 2 * inc.cuts().len());
    for &t in &passed {
        let tr = inc.triangles[t];
        assert!(
            inc.cuts()
                .iter()
                .any(|c| tr.contains(&c[0]) && tr.contains(&c[1]))
        );
    }
    // Only anterior outer-wall originals were divided.
    for t in 0..inc.triangles.len() {
        if inc.origin(t) != t || t >= originals.len() {
            let c = originals[inc.origin(t)].centroid;
            assert!(c.y > 0.008, "divided original at {c}");
        }
    }
}

#[test]
fn a_second_path_after_lifting_the_tool_keeps_it_watertight() {
    let s = esophagus_like();
    let originals = s.elements();
    let mut inc = Incision::new(s.vertices.clone(), s.triangles.clone());
    for (angle, z0, z1) in [(1.4f64, 0.02, 0.03), (1.7, 0.03, 0.02)] {
        for k in 0..=40 {
            let f = k as f64 / 40.0;
            let p = DVec3::new(0.01 * angle.cos(), 0.01 * angle.sin(), z0 + (z1 - z0) * f);
            let t = closest(&inc, p);
            inc.advance(t, p);
        }
        inc.lift();
    }
    assert!(as_surface(&inc).is_watertight());
    check_hierarchy(&inc, &originals);
    assert!(inc.cut_length_m() > 0.015);
}
