use super::*;

const TOL: f32 = 1e-6;

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

#[track_caller]
fn close(got: f32, want: f64, tol: f32) {
    assert!(
        (f64::from(got) - want).abs() <= f64::from(tol),
        "got {got}, want {want} (tolerance {tol})"
    );
}

#[track_caller]
fn close_v(got: Vec3, want: [f64; 3], tol: f32) {
    for (g, w) in got.to_array().into_iter().zip(want) {
        assert!(
            (f64::from(g) - w).abs() <= f64::from(tol),
            "got {got}, want {want:?} (tolerance {tol})"
        );
    }
}

// ---------------------------------------------------------------- sphere sets

#[test]
fn sphere_ray_along_an_axis_hits_at_centre_distance_minus_radius() {
    let centers = [v(0.3, 0.0, 0.0)];
    let radii = [0.05];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    let hit = s.cast_ray(Vec3::ZERO, Vec3::X, 1.0).expect("hit");
    assert_eq!(hit.feature, 0);
    close(hit.distance_m, 0.25, TOL);
    close(hit.t, 0.0, 0.0);
    close_v(hit.point, [0.25, 0.0, 0.0], TOL);
    close_v(hit.normal, [-1.0, 0.0, 0.0], TOL);
}

#[test]
fn sphere_the_nearest_of_two_wins() {
    let centers = [v(0.5, 0.0, 0.0), v(0.2, 0.0, 0.0)];
    let radii = [0.05, 0.02];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    let hit = s.cast_ray(Vec3::ZERO, Vec3::X, 1.0).expect("hit");
    assert_eq!(hit.feature, 1);
    close(hit.distance_m, 0.18, TOL);
    // From the other side the big sphere comes first.
    let hit = s.cast_ray(v(1.0, 0.0, 0.0), Vec3::NEG_X, 1.0).expect("hit");
    assert_eq!(hit.feature, 0);
    close(hit.distance_m, 0.45, TOL);
    close_v(hit.normal, [1.0, 0.0, 0.0], TOL);
}

#[test]
fn sphere_miss_beyond_max_and_beside() {
    let centers = [v(0.3, 0.0, 0.0)];
    let radii = [0.05];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    assert!(s.cast_ray(Vec3::ZERO, Vec3::X, 0.24).is_none());
    assert!(s.cast_ray(Vec3::ZERO, Vec3::X, 0.26).is_some());
    assert!(s.cast_ray(v(0.0, 0.06, 0.0), Vec3::X, 1.0).is_none());
    // Behind the origin.
    assert!(s.cast_ray(Vec3::ZERO, Vec3::NEG_X, 1.0).is_none());
    // Off-centre: the chord at height 0.03 enters at x = 0.3 - 0.04.
    let hit = s.cast_ray(v(0.0, 0.03, 0.0), Vec3::X, 1.0).expect("hit");
    close(hit.distance_m, 0.26, TOL);
    close_v(hit.normal, [-0.8, 0.6, 0.0], TOL);
    // Its bounding sphere starts at 0.25, the sphere itself only at 0.26.
    assert!(s.cast_ray(v(0.0, 0.03, 0.0), Vec3::X, 0.255).is_none());
}

#[test]
fn sphere_ray_from_inside_hits_at_zero_facing_back() {
    let centers = [v(0.3, 0.0, 0.0)];
    let radii = [0.05];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    let origin = v(0.31, 0.01, 0.0);
    let dir = v(1.0, 1.0, 0.0).normalize();
    let hit = s.cast_ray(origin, dir, 1.0).expect("hit");
    assert_eq!(hit.distance_m, 0.0);
    assert_eq!(hit.point, origin);
    close_v(hit.normal, [-f64::from(dir.x), -f64::from(dir.y), 0.0], TOL);
}

