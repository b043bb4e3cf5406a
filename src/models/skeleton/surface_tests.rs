use super::*;
use crate::models::skeleton::collision::{Hit, detect};
use crate::models::skeleton::vessel::VesselParams;

/// The nearest point of a triangle: inside the face, on an edge, at a corner; the weights
/// sum to one and rebuild the point from the corners.
#[test]
fn the_nearest_point_of_a_triangle_by_its_regions() {
    let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
    for (p, want) in [
        // Above the face: straight down onto it.
        (DVec3::new(0.25, 0.25, 0.7), DVec3::new(0.25, 0.25, 0.0)),
        // Beyond the edge from b to c: onto its middle.
        (DVec3::new(1.0, 1.0, 0.3), DVec3::new(0.5, 0.5, 0.0)),
        // Below the edge from a to b.
        (DVec3::new(0.6, -2.0, 0.0), DVec3::new(0.6, 0.0, 0.0)),
        // Out past the corners.
        (DVec3::new(-1.0, -1.0, 1.0), a),
        (DVec3::new(3.0, -0.5, 0.0), b),
        (DVec3::new(-0.2, 4.0, -1.0), c),
    ] {
        let (q, w) = nearest_on_triangle(p, a, b, c);
        assert!(q.distance(want) < 1e-12, "{p}: {q}, expected {want}");
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{w:?}");
        let rebuilt = a * w[0] + b * w[1] + c * w[2];
        assert!(rebuilt.distance(q) < 1e-12, "{w:?}");
        assert!(w.iter().all(|&x| x >= -1e-12), "{w:?}");
    }
}

/// A vessel of the scenario's size, and a wire ball (0.9 mm) pressed into the wall halfway
/// between four wall balls: the balls (2 mm, 3.5 mm apart around the ring) leave it room to
/// pass, the surface does not, and pushes it back into the lumen, also from past the wall's
/// central surface; the wall takes the opposite of the force on the ball, spread over the
/// triangle's corners.
#[test]
fn a_thin_wire_meets_the_wall_between_its_balls() {
    let vessel = Vessel::new(&VesselParams::default());
    let surface = WallSurface::new(&vessel);
    let trunk = &vessel.tubes[0];
    let (r0, r1) = (&trunk.rings[2], &trunk.rings[3]);
    let quad = [r0[0], r0[1], r1[0], r1[1]].map(|b| b.expect("a whole ring"));
    let centre = quad
        .iter()
        .map(|&b| vessel.balls.x[b as usize])
        .sum::<DVec3>()
        / 4.0;
    // 0.4 mm in from the wall's central surface, towards the axis.
    let on_axis = trunk.start + trunk.dir * trunk.along(centre);
    let out = (centre - on_axis).normalize();
    let mut wire = Balls::default();
    wire.push(centre - out * 0.0004, 2e-5, 0.00045);
    let mut balls_hit: Vec<Hit> = Vec::new();
    detect(&wire, 0, &vessel, &[], &mut balls_hit);
    assert!(
        balls_hit.is_empty(),
        "the wall's balls leave a gap: {balls_hit:?}"
    );
    let mut candidates = Vec::new();
    surface.candidates(&wire, 0, &vessel, &[], 0.002, &mut candidates);
    let mut hits = Vec::new();
    surface.narrow(&candidates, &wire, &vessel, &mut hits);
    assert_eq!(hits.len(), 1, "one hit for one ball: {hits:?}");
    let h = hits[0];
    // Half the wall (1 mm) and the ball's radius, less 0.4 mm: 1.05 mm deep, the normal
    // pointing into the vessel.
    assert!((h.depth_m - 0.00105).abs() < 5e-5, "{h:?}");
    assert!(h.normal.dot(out) < -0.99, "{h:?}");
    // 0.4 mm past the central surface: 1.85 mm deep, still pushed in.
    let mut past = wire.clone();
    past.x[0] = centre + out * 0.0004;
    let mut past_hits = Vec::new();
    surface.candidates(&past, 0, &vessel, &[], 0.002, &mut candidates);
    surface.narrow(&candidates, &past, &vessel, &mut past_hits);
    assert_eq!(past_hits.len(), 1, "{past_hits:?}");
    assert!(
        (past_hits[0].depth_m - 0.00185).abs() < 5e-5,
        "{past_hits:?}"
    );
    assert!(past_hits[0].normal.dot(out) < -0.99, "{past_hits:?}");
    let law = ContactLaw {
        stiffness_n_per_m: 45.0,
        damping_n_s_per_m: 0.0,
        preload_n: 0.045,
        friction: 0.05,
    };
    let mut on_wire = vec![DVec3::ZERO];
    let mut on_wall = vec![DVec3::ZERO; vessel.balls.len()];
    surface.forces(&hits, &law, &wire, &vessel, &mut on_wire, &mut on_wall);
    let want = law.stiffness_n_per_m * h.depth_m + law.preload_n;
    assert!((on_wire[0].length() - want).abs() < 1e-12, "{}", on_wire[0]);
    let wall_total: DVec3 = on_wall.iter().sum();
    assert!((wall_total + on_wire[0]).length() < 1e-15, "{wall_total}");
    let loaded = on_wall.iter().filter(|f| **f != DVec3::ZERO).count();
    assert_eq!(loaded, 3, "the triangle's corners");
}

/// Holes take their triangles out of the candidates.
#[test]
fn punctured_wall_balls_leave_no_surface() {
    let vessel = Vessel::new(&VesselParams::default());
    let surface = WallSurface::new(&vessel);
    let trunk = &vessel.tubes[0];
    let b = trunk.rings[2][0].expect("a whole ring") as usize;
    let on_axis = trunk.start + trunk.dir * trunk.along(vessel.balls.x[b]);
    let inward = (on_axis - vessel.balls.x[b]).normalize();
    let mut wire = Balls::default();
    wire.push(vessel.balls.x[b] + inward * 0.001, 2e-5, 0.00045);
    let mut candidates = Vec::new();
    surface.candidates(&wire, 0, &vessel, &[], 0.002, &mut candidates);
    assert!(!candidates.is_empty());
    let mut holes = vec![false; vessel.balls.len()];
    holes[b] = true;
    surface.candidates(&wire, 0, &vessel, &holes, 0.002, &mut candidates);
    for &(_, t) in &candidates {
        assert!(!surface.triangles[t as usize].contains(&(b as u32)));
    }
}
