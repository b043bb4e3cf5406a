use super::*;
use glam::Mat3;
use std::f64::consts::{FRAC_1_SQRT_2, PI as PI64};

const MM: f32 = 1e-3;

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

#[track_caller]
fn close(got: f32, want: f64, tol: f64) {
    assert!(
        (f64::from(got) - want).abs() <= tol,
        "got {got}, want {want} (tolerance {tol})"
    );
}

#[track_caller]
fn close_v(got: Vec3, want: [f64; 3], tol: f64) {
    for (g, w) in got.to_array().into_iter().zip(want) {
        assert!(
            (f64::from(g) - w).abs() <= tol,
            "got {got}, want {want:?} (tolerance {tol})"
        );
    }
}

/// All contacts of `tool` with `points`, by testing every point.
fn all_hits(tool: &Instrument, points: &[Vec3]) -> Vec<ToolContact> {
    let mut out = Vec::new();
    tool.contacts_all(PointCloud::from_points(points), &mut out);
    out
}

fn single(cyl: ToolCylinder) -> Instrument {
    Instrument::new(vec![cyl]).expect("one cylinder")
}

/// A cylinder of radius 2.5 mm along +X from the origin, `len_m` long.
fn x_rod(len_m: f32) -> ToolCylinder {
    ToolCylinder::constant(Vec3::ZERO, v(len_m, 0.0, 0.0), 2.5 * MM).expect("valid")
}

/// The orientation that points the instrument (local -Z) along `dir`.
fn aiming(dir: Vec3) -> Quat {
    Quat::from_rotation_arc(Vec3::NEG_Z, dir.normalize())
}

// ------------------------------------------------------------------------ step 1: the angles

#[test]
fn step1_rejects_vertices_beyond_either_end() {
    let tool = single(x_rod(0.02));
    // All three lie 1 mm from the axis line, well within the radius of the line.
    let pts = [
        v(-MM, 1.0 * MM, 0.0),
        v(21.0 * MM, 1.0 * MM, 0.0),
        v(10.0 * MM, 1.0 * MM, 0.0),
    ];
    let hits = all_hits(&tool, &pts);
    assert_eq!(hits.len(), 1, "{hits:?}");
    assert_eq!(hits[0].vertex, 2);

    // An oblique axis: 0.5 mm behind p0 and 0.5 mm past p1 (along the axis), 0.5 mm off it.
    let p0 = v(0.01, 0.02, 0.03);
    let a = v(0.01, 0.01, 0.005);
    let cyl = ToolCylinder::constant(p0, p0 + a, 2.5 * MM).expect("valid");
    let u = a.normalize();
    let side = u.any_orthonormal_vector();
    assert!(
        cyl.penetration(p0 - u * 0.5 * MM + side * 0.5 * MM)
            .is_none()
    );
    assert!(
        cyl.penetration(p0 + a + u * 0.5 * MM + side * 0.5 * MM)
            .is_none()
    );
    assert!(cyl.penetration(p0 + a * 0.5 + side * 0.5 * MM).is_some());
}

#[test]
fn step1_accepts_exactly_ninety_degrees_and_rejects_just_past() {
    let cyl = x_rod(0.01);
    // Projection exactly at p0: ∠p1 p0 v = 90°.
    let at0 = cyl
        .penetration(v(0.0, 1.0 * MM, 0.0))
        .expect("90° at p0 is inside");
    assert_eq!(at0.t, 0.0);
    assert_eq!(at0.axis_point, Vec3::ZERO);
    close(at0.depth_m, 1.5e-3, 1e-9);
    close_v(at0.dir, [0.0, 1.0, 0.0], 1e-7);
    // Projection exactly at p1: ∠p0 p1 v = 90°.
    let at1 = cyl
        .penetration(v(0.01, 1.0 * MM, 0.0))
        .expect("90° at p1 is inside");
    assert_eq!(at1.t, 1.0);
    assert_eq!(at1.axis_point, v(0.01, 0.0, 0.0));
    close(at1.depth_m, 1.5e-3, 1e-9);
    // One micrometre past either end: the angle exceeds 90°.
    assert!(cyl.penetration(v(-1e-6, 1.0 * MM, 0.0)).is_none());
    assert!(cyl.penetration(v(0.010001, 1.0 * MM, 0.0)).is_none());
}