#[test]
fn sphere_nearest_within_orders_by_distance_then_index() {
    let centers = [
        v(0.1, 0.0, 0.0),
        v(-0.1, 0.0, 0.0),
        v(0.0, 0.05, 0.0),
        v(0.0, 0.0, 0.5),
    ];
    let radii = [0.02, 0.02, 0.01, 0.01];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    let found = s.nearest_within(Vec3::ZERO, 0.1);
    let ids: Vec<u32> = found.iter().map(|f| f.1).collect();
    assert_eq!(ids, vec![2, 0, 1]);
    close(found[0].0, 0.04, TOL);
    close(found[1].0, 0.08, TOL);
    close(found[2].0, 0.08, TOL);
    let ids: Vec<u32> = s
        .nearest_within(Vec3::ZERO, 0.0799)
        .iter()
        .map(|f| f.1)
        .collect();
    assert_eq!(ids, vec![2]);
    // A centre inside a sphere is at negative distance, so it comes first.
    let found = s.nearest_within(v(0.0, 0.045, 0.0), 0.1);
    assert_eq!(found[0].1, 2);
    close(found[0].0, -0.005, TOL);
}

#[test]
fn ties_go_to_the_lowest_feature_id() {
    let centers = [v(0.3, 0.0, 0.0), v(0.0, 0.0, 0.7), v(0.3, 0.0, 0.0)];
    let radii = [0.05, 0.01, 0.05];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    assert_eq!(s.distance(Vec3::ZERO).expect("some").1, 0);
    assert_eq!(
        s.cast_ray(Vec3::ZERO, Vec3::X, 1.0).expect("hit").feature,
        0
    );
    assert_eq!(
        s.cast_ray(v(0.3, 0.0, 0.0), Vec3::X, 1.0)
            .expect("hit")
            .feature,
        0
    );
    let a = [v(0.0, 0.0, 0.2), Vec3::ZERO, Vec3::ZERO];
    let b = [v(0.0, 0.1, 0.2), v(0.1, 0.0, 0.0), v(0.1, 0.0, 0.0)];
    let c = CapsuleSet::new(&a, &b, &[0.02, 0.05, 0.05]).expect("valid");
    let (d, f, _) = c.distance(v(0.05, 0.1, 0.0)).expect("some");
    close(d, 0.05, TOL);
    assert_eq!(f, 1);
}

#[test]
fn sphere_contacts_depth_is_radii_minus_centre_distance() {
    let centers = [v(0.1, 0.06, 0.0), v(0.5, 0.0, 0.0), v(0.1, 0.02, 0.04)];
    let radii = [0.02, 0.05, 0.015];
    let s = SphereSet::new(&centers, &radii).expect("valid");
    let contacts = s.sphere_contacts(v(0.1, 0.02, 0.0), 0.03);
    let ids: Vec<u32> = contacts.iter().map(|c| c.feature).collect();
    assert_eq!(ids, vec![0, 2]);
    // 0.03 + 0.02 - 0.04
    close(contacts[0].depth_m, 0.01, TOL);
    close_v(contacts[0].point, [0.1, 0.04, 0.0], TOL);
    close_v(contacts[0].normal, [0.0, -1.0, 0.0], TOL);
    // 0.03 + 0.015 - 0.04
    close(contacts[1].depth_m, 0.005, TOL);
    close_v(contacts[1].point, [0.1, 0.02, 0.025], TOL);
    close_v(contacts[1].normal, [0.0, 0.0, -1.0], TOL);
    assert!(s.sphere_contacts(v(0.1, -0.02, 0.0), 0.01).is_empty());
}

// ---------------------------------------------------------------- capsules

fn one_capsule() -> ([Vec3; 1], [Vec3; 1], [f32; 1]) {
    ([Vec3::ZERO], [v(0.2, 0.0, 0.0)], [0.03])
}

#[test]
fn capsule_ray_perpendicular_to_the_side() {
    let (a, b, r) = one_capsule();
    let c = CapsuleSet::new(&a, &b, &r).expect("valid");
    let hit = c
        .cast_ray(v(0.05, 0.5, 0.0), Vec3::NEG_Y, 1.0)
        .expect("hit");
    close(hit.distance_m, 0.47, TOL);
    close_v(hit.point, [0.05, 0.03, 0.0], TOL);
    close_v(hit.normal, [0.0, 1.0, 0.0], TOL);
    close(hit.t, 0.25, TOL);
    // Off the axis plane by z = 0.02: the side is at y = sqrt(0.03² - 0.02²).
    let y = (0.03f64 * 0.03 - 0.02 * 0.02).sqrt();
    let hit = c
        .cast_ray(v(0.05, 0.5, 0.02), Vec3::NEG_Y, 1.0)
        .expect("hit");
    close(hit.distance_m, 0.5 - y, TOL);
    close_v(hit.normal, [0.0, y / 0.03, 0.02 / 0.03], TOL);
}

#[test]
fn capsule_ray_along_the_axis_hits_the_cap() {
    let (a, b, r) = one_capsule();
    let c = CapsuleSet::new(&a, &b, &r).expect("valid");
    let hit = c.cast_ray(v(-0.5, 0.0, 0.0), Vec3::X, 1.0).expect("hit");
    close(hit.distance_m, 0.47, TOL);
    close_v(hit.point, [-0.03, 0.0, 0.0], TOL);
    close_v(hit.normal, [-1.0, 0.0, 0.0], TOL);
    assert_eq!(hit.t, 0.0);
    // Parallel to the axis, 0.01 off it: the far cap at x = 0.2 + sqrt(0.03² - 0.01²).
    let x = 0.2 + (0.03f64 * 0.03 - 0.01 * 0.01).sqrt();
    let hit = c
        .cast_ray(v(0.7, 0.01, 0.0), Vec3::NEG_X, 1.0)
        .expect("hit");
    close(hit.distance_m, 0.7 - x, TOL);
    close_v(hit.normal, [(x - 0.2) / 0.03, 0.01 / 0.03, 0.0], TOL);
    assert_eq!(hit.t, 1.0);
}

#[test]
fn capsule_distance_beside_beyond_the_ends_and_inside() {
    let a = [Vec3::ZERO, v(0.0, 1.0, 0.0)];
    let b = [v(0.2, 0.0, 0.0), v(0.0, 1.0, 0.0)];
    let r = [0.03, 0.01];
    let c = CapsuleSet::new(&a, &b, &r).expect("valid");
    let (d, f, t) = c.distance(v(0.1, 0.1, 0.0)).expect("some");
    close(d, 0.07, TOL);
    assert_eq!(f, 0);
    close(t, 0.5, TOL);
    let (d, f, t) = c.distance(v(0.3, 0.0, 0.1)).expect("some");
    close(d, 0.02f64.sqrt() - 0.03, TOL);
    assert_eq!((f, t), (0, 1.0));
    let (d, _, t) = c.distance(v(-0.04, 0.03, 0.0)).expect("some");
    close(d, 0.02, TOL);
    assert_eq!(t, 0.0);
    let (d, f, t) = c.distance(v(0.15, 0.01, 0.0)).expect("some");
    close(d, -0.02, TOL);
    assert_eq!(f, 0);
    close(t, 0.75, TOL);
    // The zero-length capsule is a sphere.
    let (d, f, _) = c.distance(v(0.0, 1.05, 0.0)).expect("some");
    close(d, 0.04, TOL);
    assert_eq!(f, 1);
}

// ---------------------------------------------------------------- generalized cylinders