// ---------------------------------------------------------------------- step 2: the distance

#[test]
fn step2_depth_and_direction_against_hand_values() {
    let cyl = x_rod(0.02);
    // d = sqrt(2) mm at t = 0.25: depth = 2.5 - 1.41421356 = 1.08578644 mm along (0, 1, 1)/√2.
    let hit = cyl
        .penetration(v(5.0 * MM, 1.0 * MM, 1.0 * MM))
        .expect("inside");
    close(hit.t, 0.25, 1e-7);
    close_v(hit.axis_point, [0.005, 0.0, 0.0], 1e-9);
    close(hit.depth_m, 1.085_786_44e-3, 1e-9);
    close_v(hit.dir, [0.0, FRAC_1_SQRT_2, FRAC_1_SQRT_2], 1e-6);
    // 2.4 mm off the axis: 0.1 mm deep; exactly at the radius or beyond: outside (d < r).
    close(
        cyl.penetration(v(5.0 * MM, 2.4 * MM, 0.0))
            .expect("inside")
            .depth_m,
        1e-4,
        1e-9,
    );
    assert!(cyl.penetration(v(5.0 * MM, 2.5 * MM, 0.0)).is_none());
    assert!(cyl.penetration(v(5.0 * MM, 0.0, -2.6 * MM)).is_none());

    // An oblique axis with unit direction (0.6, 0.8, 0) and length 5 mm.
    let p0 = v(0.01, 0.02, -0.01);
    let a = v(3.0 * MM, 4.0 * MM, 0.0);
    let cyl = ToolCylinder::constant(p0, p0 + a, 2.5 * MM).expect("valid");
    let hit = cyl
        .penetration(p0 + a * 0.4 + v(0.0, 0.0, 2.0 * MM))
        .expect("inside");
    close(hit.t, 0.4, 1e-5);
    close(hit.depth_m, 0.5e-3, 1e-8);
    close_v(hit.dir, [0.0, 0.0, 1.0], 1e-5);
    let hit = cyl
        .penetration(p0 + a * 0.7 + v(-0.8, 0.6, 0.0) * MM)
        .expect("inside");
    close(hit.t, 0.7, 1e-5);
    close(hit.depth_m, 1.5e-3, 1e-8);
    close_v(hit.dir, [-0.8, 0.6, 0.0], 1e-5);
}

#[test]
fn tapered_cylinder_penetration_follows_the_interpolated_radius() {
    // r = 3 mm at t = 0 down to 1 mm at t = 1, over 20 mm: r(t) = 3 - 2t mm.
    let cyl = ToolCylinder::new(
        Vec3::ZERO,
        v(0.02, 0.0, 0.0),
        &[(0.0, 3.0 * MM), (1.0, 1.0 * MM)],
    )
    .expect("valid");
    close(cyl.max_radius_m(), 3e-3, 1e-10);
    // 2 mm off the axis near t = 0 (t = 0.1, r = 2.8 mm): 0.8 mm deep.
    let near0 = cyl
        .penetration(v(2.0 * MM, 2.0 * MM, 0.0))
        .expect("inside near t = 0");
    close(near0.t, 0.1, 1e-6);
    close(near0.depth_m, 0.8e-3, 1e-8);
    // At t = 0.4 (r = 2.2 mm): 0.2 mm deep.
    close(
        cyl.penetration(v(8.0 * MM, 0.0, 2.0 * MM))
            .expect("inside")
            .depth_m,
        0.2e-3,
        1e-8,
    );
    // The same 2 mm near t = 1 (t = 0.9, r = 1.2 mm): outside.
    assert!(cyl.penetration(v(18.0 * MM, 2.0 * MM, 0.0)).is_none());

    // Three samples, constant outside [0.2, 1].
    let cyl = ToolCylinder::new(
        Vec3::ZERO,
        Vec3::X,
        &[(0.2, 2.0 * MM), (0.6, 4.0 * MM), (1.0, 1.0 * MM)],
    )
    .expect("valid");
    close(cyl.radius_at(0.0), 2e-3, 1e-9);
    close(cyl.radius_at(0.1), 2e-3, 1e-9);
    close(cyl.radius_at(0.4), 3e-3, 1e-9);
    close(cyl.radius_at(0.6), 4e-3, 1e-9);
    close(cyl.radius_at(0.8), 2.5e-3, 1e-9);
    close(cyl.radius_at(1.0), 1e-3, 1e-9);
}

#[test]
fn vertex_on_the_axis_gets_a_finite_perpendicular_direction_and_the_full_radius() {
    let cyl = x_rod(0.02);
    let hit = cyl.penetration(v(0.01, 0.0, 0.0)).expect("inside");
    assert_eq!(hit.depth_m, 2.5 * MM);
    assert!(hit.dir.is_finite());
    close(hit.dir.length(), 1.0, 1e-6);
    close(hit.dir.dot(Vec3::X), 0.0, 1e-7);

    // An oblique axis; the vertex is p0 itself, so v - p is exactly zero.
    let p0 = v(0.01, -0.02, 0.03);
    let cyl = ToolCylinder::new(
        p0,
        p0 + v(1.0, 2.0, 3.0) * MM,
        &[(0.0, 2.0 * MM), (1.0, 1.0 * MM)],
    )
    .expect("valid");
    let hit = cyl.penetration(p0).expect("inside");
    assert_eq!(hit.t, 0.0);
    assert_eq!(hit.depth_m, 2.0 * MM);
    assert!(hit.dir.is_finite());
    close(hit.dir.length(), 1.0, 1e-6);
    close(hit.dir.dot(v(1.0, 2.0, 3.0).normalize()), 0.0, 1e-6);
    // Deterministic: the same direction every time.
    assert_eq!(cyl.penetration(p0).expect("inside").dir, hit.dir);
}

#[test]
fn a_vertex_inside_two_cylinders_is_reported_once_for_the_deeper() {
    let long = ToolCylinder::constant(Vec3::ZERO, v(0.02, 0.0, 0.0), 2.0 * MM).expect("valid");
    let fat =
        ToolCylinder::constant(v(0.005, 0.0, 0.0), v(0.015, 0.0, 0.0), 3.0 * MM).expect("valid");
    let tool = Instrument::new(vec![long.clone(), fat]).expect("valid");
    let hits = all_hits(
        &tool,
        &[v(10.0 * MM, 1.0 * MM, 0.0), v(2.0 * MM, 1.0 * MM, 0.0)],
    );
    assert_eq!(hits.len(), 2);
    assert_eq!((hits[0].vertex, hits[0].cylinder), (0, 1));
    close(hits[0].depth_m, 2e-3, 1e-8);
    assert_eq!((hits[1].vertex, hits[1].cylinder), (1, 0));
    close(hits[1].depth_m, 1e-3, 1e-8);
    // Equal depths: the lower index.
    let twins = Instrument::new(vec![long.clone(), long]).expect("valid");
    assert_eq!(
        all_hits(&twins, &[v(10.0 * MM, 1.0 * MM, 0.0)])[0].cylinder,
        0
    );
}

#[test]
fn tip_contacts_is_a_sphere_about_the_tip() {
    let pts = [
        v(1.0 * MM, 0.0, 0.0),
        Vec3::ZERO,
        v(0.0, 3.0 * MM, 0.0),
        v(0.0, 0.0, -1.5 * MM),
    ];
    let mut out = Vec::new();
    tip_contacts(
        Vec3::ZERO,
        2.0 * MM,
        PointCloud::from_points(&pts),
        &mut out,
    )
    .expect("valid");
    let got: Vec<(u32, f32, Vec3)> = out.iter().map(|c| (c.vertex, c.depth_m, c.dir)).collect();
    assert_eq!(got.len(), 3, "{got:?}");
    assert_eq!((got[0].0, got[0].2), (0, Vec3::X));
    close(got[0].1, 1e-3, 1e-9);
    assert_eq!((got[1].0, got[1].1, got[1].2), (1, 2.0 * MM, Vec3::X));
    assert_eq!((got[2].0, got[2].2), (3, Vec3::NEG_Z));
    close(got[2].1, 0.5e-3, 1e-9);
}