/// Distance from `p` to the segment a-b minus `r`, written out independently.
fn capsule_sd(p: [f64; 3], a: [f64; 3], b: [f64; 3], r: f64) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let s = ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / l2).clamp(0.0, 1.0);
    let d = [ap[0] - s * ab[0], ap[1] - s * ab[1], ap[2] - s * ab[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - r
}

fn f64s(p: Vec3) -> [f64; 3] {
    [f64::from(p.x), f64::from(p.y), f64::from(p.z)]
}

#[test]
fn cylinder_with_equal_radii_behaves_as_capsules() {
    let line = [Vec3::ZERO, v(0.1, 0.0, 0.0), v(0.1, 0.1, 0.0)];
    let radii = [0.01; 3];
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    let (a, b) = ([line[0], line[1]], [line[1], line[2]]);
    let caps = CapsuleSet::new(&a, &b, &radii[..2]).expect("valid");
    for i in 0..9 {
        for j in 0..9 {
            let p = v(-0.04 + 0.025 * i as f32, -0.04 + 0.025 * j as f32, 0.007);
            let want = (0..2)
                .map(|k| capsule_sd(f64s(p), f64s(line[k]), f64s(line[k + 1]), 0.01))
                .fold(f64::INFINITY, f64::min);
            let (dg, _, _) = g.distance(p).expect("some");
            let (dc, _, _) = caps.distance(p).expect("some");
            close(dg, want, TOL);
            close(dc, want, TOL);
        }
    }
    for (origin, dir) in [
        (v(0.05, 0.3, 0.0), Vec3::NEG_Y),
        (v(0.3, 0.05, 0.004), Vec3::NEG_X),
        (v(0.1, 0.3, 0.0), Vec3::NEG_Y),
    ] {
        let hg = g.cast_ray(origin, dir, 1.0).expect("hit");
        let hc = caps.cast_ray(origin, dir, 1.0).expect("hit");
        assert_eq!((hg.feature, hg.t), (hc.feature, hc.t));
        assert!((hg.distance_m - hc.distance_m).abs() < TOL);
    }
    let hit = g
        .cast_ray(v(0.05, 0.3, 0.0), Vec3::NEG_Y, 1.0)
        .expect("hit");
    close(hit.distance_m, 0.29, TOL);
}

/// The test's tapered segment: a = 0 with 0.01 m, b = (0.1, 0, 0) with 0.005 m.
fn tapered() -> ([Vec3; 2], [f32; 2]) {
    ([Vec3::ZERO, v(0.1, 0.0, 0.0)], [0.01, 0.005])
}

/// Half-angle of the test's cone: the surface tilts toward +x by asin((ra - rb) / L).
fn theta() -> f64 {
    (0.005f64 / 0.1).asin()
}

/// Brute force over the hull's inscribed spheres (centre (s L, 0, 0), radius ra + s (rb - ra)):
/// the distance from an outside point and the parameter of the nearest sphere.
fn union_sd(p: [f64; 3]) -> (f64, f64) {
    let n = 200_000;
    (0..=n)
        .map(|i| {
            let s = f64::from(i) / f64::from(n);
            let (cx, r) = (0.1 * s, 0.01 - 0.005 * s);
            let d = ((p[0] - cx).powi(2) + p[1].powi(2) + p[2].powi(2)).sqrt() - r;
            (d, s)
        })
        .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a })
}

#[test]
fn tapered_lateral_distance_and_normal_match_the_cone() {
    let (line, radii) = tapered();
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    let (s, c) = theta().sin_cos();
    // Tangent points of the lateral line in the (x, y) plane, and its outward normal.
    let ta = [0.01 * s, 0.01 * c];
    let n = [s, c];
    for p in [v(0.05, 0.04, 0.0), v(0.03, 0.012, 0.0), v(0.08, 0.02, 0.0)] {
        let want = (f64::from(p.x) - ta[0]) * n[0] + (f64::from(p.y) - ta[1]) * n[1];
        let (brute, brute_t) = union_sd(f64s(p));
        assert!((want - brute).abs() < 1e-8, "{want} vs {brute}");
        let (d, f, t) = g.distance(p).expect("some");
        assert_eq!(f, 0);
        close(d, want, TOL);
        close(t, brute_t, 1e-4);
        let contact = g.sphere_contacts(p, d + 0.001);
        assert_eq!(contact.len(), 1);
        close_v(contact[0].normal, [s, c, 0.0], TOL);
        close(contact[0].depth_m, 0.001, TOL);
        // The contact point lies on the lateral line.
        let q = f64s(contact[0].point);
        close(0.0, (q[0] - ta[0]) * n[0] + (q[1] - ta[1]) * n[1], TOL);
    }
    // Rotated about the axis: the same distance, the normal turned with it.
    let (d, _, _) = g.distance(v(0.05, 0.0, 0.04)).expect("some");
    close(d, 0.05 * s + 0.04 * c - 0.01, TOL);
    let contact = g.sphere_contacts(v(0.05, 0.0, 0.04), 0.04);
    close_v(contact[0].normal, [s, 0.0, c], TOL);
    // Inside, near the axis: the nearest surface is the lateral one.
    let (d, _, _) = g.distance(v(0.05, 0.002, 0.0)).expect("some");
    close(d, 0.05 * s + 0.002 * c - 0.01, TOL);
    // Beyond the small end.
    let (d, _, t) = g.distance(v(0.13, 0.0, 0.0)).expect("some");
    close(d, 0.025, TOL);
    assert_eq!(t, 1.0);
}