// ---------------------------------------------------------------------------------- forces

/// A flat sheet z = 0 of cell-centred points `spacing_m` apart over x in [-5, 25] mm and y in
/// [-5, 5] mm; each point stands for one cell.
fn sheet(spacing_m: f64) -> Vec<Vec3> {
    let nx = (0.030 / spacing_m).round() as usize;
    let ny = (0.010 / spacing_m).round() as usize;
    let mut pts = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let x = -0.005 + (i as f64 + 0.5) * spacing_m;
            let y = -0.005 + (j as f64 + 0.5) * spacing_m;
            pts.push(v(x as f32, y as f32, 0.0));
        }
    }
    pts
}

#[test]
fn sheet_force_does_not_depend_on_resolution_and_matches_the_integral() {
    // A 20 mm rod of radius r = 2.5 mm lying along x, pressed h = 0.9 mm into the sheet: its
    // axis is c = r - h = 1.6 mm above it (0.1 mm off y = 0, so the grid is not symmetric).
    let (r, h, len, k) = (2.5e-3f64, 0.9e-3f64, 0.02f64, 1e7f32);
    let c = r - h;
    let w = (r * r - c * c).sqrt(); // half-width of the contact strip
    let y0 = 0.1e-3;
    let rod = ToolCylinder::constant(
        v(0.0, y0 as f32, c as f32),
        v(len as f32, y0 as f32, c as f32),
        r as f32,
    )
    .expect("valid");
    let tool = single(rod);
    // A vertex at lateral offset y is d = sqrt(y² + c²) from the axis. Over the strip |y| < w:
    //   ∫ depth dy = ∫ (r - d) dy = w r - c² ln((r + w) / c)
    //   ∫ depth · (c / d) dy (the part along -z) = 2 r c ln((r + w) / c) - 2 w c
    let ln = ((r + w) / c).ln();
    let want_sum = f64::from(k) * len * (w * r - c * c * ln);
    let want_fz = -f64::from(k) * len * (2.0 * r * c * ln - 2.0 * w * c);

    let mut totals = Vec::new();
    for spacing in [0.5e-3, 0.25e-3] {
        let pts = sheet(spacing);
        let areas = vec![(spacing * spacing) as f32; pts.len()];
        let hits = all_hits(&tool, &pts);
        let mut forces = Vec::new();
        let reaction = penalty_forces(
            &hits,
            VertexAreas::PerVertex(&areas),
            k,
            Vec3::ZERO,
            &mut forces,
        )
        .expect("valid");
        let magnitude: f64 = forces.iter().map(|(_, f)| f64::from(f.length())).sum();
        let on_sheet = -reaction.force_n;
        println!(
            "spacing {:.2} mm: {} points, {} contacts, sum |f| = {magnitude:.5} N (k ∫depth dA = \
             {want_sum:.5} N), F_z on sheet = {:.5} N (analytic {want_fz:.5} N), F_y = {:.2e} N",
            spacing * 1e3,
            pts.len(),
            hits.len(),
            on_sheet.z,
            on_sheet.y,
        );
        assert!(
            (magnitude - want_sum).abs() <= 0.02 * want_sum,
            "{magnitude} vs {want_sum}"
        );
        close(on_sheet.z, want_fz, 0.02 * want_fz.abs());
        assert!(on_sheet.y.abs() <= 0.02 * on_sheet.z.abs());
        assert!(on_sheet.x.abs() <= 1e-4 * on_sheet.z.abs());
        // A uniform area gives the same forces.
        let mut uniform = Vec::new();
        let same = penalty_forces(
            &hits,
            VertexAreas::Uniform((spacing * spacing) as f32),
            k,
            Vec3::ZERO,
            &mut uniform,
        )
        .expect("valid");
        assert_eq!((same, &uniform), (reaction, &forces));
        totals.push(f64::from(on_sheet.z));
    }
    let change = (totals[0] - totals[1]).abs() / totals[1].abs();
    println!(
        "F_z changes by {:.3} % from 0.5 mm to 0.25 mm spacing",
        change * 100.0
    );
    assert!(change <= 0.02, "{totals:?}");
}

#[test]
fn reaction_is_minus_the_sum_of_vertex_forces_with_its_torque() {
    // One contact by hand: 1.5 mm deep along +Y at axis point (5, 0, 0) mm, area 1 mm²,
    // k = 1e7 Pa/m: f = 1e7 · 1e-6 · 1.5e-3 = 0.015 N along +Y.
    let tool = single(x_rod(0.02));
    let hits = all_hits(&tool, &[v(5.0 * MM, 1.0 * MM, 0.0)]);
    let mut forces = Vec::new();
    let at_origin = penalty_forces(
        &hits,
        VertexAreas::Uniform(1e-6),
        1e7,
        Vec3::ZERO,
        &mut forces,
    )
    .expect("valid");
    assert_eq!(forces.len(), 1);
    close_v(forces[0].1, [0.0, 0.015, 0.0], 1e-8);
    close_v(at_origin.force_n, [0.0, -0.015, 0.0], 1e-8);
    // (0.005, 0, 0) × (0, -0.015, 0) = (0, 0, -7.5e-5) N·m.
    close_v(at_origin.torque_n_m, [0.0, 0.0, -7.5e-5], 1e-11);
    let about = v(0.01, 0.0, 0.0);
    let at_end =
        penalty_forces(&hits, VertexAreas::Uniform(1e-6), 1e7, about, &mut forces).expect("valid");
    close_v(at_end.torque_n_m, [0.0, 0.0, 7.5e-5], 1e-11);

    // Many contacts: a grasper's jaws driven through the sheet, unequal areas.
    let pts = sheet(0.5e-3);
    let tool =
        Instrument::grasper(v(0.01, 0.0, 3.0 * MM), aiming(v(1.0, 0.2, -1.0)), 0.6).expect("valid");
    let hits = all_hits(&tool, &pts);
    assert!(hits.len() >= 20, "{}", hits.len());
    let areas: Vec<f32> = (0..pts.len())
        .map(|i| 1e-6 * (1.0 + (i % 7) as f32 * 0.1))
        .collect();
    let reaction = penalty_forces(
        &hits,
        VertexAreas::PerVertex(&areas),
        1e7,
        Vec3::ZERO,
        &mut forces,
    )
    .expect("valid");
    assert_eq!(forces.len(), hits.len());
    let sum: Vec3 = forces.iter().fold(Vec3::ZERO, |s, (_, f)| s + *f);
    assert_eq!(
        reaction.force_n, -sum,
        "summed in the same order: the same bits"
    );
    assert!(reaction.force_n.length() > 0.0);
    // About another point: τ_about = τ_origin + (origin - about) × F.
    let moved = penalty_forces(
        &hits,
        VertexAreas::PerVertex(&areas),
        1e7,
        about,
        &mut forces,
    )
    .expect("valid");
    let want = reaction.torque_n_m + (Vec3::ZERO - about).cross(reaction.force_n);
    let scale = reaction.torque_n_m.length().max(1e-9);
    assert!(
        (moved.torque_n_m - want).length() <= 1e-4 * scale,
        "{moved:?} vs {want}"
    );
    assert_eq!(moved.force_n, reaction.force_n);
}

// ------------------------------------------------------------------- local concavity trap