#[test]
fn tapered_perpendicular_ray_at_the_middle_hits_the_cone() {
    let (line, radii) = tapered();
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    let (s, c) = theta().sin_cos();
    let y = (0.01 - 0.05 * s) / c;
    // Independently: the highest inscribed sphere over x = 0.05.
    let n = 200_000;
    let brute = (0..=n)
        .map(|i| {
            let u = f64::from(i) / f64::from(n);
            let (cx, r) = (0.1 * u, 0.01 - 0.005 * u);
            (r * r - (0.05 - cx).powi(2)).max(0.0).sqrt()
        })
        .fold(0.0, f64::max);
    assert!((y - brute).abs() < 1e-8, "{y} vs {brute}");
    let hit = g
        .cast_ray(v(0.05, 0.5, 0.0), Vec3::NEG_Y, 1.0)
        .expect("hit");
    assert_eq!(hit.feature, 0);
    close(hit.distance_m, 0.5 - y, TOL);
    close_v(hit.point, [0.05, y, 0.0], TOL);
    close_v(hit.normal, [s, c, 0.0], TOL);
    close(hit.t, (0.05 * c - y * s) / (0.1 * c), TOL);
    // Oblique, in the plane z = 0 through the axis: the ray meets the lateral line
    // x sin + y cos = ra where (o + l d) . (sin, cos) = ra.
    let (o, d) = ([0.2f64, 0.1], [-(0.8f64.sqrt()), -(0.2f64.sqrt())]);
    let l = (0.01 - o[0] * s - o[1] * c) / (d[0] * s + d[1] * c);
    let p = [o[0] + l * d[0], o[1] + l * d[1]];
    // On the band between the tangent points x = ra sin and x = L + rb sin.
    assert!(p[0] > 0.01 * s && p[0] < 0.1 + 0.005 * s, "{p:?}");
    let dir = v(-(0.8f32.sqrt()), -(0.2f32.sqrt()), 0.0);
    let hit = g.cast_ray(v(0.2, 0.1, 0.0), dir, 1.0).expect("hit");
    close(hit.distance_m, l, TOL);
    close_v(hit.point, [p[0], p[1], 0.0], TOL);
    close_v(hit.normal, [s, c, 0.0], TOL);
    // Along +z from below: the same cone, met on its -z side.
    let hit = g.cast_ray(v(0.05, 0.0, -0.3), Vec3::Z, 1.0).expect("hit");
    close(hit.distance_m, 0.3 - y, TOL);
    close_v(hit.normal, [s, 0.0, -c], TOL);
}

#[test]
fn tapered_axial_ray_hits_the_caps() {
    let (line, radii) = tapered();
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    let hit = g.cast_ray(v(-0.5, 0.0, 0.0), Vec3::X, 1.0).expect("hit");
    close(hit.distance_m, 0.49, TOL);
    close_v(hit.point, [-0.01, 0.0, 0.0], TOL);
    close_v(hit.normal, [-1.0, 0.0, 0.0], TOL);
    assert_eq!(hit.t, 0.0);
    let hit = g.cast_ray(v(0.5, 0.0, 0.0), Vec3::NEG_X, 1.0).expect("hit");
    close(hit.distance_m, 0.395, TOL);
    close_v(hit.normal, [1.0, 0.0, 0.0], TOL);
    assert_eq!(hit.t, 1.0);
}

#[test]
fn polyline_hits_on_the_second_segment_name_it() {
    let line = [Vec3::ZERO, v(0.1, 0.0, 0.0), v(0.1, 0.1, 0.0)];
    let g = GeneralizedCylinder::new(&line, &[0.01; 3]).expect("valid");
    let hit = g
        .cast_ray(v(0.3, 0.05, 0.0), Vec3::NEG_X, 1.0)
        .expect("hit");
    assert_eq!(hit.feature, 1);
    close(hit.t, 0.5, TOL);
    close(hit.distance_m, 0.19, TOL);
    close_v(hit.normal, [1.0, 0.0, 0.0], TOL);
    // Tapering up along the second segment (0.01 m to 0.02 m over 0.1 m along +y): the surface
    // at 0.05 along it is (ra - x sin) / cos from the axis, with sin = -0.1.
    let radii = [0.01, 0.01, 0.02];
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    let (s, c) = (-0.1f64, (1.0f64 - 0.01).sqrt());
    let y = (0.01 - 0.05 * s) / c;
    let hit = g
        .cast_ray(v(0.3, 0.05, 0.0), Vec3::NEG_X, 1.0)
        .expect("hit");
    assert_eq!(hit.feature, 1);
    close(hit.distance_m, 0.2 - y, TOL);
    close(hit.t, (0.05 * c - y * s) / (0.1 * c), TOL);
    // The normal tilts toward -y, the small end.
    close_v(hit.normal, [c, s, 0.0], TOL);
    let (d, f, t) = g.distance(v(0.1, 0.13, 0.0)).expect("some");
    close(d, 0.01, TOL);
    assert_eq!((f, t), (1, 1.0));
}