#[test]
fn concavity_trap_the_shaft_touches_the_rim_while_the_tip_point_sees_nothing() {
    // A groove along y, 12 mm wide and 12 mm deep, in a plateau at z = 0 (Fig. 3): its
    // cross-section walks the plateau x in [-20, -6] mm, down the wall at x = -6, along the
    // floor at z = -12, up the wall at x = 6 and along the plateau to x = 20, every 0.5 mm,
    // repeated for y in [-10, 10] mm.
    let mut section = Vec::new();
    for i in -40..=-12 {
        section.push((i as f32 * 0.5, 0.0));
    }
    for i in 1..=24 {
        section.push((-6.0, -(i as f32) * 0.5));
    }
    for i in -11..=11 {
        section.push((i as f32 * 0.5, -12.0));
    }
    for i in (1..=24).rev() {
        section.push((6.0, -(i as f32) * 0.5));
    }
    for i in 12..=40 {
        section.push((i as f32 * 0.5, 0.0));
    }
    let mut pts = Vec::new();
    for j in -20..=20 {
        for &(x, z) in &section {
            pts.push(v(x * MM, j as f32 * 0.5 * MM, z * MM));
        }
    }
    // An L-hook whose tip hangs in the middle of the groove, 6 mm from the walls and the floor,
    // hook along +y (down the groove), the shaft leaving at 45° over the right rim: its axis
    // passes through the rim's edge (x = 6, z = 0), where the tapered shaft is 2.2 mm thick.
    let tip = v(0.0, 0.0, -6.0 * MM);
    let up = v(1.0, 0.0, 1.0).normalize(); // local +Z: towards the handle
    let orientation = Quat::from_mat3(&Mat3::from_cols(Vec3::Y.cross(up), Vec3::Y, up));
    let tool = Instrument::l_hook(tip, orientation).expect("valid");
    let hook = &tool.cylinders()[1];
    close_v(hook.p1() - hook.p0(), [0.0, 6e-3, 0.0], 1e-7);

    let hits = all_hits(&tool, &pts);
    let mut tip_hits = Vec::new();
    tip_contacts(
        tip,
        SHAFT_RADIUS_M,
        PointCloud::from_points(&pts),
        &mut tip_hits,
    )
    .expect("valid");
    let deepest = hits.iter().map(|c| c.depth_m).fold(0.0, f32::max);
    println!(
        "groove of {} points: generalized cylinders find {} contacts (deepest {:.2} mm); the tip \
         point finds {}",
        pts.len(),
        hits.len(),
        deepest * 1e3,
        tip_hits.len()
    );
    assert!(tip_hits.is_empty(), "no tissue near the tip: {tip_hits:?}");
    assert!(hits.len() >= 10, "{}", hits.len());
    assert!(deepest > 1.0 * MM, "{deepest}");
    for c in &hits {
        assert_eq!(c.cylinder, 0, "the shaft, not the hook: {c:?}");
        let p = pts[c.vertex as usize];
        let from_rim = (v(p.x, 0.0, p.z) - v(6.0 * MM, 0.0, 0.0)).length();
        assert!(from_rim < 4.0 * MM, "contact at {p} is not at the rim");
    }
}

// --------------------------------------------------------------------------- instruments

#[test]
fn l_hook_hook_is_perpendicular_to_the_shaft_at_its_tip() {
    let tip = v(0.01, -0.02, 0.05);
    let q = Quat::from_euler(glam::EulerRot::YXZ, 0.4, -0.7, 1.1);
    let tool = Instrument::l_hook(tip, q * 2.0).expect("valid (scaled quaternion normalised)");
    let [straight, hook] = tool.cylinders() else {
        panic!("two cylinders, got {}", tool.cylinders().len());
    };
    assert_eq!(straight.p1(), tip);
    assert_eq!(hook.p0(), tip);
    let shaft = straight.p1() - straight.p0();
    let bent = hook.p1() - hook.p0();
    close(shaft.length(), 0.33, 1e-6);
    close(bent.length(), 6e-3, 1e-8);
    close(shaft.normalize().dot(bent.normalize()), 0.0, 1e-6);
    // The instrument points along local -Z, the hook along local +Y.
    close_v(
        shaft.normalize(),
        (q * Vec3::NEG_Z).as_dvec3().to_array(),
        1e-6,
    );
    close_v(bent.normalize(), (q * Vec3::Y).as_dvec3().to_array(), 1e-6);
    // 2.5 mm shaft narrowing over its last 10 mm to the 0.5 mm wire.
    close(straight.radius_at(0.0), 2.5e-3, 1e-10);
    close(straight.radius_at(1.0 - 0.010 / 0.33), 2.5e-3, 1e-9);
    close(straight.radius_at(1.0 - 0.005 / 0.33), 1.5e-3, 1e-8);
    close(straight.radius_at(1.0), 0.5e-3, 1e-10);
    close(hook.max_radius_m(), 0.5e-3, 1e-10);
}

#[test]
fn grasper_jaws_open_by_the_given_angle() {
    let hinge = v(-0.02, 0.03, 0.01);
    let q = Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.2, -0.5);
    let forward = q * Vec3::NEG_Z;
    for degrees in [0.0f64, 30.0, 60.0] {
        let opening = (degrees * PI64 / 180.0) as f32;
        let tool = Instrument::grasper(hinge, q, opening).expect("valid");
        let [shaft, upper, lower] = tool.cylinders() else {
            panic!("three cylinders");
        };
        assert_eq!(shaft.p1(), hinge);
        close(shaft.max_radius_m(), 2.5e-3, 1e-10);
        let (du, dl) = (upper.p1() - upper.p0(), lower.p1() - lower.p0());
        close(du.length(), 0.02, 1e-7);
        close(dl.length(), 0.02, 1e-7);
        let between = du.cross(dl).length().atan2(du.dot(dl));
        close(between, f64::from(opening), 1e-5);
        // Symmetric about the shaft, the upper jaw towards local +Y.
        let half = |d: Vec3| d.cross(forward).length().atan2(d.dot(forward));
        close(half(du), f64::from(opening) / 2.0, 1e-5);
        close(half(dl), f64::from(opening) / 2.0, 1e-5);
        close(((du + dl).normalize() - forward).length(), 0.0, 1e-5);
        let up = q * Vec3::Y;
        assert!((upper.p1() - hinge).dot(up) > 0.0 && (lower.p1() - hinge).dot(up) < 0.0);
        // Each jaw's axis starts 1.25 mm off the pin; jaws narrow from 1.25 to 0.75 mm.
        close((upper.p0() - hinge).length(), 1.25e-3, 1e-8);
        close((lower.p0() - hinge).length(), 1.25e-3, 1e-8);
        close(upper.radius_at(0.0), 1.25e-3, 1e-10);
        close(upper.radius_at(1.0), 0.75e-3, 1e-10);
    }
}

// -------------------------------------------------------------------------------- errors