#[test]
fn contained_sphere_segment_is_the_bigger_sphere() {
    // |a - b| + rb = 0.03 <= ra: sphere b lies inside sphere a.
    let line = [Vec3::ZERO, v(0.01, 0.0, 0.0)];
    let g = GeneralizedCylinder::new(&line, &[0.05, 0.02]).expect("valid");
    for p in [v(0.1, 0.0, 0.0), v(0.0, 0.1, 0.0), v(-0.1, 0.0, 0.0)] {
        let (d, f, t) = g.distance(p).expect("some");
        close(d, 0.05, TOL);
        assert_eq!((f, t), (0, 0.0));
    }
    let hit = g.cast_ray(v(1.0, 0.0, 0.0), Vec3::NEG_X, 2.0).expect("hit");
    close(hit.distance_m, 0.95, TOL);
    // The other way round: the bigger sphere is the second, so t = 1.
    let line = [v(0.01, 0.0, 0.0), Vec3::ZERO];
    let g = GeneralizedCylinder::new(&line, &[0.02, 0.05]).expect("valid");
    let (d, _, t) = g.distance(v(0.1, 0.0, 0.0)).expect("some");
    close(d, 0.05, TOL);
    assert_eq!(t, 1.0);
    // Coincident points with equal radii, and a single point: spheres.
    let line = [v(0.2, 0.0, 0.0), v(0.2, 0.0, 0.0)];
    let g = GeneralizedCylinder::new(&line, &[0.03, 0.03]).expect("valid");
    close(g.distance(Vec3::ZERO).expect("some").0, 0.17, TOL);
    let g = GeneralizedCylinder::new(&line[..1], &[0.03]).expect("valid");
    assert_eq!(g.feature_count(), 1);
    let hit = g.cast_ray(Vec3::ZERO, Vec3::X, 1.0).expect("hit");
    close(hit.distance_m, 0.17, TOL);
}

#[test]
fn new_rejects_bad_arrays_naming_the_index() {
    let p3 = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let e = SphereSet::new(&p3, &[0.1, 0.1]).expect_err("mismatch");
    assert!(matches!(
        e,
        PrimitiveError::LengthMismatch {
            expected: 3,
            found: 2,
            ..
        }
    ));
    let e = CapsuleSet::new(&p3, &p3[..2], &[0.1; 3]).expect_err("mismatch");
    assert!(e.to_string().contains("b has 2 entries"), "{e}");
    let e = GeneralizedCylinder::new(&p3, &[0.1; 4]).expect_err("mismatch");
    assert!(e.to_string().contains("radii has 4"), "{e}");
    for bad in [0.0, -0.01, f32::NAN, f32::INFINITY] {
        let e = SphereSet::new(&p3, &[0.1, 0.1, bad]).expect_err("bad radius");
        assert!(matches!(e, PrimitiveError::BadRadius { index: 2, .. }));
        assert!(e.to_string().contains("index 2"), "{e}");
        let e = GeneralizedCylinder::new(&p3, &[0.1, bad, 0.1]).expect_err("bad radius");
        assert!(e.to_string().contains("index 1"), "{e}");
    }
    let nan = [Vec3::ZERO, v(0.0, f32::NAN, 0.0), Vec3::Y];
    let e = SphereSet::new(&nan, &[0.1; 3]).expect_err("bad point");
    assert!(matches!(e, PrimitiveError::BadPoint { index: 1, .. }));
    assert!(e.to_string().contains("index 1"), "{e}");
    let e = CapsuleSet::new(&p3, &nan, &[0.1; 3]).expect_err("bad point");
    assert!(e.to_string().starts_with("b at index 1"), "{e}");
    let e = GeneralizedCylinder::new(&nan, &[0.1; 3]).expect_err("bad point");
    assert!(e.to_string().contains("centreline at index 1"), "{e}");
    assert!(GeneralizedCylinder::new(&[], &[]).is_ok());
}