#[test]
fn invalid_inputs_give_typed_errors() {
    let (a, b) = (Vec3::ZERO, Vec3::X);
    let nan = v(f32::NAN, 0.0, 0.0);
    assert!(matches!(
        ToolCylinder::constant(nan, b, 1e-3),
        Err(ToolError::NonFinitePoint { which: "p0", .. })
    ));
    assert!(matches!(
        ToolCylinder::constant(a, v(0.0, f32::INFINITY, 0.0), 1e-3),
        Err(ToolError::NonFinitePoint { which: "p1", .. })
    ));
    assert_eq!(
        ToolCylinder::constant(b, b, 1e-3),
        Err(ToolError::DegenerateAxis { point: b })
    );
    assert_eq!(ToolCylinder::new(a, b, &[]), Err(ToolError::EmptyProfile));
    for bad in [0.0, -1e-3, f32::NAN, f32::INFINITY] {
        let err = ToolCylinder::new(a, b, &[(0.0, 1e-3), (1.0, bad)]).expect_err("bad radius");
        assert!(
            matches!(err, ToolError::BadRadius { sample: 1, .. }),
            "{err:?}"
        );
    }
    for (profile, sample) in [
        (&[(-0.1, 1e-3)][..], 0),
        (&[(0.0, 1e-3), (1.5, 1e-3)][..], 1),
        (&[(0.5, 1e-3), (0.5, 2e-3)][..], 1),
        (&[(0.6, 1e-3), (0.2, 2e-3)][..], 1),
        (&[(f32::NAN, 1e-3)][..], 0),
    ] {
        let err = ToolCylinder::new(a, b, profile).expect_err("bad t");
        assert!(
            matches!(err, ToolError::BadParameter { sample: s, .. } if s == sample),
            "{err:?}"
        );
    }
    let msg = ToolCylinder::new(a, b, &[(0.5, 1e-3), (0.5, 2e-3)])
        .expect_err("bad t")
        .to_string();
    assert!(msg.contains("sample 1") && msg.contains("t = 0.5"), "{msg}");

    assert_eq!(Instrument::new(Vec::new()), Err(ToolError::NoCylinders));
    assert!(matches!(
        Instrument::l_hook(Vec3::ZERO, Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)),
        Err(ToolError::BadPose { .. })
    ));
    assert!(matches!(
        Instrument::grasper(nan, Quat::IDENTITY, 0.5),
        Err(ToolError::BadPose { .. })
    ));
    for bad in [-0.1, 3.2, f32::NAN] {
        assert!(matches!(
            Instrument::grasper(Vec3::ZERO, Quat::IDENTITY, bad),
            Err(ToolError::BadOpening { .. })
        ));
    }
    assert_eq!(
        PointCloud::from_components(&[0.0; 3], &[0.0; 2], &[0.0; 3]).map(|c| c.len()),
        Err(ToolError::ComponentLengths { x: 3, y: 2, z: 3 })
    );
    let mut out = Vec::new();
    assert_eq!(
        tip_contacts(
            Vec3::ZERO,
            0.0,
            PointCloud::from_points(&[Vec3::ZERO]),
            &mut out
        ),
        Err(ToolError::BadRadius {
            sample: 0,
            value: 0.0
        })
    );

    // Forces: three contacts on vertices 0, 1 and 5.
    let tool = single(x_rod(0.02));
    let pts = [
        v(0.001, 0.001, 0.0),
        v(0.002, 0.001, 0.0),
        v(1.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(1.0, 0.0, 0.0),
        v(0.003, 0.001, 0.0),
    ];
    let hits = all_hits(&tool, &pts);
    assert_eq!(hits.len(), 3);
    let mut forces = vec![(9, Vec3::ONE)];
    let short = [1e-6; 4];
    assert_eq!(
        penalty_forces(&hits, VertexAreas::PerVertex(&short), 1e7, a, &mut forces),
        Err(ToolError::MissingArea { vertex: 5, len: 4 })
    );
    assert!(forces.is_empty(), "no partial output: {forces:?}");
    let negative = [1e-6, -1e-6, 1e-6, 1e-6, 1e-6, 1e-6];
    assert_eq!(
        penalty_forces(
            &hits,
            VertexAreas::PerVertex(&negative),
            1e7,
            a,
            &mut forces
        ),
        Err(ToolError::BadArea {
            vertex: 1,
            value: -1e-6
        })
    );
    assert!(matches!(
        penalty_forces(&hits, VertexAreas::Uniform(f32::NAN), 1e7, a, &mut forces),
        Err(ToolError::BadArea { vertex: 0, .. })
    ));
    for bad in [-1.0, f32::NAN] {
        assert!(matches!(
            penalty_forces(&hits, VertexAreas::Uniform(1e-6), bad, a, &mut forces),
            Err(ToolError::BadStiffness { .. })
        ));
    }
    // Non-finite tissue points never penetrate and stay out of the blocks' boxes.
    let odd = [
        nan,
        v(f32::INFINITY, 0.0, 0.0),
        v(0.01, 0.0, f32::NEG_INFINITY),
    ];
    assert!(all_hits(&tool, &odd).is_empty());
    let blocks = PointBlocks::new(PointCloud::from_points(&odd));
    assert!(
        tool.contacts(PointCloud::from_points(&odd), &blocks, &mut Vec::new())
            .is_ok()
    );
}