#[test]
fn non_finite_queries_and_empty_sets_answer_nothing() {
    let (line, radii) = tapered();
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    assert!(g.cast_ray(v(f32::NAN, 0.0, 0.0), Vec3::X, 1.0).is_none());
    assert!(
        g.cast_ray(v(-1.0, 0.0, 0.0), v(f32::INFINITY, 0.0, 0.0), 1.0)
            .is_none()
    );
    assert!(g.cast_ray(v(-1.0, 0.0, 0.0), Vec3::X, f32::NAN).is_none());
    assert!(g.cast_ray(v(-1.0, 0.0, 0.0), Vec3::ZERO, 2.0).is_none());
    assert!(g.distance(v(0.0, f32::NAN, 0.0)).is_none());
    assert!(g.nearest_within(Vec3::ZERO, f32::NAN).is_empty());
    assert!(g.sphere_contacts(v(f32::NAN, 0.0, 0.0), 0.1).is_empty());
    let empty = GeneralizedCylinder::new(&[], &[]).expect("valid");
    assert_eq!(empty.feature_count(), 0);
    assert!(empty.distance(Vec3::ZERO).is_none());
    assert!(empty.cast_ray(Vec3::ZERO, Vec3::X, 1.0).is_none());
    let none = SphereSet::new(&[], &[]).expect("valid");
    assert!(none.distance(Vec3::ZERO).is_none());
}

use crate::collision::test_support::Lcg;

#[test]
fn random_rays_hit_the_surface_with_nothing_inside_before() {
    let line = [
        Vec3::ZERO,
        v(0.08, 0.02, 0.0),
        v(0.15, 0.0, 0.03),
        v(0.2, -0.03, 0.03),
        v(0.215, -0.03, 0.03),
    ];
    // The last segment is steep (sin = -14/15), the case where the cone's other nappe comes
    // close to its band.
    let radii = [0.012, 0.006, 0.015, 0.004, 0.018];
    let g = GeneralizedCylinder::new(&line, &radii).expect("valid");
    let mut rng = Lcg(0x5eed);
    let (mut hits, mut misses, mut inside) = (0, 0, 0);
    let max_m = 0.6;
    let step = 1e-4;
    for ray in 0..200 {
        let k = (rng.next() * 4.0) as usize % 4;
        // One ray in ten starts on the centreline, inside.
        let origin = if ray % 10 == 0 {
            line[k].lerp(line[k + 1], rng.next())
        } else {
            v(
                rng.range(-0.15, 0.35),
                rng.range(-0.2, 0.2),
                rng.range(-0.2, 0.2),
            )
        };
        let aim = line[k].lerp(line[k + 1], rng.next())
            + v(
                rng.range(-0.02, 0.02),
                rng.range(-0.02, 0.02),
                rng.range(-0.02, 0.02),
            );
        let Some(dir) = (aim - origin).try_normalize() else {
            continue;
        };
        let reach = match g.cast_ray(origin, dir, max_m) {
            Some(hit) => {
                let (d, f, _) = g.distance(hit.point).expect("some");
                assert!((hit.normal.length() - 1.0).abs() < 1e-5, "{hit:?}");
                if hit.distance_m == 0.0 {
                    inside += 1;
                    assert!(d <= 0.0, "{hit:?} starts outside");
                    assert!((hit.normal + dir).length() < 1e-6, "{hit:?}");
                } else {
                    hits += 1;
                    assert!(d.abs() < 1e-5, "hit {hit:?} is {d} m off the surface");
                    assert!(hit.normal.dot(dir) <= 1e-6, "{hit:?} leaves");
                    // The feature reported is the one touching the hit point.
                    let own = g.shape(hit.feature as usize).closest(hit.point).sd;
                    assert!(own.abs() < 1e-5, "{hit:?}: feature {f} nearest, own {own}");
                }
                hit.distance_m
            }
            None => {
                misses += 1;
                max_m
            }
        };
        let mut s = 0.0;
        while s < reach - 1e-6 {
            let (d, _, _) = g.distance(origin + dir * s).expect("some");
            assert!(
                d > -1e-6,
                "{s} m along {origin} {dir} is {d} m inside, before {reach}"
            );
            s += step;
        }
    }
    assert!(
        hits >= 60 && misses >= 10 && inside >= 15,
        "hits {hits}, misses {misses}, inside {inside}"
    );
}
