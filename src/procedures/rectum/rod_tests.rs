//! The skinned rod (`models::cosserat::skinned`) on the rectum's geometry: its skin, contact,
//! grasps, determinism and checkpoints, and its parameters refused by name.

use crate::collision::{Instrument, ToolCylinder};
use crate::mesh::{TriMesh, TubeSpec, tube};
use crate::models::cosserat::skin::{RodPose, Selection, Skin};
use crate::models::cosserat::skinned::*;
use crate::procedures::rectum::anatomy::{AnatomyParams, medial_axis};
use crate::sim::{Contact, ContactKind, Hand, ModelOutput, TissueModel, on_threads};
use glam::{DMat3, DQuat, DVec3, Quat, Vec3};

/// The anatomy's medial axis (the sacral curve) and a tube mesh of the rectum's radius on it.
fn sacral() -> (Vec<Vec3>, TriMesh) {
    let a = AnatomyParams::default();
    let axis = medial_axis(&a, 256);
    let surface = tube(&TubeSpec {
        path: axis.clone(),
        radius_m: a.rectum_radius_m,
        segments: 48,
        rings: 76,
    });
    (axis, surface)
}

fn sacral_rod(params: SkinnedRodParams) -> SkinnedRod {
    let (axis, surface) = sacral();
    SkinnedRod::new(&axis, &surface, params).expect("a rod")
}

/// A straight 15 cm rod along +x from the origin.
fn straight_rod(elements: usize) -> SkinnedRod {
    let axis = [Vec3::ZERO, Vec3::new(0.15, 0.0, 0.0)];
    let surface = tube(&TubeSpec {
        path: axis.to_vec(),
        radius_m: 0.02,
        segments: 24,
        rings: 16,
    });
    let params = SkinnedRodParams {
        elements,
        ..SkinnedRodParams::default()
    };
    SkinnedRod::new(&axis, &surface, params).expect("a rod")
}

fn place_all(skin: &Skin, pose: RodPose<'_>) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; skin.len()];
    skin.place_pose(pose, Selection::All, &mut out)
        .expect("placed");
    out
}

/// Bends the rod by `force` (N) on its middle node for `steps` steps of 1 ms.
fn bend(rod: &mut SkinnedRod, force: DVec3, steps: usize) {
    let mid = rod.rod().elements() / 2;
    for _ in 0..steps {
        rod.add_node_force(mid, force);
        rod.advance(1e-3);
    }
}

#[test]
fn the_skin_at_rest_puts_every_point_where_it_was_bound() {
    let rod = sacral_rod(SkinnedRodParams::default());
    let surface = rod.surface().clone();
    let placed = place_all(rod.skin(), RodPose::of(rod.rod()));
    let worst = placed
        .iter()
        .zip(&surface.positions)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0f32, f32::max);
    eprintln!(
        "skin at rest: worst error {worst:.3e} m over {} points",
        placed.len()
    );
    assert!(worst < 1e-6, "{worst}");
    // A range and a list place the same points as the whole set.
    let mut part = vec![Vec3::ZERO; 100];
    rod.skin()
        .place(&rod, Selection::Range(1000..1100), &mut part)
        .expect("range");
    assert_eq!(part[..], placed[1000..1100]);
    let list: Vec<u32> = vec![7, 3, 2000, 3];
    let mut some = vec![Vec3::ZERO; list.len()];
    rod.skin()
        .place(&rod, Selection::List(&list), &mut some)
        .expect("list");
    for (k, &i) in list.iter().enumerate() {
        assert_eq!(some[k], placed[i as usize]);
    }
    // Refusals: an index past the end, an output of the wrong length, a foreign pose.
    let n = rod.skin().len();
    assert_eq!(
        rod.skin()
            .place(&rod, Selection::List(&[n as u32]), &mut some[..1]),
        Err(RodModelError::NoSuchPoint {
            index: n,
            points: n
        })
    );
    assert!(matches!(
        rod.skin().place(&rod, Selection::All, &mut some),
        Err(RodModelError::OutputLength { .. })
    ));
    let other = straight_rod(12);
    assert!(matches!(
        rod.skin().place(&other, Selection::Range(0..4), &mut some),
        Err(RodModelError::PoseMismatch { elements: 30, .. })
    ));
}

#[test]
fn a_rigid_motion_of_the_rod_moves_every_skinned_point_rigidly() {
    let mut rod = sacral_rod(SkinnedRodParams::default());
    // Bent first, so that the frames differ from element to element.
    bend(&mut rod, DVec3::new(0.0, 0.0, 2.0), 300);
    let bent = place_all(rod.skin(), RodPose::of(rod.rod()));
    let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let shift = DVec3::new(0.05, -0.02, 0.1);
    let positions: Vec<DVec3> = rod
        .rod()
        .positions()
        .iter()
        .map(|&x| q * x + shift)
        .collect();
    let frames: Vec<DMat3> = rod
        .rod()
        .frames()
        .iter()
        .map(|&r| DMat3::from_quat(q) * r)
        .collect();
    let moved = place_all(
        rod.skin(),
        RodPose {
            positions: &positions,
            frames: &frames,
        },
    );
    let worst = bent
        .iter()
        .zip(&moved)
        .map(|(b, m)| (q * b.as_dvec3() + shift).distance(m.as_dvec3()))
        .fold(0.0f64, f64::max);
    assert!(worst < 1e-6, "{worst} m from the rigidly moved point");
    // Distances between points (pairs half the set apart: centimetres) are kept.
    let half = bent.len() / 2;
    let mut rel = 0.0f64;
    for i in (0..half).step_by(7) {
        let before = bent[i].as_dvec3().distance(bent[i + half].as_dvec3());
        let after = moved[i].as_dvec3().distance(moved[i + half].as_dvec3());
        if before > 0.01 {
            rel = rel.max((after / before - 1.0).abs());
        }
    }
    eprintln!("rigid motion: worst point error {worst:.3e} m, worst distance change {rel:.3e}");
    assert!(rel < 1e-6, "{rel}");
}

#[test]
fn a_bent_rod_carries_the_skin_across_element_boundaries_without_a_seam() {
    let mut rod = sacral_rod(SkinnedRodParams::default());
    let mid = rod.rod().elements() / 2;
    let c = rod.rod().positions()[mid];
    let tangent = (rod.rod().positions()[mid + 1] - rod.rod().positions()[mid - 1]).normalize();
    // Lines of points 0.25 mm apart along the surface across node `mid` (the boundary of
    // elements mid - 1 and mid), on the sides towards and away from the bend (+z, -z) and on
    // the anterior side.
    let sides = [DVec3::Z, DVec3::NEG_Z, DVec3::Y];
    let mut points = Vec::new();
    for side in sides {
        for k in -16..=16 {
            points.push((c + tangent * (2.5e-4 * f64::from(k)) + side * 0.02).as_vec3());
        }
    }
    let skin = Skin::bind(&rod, &points);
    bend(&mut rod, DVec3::new(0.0, 0.0, 1.0), 600);
    let mut placed = vec![Vec3::ZERO; points.len()];
    skin.place(&rod, Selection::All, &mut placed)
        .expect("placed");
    let r = rod.rod().frames();
    let joint = crate::models::cosserat::so3::log(r[mid - 1].transpose() * r[mid]).length();
    let lateral = (rod.rod().positions()[mid] - c).z;
    let mut worst = 0.0f32;
    for line in 0..sides.len() {
        for k in 0..32 {
            let i = line * 33 + k;
            let ratio = placed[i].distance(placed[i + 1]) / points[i].distance(points[i + 1]);
            worst = worst.max(ratio);
        }
    }
    // Element frames held constant over each element would open a gap of about r * joint
    // at the boundary, against 0.25 mm between the points.
    let seam = 0.02 * joint;
    eprintln!(
        "bend: mid node moved {lateral:.4} m, joint angle {joint:.4} rad (a seam without \
         blending: {:.3} mm); worst neighbour distance ratio {worst:.4}",
        seam * 1e3
    );
    assert!(
        joint > 0.005,
        "the bend is too slight to show a seam: {joint} rad"
    );
    assert!(worst < 1.1, "{worst}");
}

/// For a cylinder of radius `rt` crossing a straight rod of radius `rs` at right angles, its
/// axis `h` from the rod's: `depth(s) = R - sqrt(s^2 + h^2)` with `R = rs + rt`, over
/// `|s| < a = sqrt(R^2 - h^2)`. Returns `integral depth ds = a R - h^2 ln((a + R) / h)` and the
/// integral of its component across both axes, `depth h / sqrt(s^2 + h^2)`:
/// `2 h (R asinh(a / h) - a)`.
fn crossing_integrals(rs: f64, rt: f64, h: f64) -> (f64, f64) {
    let big = rs + rt;
    let a = (big * big - h * h).sqrt();
    (
        a * big - h * h * ((a + big) / h).ln(),
        2.0 * h * (big * (a / h).asinh() - a),
    )
}

#[test]
fn a_pressed_cylinder_pushes_with_k_times_the_integral_of_depth_at_any_resolution() {
    let (rs, rt, depth) = (0.02, 0.0025, 0.005);
    let h = rs + rt - depth;
    // Across the rod at x = 76.3 mm (off the nodes), a long shaft along z.
    let x0 = 0.0763;
    let tool = Instrument::new(vec![
        ToolCylinder::constant(
            Vec3::new(x0 as f32, h as f32, -0.1),
            Vec3::new(x0 as f32, h as f32, 0.1),
            rt as f32,
        )
        .expect("a cylinder"),
    ])
    .expect("a tool");
    let k = SkinnedRodParams::default().contact_stiffness_pa;
    let (depth_integral, across_integral) = crossing_integrals(rs, rt, h);
    let (want, want_down) = (k * depth_integral, k * across_integral);
    let mut totals = Vec::new();
    for n in [30, 60] {
        let mut rod = straight_rod(n);
        let reaction = rod.press(&tool, 1);
        let f = rod.pending_forces();
        let sum: DVec3 = f.iter().copied().sum();
        let magnitude: f64 = f.iter().map(|f| f.length()).sum();
        assert!(
            (reaction.as_dvec3() + sum).length() < 1e-6 * sum.length(),
            "{reaction} vs {sum}"
        );
        // Down (the tool is above), nothing along the tool.
        assert!(sum.y < 0.0 && sum.z.abs() < 1e-12, "{sum}");
        let touching = f.iter().filter(|f| f.length() > 0.0).count();
        eprintln!(
            "press at {n} elements, {touching} spheres touching: sum of |f_i| {magnitude:.4} N vs \
             k * integral of depth {want:.4} N ({:+.2} %); net force down {:.4} N vs k * \
             integral of depth h / dist {want_down:.4} N ({:+.2} %)",
            (magnitude / want - 1.0) * 100.0,
            -sum.y,
            (-sum.y / want_down - 1.0) * 100.0
        );
        assert!((magnitude / want - 1.0).abs() < 0.03);
        assert!((-sum.y / want_down - 1.0).abs() < 0.03);
        totals.push((magnitude, -sum.y));
    }
    assert!((totals[0].0 / totals[1].0 - 1.0).abs() < 0.02, "{totals:?}");
    assert!((totals[0].1 / totals[1].1 - 1.0).abs() < 0.02, "{totals:?}");
}

#[test]
fn a_flat_tool_end_pushes_with_its_face_and_its_rim() {
    // A vertical shaft (radius 2.5 mm) whose flat end is 19 mm above node 15 of a straight
    // rod (nodes 5 mm apart): 1 mm into node 15's sphere through the face; node 14's centre
    // is 5 mm aside, outside the face, and meets the rim at sqrt(19^2 + 2.5^2) mm.
    let mut rod = straight_rod(30);
    let x15 = rod.rod().positions()[15];
    let end = x15 + DVec3::new(0.0, 0.019, 0.0);
    let tool = Instrument::new(vec![
        ToolCylinder::constant(
            (end + DVec3::new(0.0, 0.3, 0.0)).as_vec3(),
            end.as_vec3(),
            0.0025,
        )
        .expect("a cylinder"),
    ])
    .expect("a tool");
    rod.press(&tool, 0);
    let k = SkinnedRodParams::default().contact_stiffness_pa;
    let l = rod.length_shares()[15];
    let f = rod.pending_forces();
    let face = DVec3::new(0.0, -k * 0.001 * l, 0.0);
    assert!((f[15] - face).length() < 1e-6 * face.length(), "{}", f[15]);
    let rim_dist = (0.019f64.powi(2) + 0.0025f64.powi(2)).sqrt();
    let rim_point = end + DVec3::new(-0.0025, 0.0, 0.0);
    let dir = (rod.rod().positions()[14] - rim_point).normalize();
    let rim = dir * (k * (0.02 - rim_dist) * rod.length_shares()[14]);
    assert!(
        (f[14] - rim).length() < 1e-6 * rim.length(),
        "{} vs {rim}",
        f[14]
    );
    // Node 13 is 10 mm aside: sqrt(19^2 + 7.5^2) = 20.4 mm, out of reach.
    assert_eq!(f[13], DVec3::ZERO);
}

#[test]
fn a_grasp_lifts_the_mid_surface_and_the_clamped_ends_stay() {
    let mut rod = sacral_rod(SkinnedRodParams::default());
    let n = rod.rod().elements();
    let start: Vec<DVec3> = rod.rod().positions().to_vec();
    let mid = n / 2;
    let up = rod.rod().frames()[mid].x_axis;
    let surface = (start[mid] + up * 0.02).as_vec3();
    assert!(
        !rod.grasp(0, (start[mid] + up * 0.026).as_vec3()),
        "out of reach"
    );
    assert!(rod.grasp(0, (start[mid] + up * 0.021).as_vec3()));
    let held0 = rod.held_point(0).expect("held");
    assert!(held0.distance(surface) < 1e-3, "{held0} vs {surface}");
    let mut jaw = held0;
    for k in 1..=500 {
        jaw = held0 + Vec3::Y * (0.01 * k as f32 / 500.0);
        rod.hold(0, jaw);
        rod.advance(1e-3);
    }
    let held = rod.held_point(0).expect("held");
    let gap = held.distance(jaw);
    let lifted = rod.rod().positions()[mid] - start[mid];
    let pull = rod.hold(0, jaw);
    eprintln!(
        "grasp: held point {:.3} mm from the jaw after a 10 mm lift, mid node up {:.3} mm, \
         pull {:.3} N",
        gap * 1e3,
        lifted.y * 1e3,
        -pull.y
    );
    assert!(gap < 0.002, "{gap} m");
    assert!(lifted.y > 0.007, "{lifted}");
    for i in [0, n] {
        assert!(rod.rod().positions()[i].distance(start[i]) < 1e-9);
    }
    rod.release(0);
    assert_eq!(rod.held_point(0), None);
    for _ in 0..500 {
        rod.advance(1e-3);
    }
    let back = rod.rod().positions()[mid].distance(start[mid]);
    eprintln!(
        "released: mid node {:.3} mm from its start after 0.5 s",
        back * 1e3
    );
    assert!(back < 0.2 * lifted.length(), "{back}");
}

/// 200 world steps of 2 ms: a grasp on the mid surface pulled up and sideways, a tip pressing
/// near one end, renders between.
fn world_run(rod: &mut SkinnedRod) -> (u64, Vec<Vec3>, Vec<(Hand, Vec3)>) {
    let mid = rod.rod().elements() / 2;
    let top = (rod.rod().positions()[mid] + rod.rod().frames()[mid].x_axis * 0.02).as_vec3();
    let tip0 = rod.rod().positions()[5].as_vec3() + Vec3::Y * 0.021;
    let mut out = ModelOutput::default();
    let mut last = Vec::new();
    for step in 0..200 {
        let s = step as f32 / 200.0;
        let contacts = [
            Contact {
                tool: Hand::Left,
                point: top + Vec3::new(0.0, 0.008, 0.004) * s,
                normal: Vec3::Y,
                kind: ContactKind::Grasp {
                    rotation: Quat::IDENTITY,
                    radius_m: 0.004,
                },
            },
            Contact {
                tool: Hand::Right,
                point: tip0 - Vec3::Y * (0.004 * s),
                normal: Vec3::Y,
                kind: ContactKind::Sphere { radius_m: 0.0025 },
            },
        ];
        out.clear();
        rod.step(0.002, &contacts, &mut out);
        if step % 50 == 49 {
            last = rod.render_mesh().positions;
        }
    }
    (rod.state_hash(), last, out.reactions.clone())
}

#[test]
fn one_and_two_threads_step_to_the_same_bits_and_checkpoints_restore_exactly() {
    let runs: Vec<_> = [1, 2]
        .into_iter()
        .map(|threads| {
            on_threads(threads, || {
                let mut rod = sacral_rod(SkinnedRodParams::default());
                world_run(&mut rod)
            })
        })
        .collect();
    assert_eq!(runs[0].0, runs[1].0);
    assert_eq!(runs[0].1, runs[1].1);
    let reactions = &runs[0].2;
    eprintln!("world run reactions: {reactions:?}");
    // Both tools feel the rod: the grasp pulls the left jaw down, the tip is pushed up.
    let left = reactions.iter().find(|r| r.0 == Hand::Left).expect("left");
    let right = reactions
        .iter()
        .find(|r| r.0 == Hand::Right)
        .expect("right");
    assert!(left.1.y < 0.0 && right.1.y > 0.0, "{reactions:?}");
    // Checkpoint, go on, restore: the same bits as at the checkpoint.
    let mut rod = sacral_rod(SkinnedRodParams::default());
    world_run(&mut rod);
    assert!(rod.state_is_finite());
    rod.checkpoint();
    let saved = rod.state_hash();
    let saved_nodes: Vec<Vec3> = (0..31).filter_map(|i| rod.point(i)).collect();
    let mut out = ModelOutput::default();
    rod.apply_point_forces(&[(15, Vec3::new(0.0, 1.0, 0.0))]);
    for _ in 0..50 {
        rod.step(0.002, &[], &mut out);
    }
    // The grasp ended with its contacts: released, with an event.
    assert!(rod.grip(0).is_none());
    assert!(
        out.events
            .iter()
            .any(|e| matches!(e, crate::sim::EventKind::Release { .. }))
    );
    assert_ne!(rod.state_hash(), saved);
    rod.restore();
    assert_eq!(rod.state_hash(), saved);
    let nodes: Vec<Vec3> = (0..31).filter_map(|i| rod.point(i)).collect();
    assert_eq!(nodes, saved_nodes);
    assert!(rod.grip(0).is_some(), "the checkpoint held the grasp");
}

#[test]
fn the_model_reports_its_sizes_collider_and_surface() {
    let mut rod = sacral_rod(SkinnedRodParams::default());
    let sizes = rod.sizes();
    assert_eq!(sizes.vertices, 31);
    assert_eq!(sizes.triangles, rod.surface().triangles.len());
    assert_eq!((rod.name(), rod.kind()), ("rod", "cosserat_rod"));
    // Down the first director onto the mid node: the tube's anterior side, 2 cm out.
    let mid = rod.rod().positions()[15].as_vec3();
    let d1 = rod.rod().frames()[15].x_axis.as_vec3();
    let hit = rod
        .collider()
        .cast_ray(mid + d1 * 0.1, -d1, 1.0)
        .expect("a hit");
    assert!((hit.distance_m - 0.08).abs() < 2e-4, "{}", hit.distance_m);
    let snap = rod.render_mesh();
    assert_eq!(snap.positions.len(), rod.surface().positions.len());
    assert_eq!(snap.indices.len(), 3 * sizes.triangles);
    assert_eq!(snap.regions.len(), sizes.triangles);
    // Normals point away from the axis on the tube's side.
    let side = rod.surface().positions.len() / 2;
    let axis_point = rod.sphere_centres()[15];
    let outward = (snap.positions[side] - axis_point).normalize();
    assert!(snap.normals[side].dot(outward) > 0.9);
}

#[test]
fn a_grasp_lifting_the_rod_is_felt_as_its_spring() {
    // The rod's step rate is `vesalius bench rectum`'s line; here, what the pull does.
    let mut rod = sacral_rod(SkinnedRodParams::default());
    let k_g = rod.params().grasp_stiffness_n_per_m;
    let mid = rod.rod().elements() / 2;
    let top = (rod.rod().positions()[mid] + rod.rod().frames()[mid].x_axis * 0.02).as_vec3();
    assert!(rod.grasp(0, top));
    let start = rod.held_point(0).expect("held");
    // The jaw rises 1 cm over 2 s, then holds still for 1 s so the rod settles.
    let steps = 2000;
    let jaw = top + Vec3::Y * 0.01;
    let mut felt = [None; 2];
    for k in 0..3000 {
        let f = (k.min(steps) as f32) / steps as f32;
        rod.hold(0, top + Vec3::Y * (0.01 * f));
        felt = rod.advance(1e-3);
    }
    assert!(rod.state_is_finite());
    let held = rod.held_point(0).expect("still held");
    // The held point followed the jaw up, but not past it: the rod pulls back.
    assert!(held.y > start.y + 1e-4, "{start} -> {held}");
    assert!(held.y < jaw.y, "{held} above the jaw {jaw}");
    // At rest, the hand feels the grasp spring: -k_g (jaw - held), pulling it down.
    let reaction = felt[0].expect("the hand holds");
    let spring = -(jaw - held) * k_g as f32;
    assert!(reaction.y < 0.0, "{reaction}");
    assert!(
        (reaction - spring).length() <= 0.05 * spring.length() + 1e-4,
        "{reaction} vs {spring}"
    );
    // The other hand holds nothing and feels nothing.
    assert_eq!(felt[1], None);
}

#[test]
fn bad_parameters_and_inputs_are_refused_by_name() {
    let d = SkinnedRodParams::default();
    assert_eq!(d.validate(), Ok(()));
    let field = |p: SkinnedRodParams| match p.validate() {
        Err(RodModelError::BadParameter { field, .. }) => field,
        other => panic!("{other:?}"),
    };
    assert_eq!(field(SkinnedRodParams { elements: 1, ..d }), "elements");
    assert_eq!(
        field(SkinnedRodParams {
            youngs_modulus_pa: -1.0,
            ..d
        }),
        "youngs_modulus_pa"
    );
    assert_eq!(
        field(SkinnedRodParams {
            poisson_ratio: 0.5,
            ..d
        }),
        "poisson_ratio"
    );
    assert_eq!(field(SkinnedRodParams { wall_m: 0.03, ..d }), "wall_m");
    assert_eq!(
        field(SkinnedRodParams {
            grasp_stiffness_n_per_m: f64::NAN,
            ..d
        }),
        "grasp_stiffness_n_per_m"
    );
    assert_eq!(
        field(SkinnedRodParams {
            gravity_m_per_s2: DVec3::new(0.0, f64::INFINITY, 0.0),
            ..d
        }),
        "gravity_m_per_s2"
    );
    let msg = SkinnedRodParams {
        contact_stiffness_pa: -5.0,
        ..d
    }
    .validate()
    .map_err(|e| e.to_string());
    assert_eq!(
        msg,
        Err(
            "rectum rod parameter `contact_stiffness_pa` is -5; expected a finite value >= 0"
                .to_string()
        )
    );
    let (axis, surface) = sacral();
    assert!(matches!(
        SkinnedRod::new(&axis, &surface, SkinnedRodParams { elements: 0, ..d }),
        Err(RodModelError::BadParameter {
            field: "elements",
            ..
        })
    ));
    assert!(matches!(
        SkinnedRod::new(&axis[..1], &surface, d),
        Err(RodModelError::ShortAxis { points: 1, .. })
    ));
    assert!(matches!(
        SkinnedRod::new(&[Vec3::ONE, Vec3::ONE], &surface, d),
        Err(RodModelError::ShortAxis { points: 2, .. })
    ));
    let mut bent = axis.clone();
    bent[7].y = f32::NAN;
    assert!(matches!(
        SkinnedRod::new(&bent, &surface, d),
        Err(RodModelError::NonFinite {
            what: "axis point",
            index: 7,
            ..
        })
    ));
    let mut holed = surface.clone();
    holed.positions[3] = Vec3::INFINITY;
    assert!(matches!(
        SkinnedRod::new(&axis, &holed, d),
        Err(RodModelError::NonFinite {
            what: "surface vertex",
            index: 3,
            ..
        })
    ));
}

#[test]
fn the_skin_places_the_membranes_first_layer_alike_on_one_and_two_threads() {
    let anatomy = crate::procedures::rectum::Anatomy::generate(AnatomyParams::default())
        .expect("the anatomy");
    let axis: Vec<Vec3> = anatomy.axis.iter().map(|f| f.point).collect();
    let mut rod =
        SkinnedRod::new(&axis, &anatomy.rectum, SkinnedRodParams::default()).expect("a rod");
    let layer = &anatomy.membrane.positions[0];
    assert_eq!(layer.len(), 240_000);
    let t0 = std::time::Instant::now();
    let skin = Skin::bind(&rod, layer);
    let bind_s = t0.elapsed().as_secs_f64();
    let rest = place_all(&skin, RodPose::of(rod.rod()));
    let worst = rest
        .iter()
        .zip(layer)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "{worst}");
    bend(&mut rod, DVec3::new(0.0, 1.0, 1.0), 200);
    // A subset: every fifth row, as a list.
    let cols = anatomy.membrane.cols;
    let list: Vec<u32> = (0..anatomy.membrane.rows)
        .step_by(5)
        .flat_map(|i| (0..cols).map(move |j| (i * cols + j) as u32))
        .collect();
    let timed = |threads: usize, which: Selection<'_>, len: usize| {
        on_threads(threads, || {
            let mut out = vec![Vec3::ZERO; len];
            let mut best = f64::INFINITY;
            for _ in 0..20 {
                let t = std::time::Instant::now();
                skin.place(&rod, which.clone(), &mut out).expect("placed");
                best = best.min(t.elapsed().as_secs_f64());
            }
            (best, out)
        })
    };
    let (one_s, one) = timed(1, Selection::All, skin.len());
    let (two_s, two) = timed(2, Selection::All, skin.len());
    assert_eq!(one, two);
    let (list1_s, some) = timed(1, Selection::List(&list), list.len());
    let (list2_s, some2) = timed(2, Selection::List(&list), list.len());
    assert_eq!(some, some2);
    for (k, &i) in list.iter().enumerate() {
        assert_eq!(some[k], one[i as usize]);
    }
    eprintln!(
        "skin of 240,000 points: bound in {:.1} ms; placed in {:.2} ms on 1 thread, {:.2} ms \
         on 2 (best of 20); {} listed points in {:.2} ms on 1, {:.2} ms on 2",
        bind_s * 1e3,
        one_s * 1e3,
        two_s * 1e3,
        list.len(),
        list1_s * 1e3,
        list2_s * 1e3
    );
}

#[test]
fn a_grasp_holds_steadily_at_the_scenarios_longest_step() {
    // The nephrectomy's 4 ms step: the rod takes substeps (module docs), so the grasp spring
    // stays stable and holds as at 1 ms.
    let mut rod = sacral_rod(SkinnedRodParams::default());
    let mid = rod.rod().elements() / 2;
    let top = (rod.rod().positions()[mid] + rod.rod().frames()[mid].x_axis * 0.02).as_vec3();
    let mut out = ModelOutput::default();
    let grasp = |point: Vec3| Contact {
        tool: Hand::Right,
        point,
        normal: Vec3::Y,
        kind: ContactKind::Grasp {
            rotation: Quat::IDENTITY,
            radius_m: 0.002,
        },
    };
    let jaw = top + Vec3::Y * 0.01;
    for k in 1..=175 {
        let point = top + Vec3::Y * (0.01 * (k.min(125) as f32 / 125.0));
        out.clear();
        rod.step(0.004, &[grasp(point)], &mut out);
    }
    let gap = rod.held_point(1).expect("held").distance(jaw);
    let speed = rod
        .rod()
        .velocities()
        .iter()
        .map(|v| v.length())
        .fold(0.0, f64::max);
    eprintln!(
        "4 ms steps ({:.0} us substeps): held point {:.3} mm from the jaw, fastest node \
         {speed:.2e} m/s",
        rod.substep_s() * 1e6,
        gap * 1e3
    );
    assert!(rod.state_is_finite());
    assert!(gap < 0.002, "{gap}");
    assert!(speed < 1e-3, "still moving at {speed} m/s");
    let pull = out
        .reactions
        .iter()
        .find(|r| r.0 == Hand::Right)
        .expect("a reaction");
    assert!(pull.1.y < -1.0, "{pull:?}");
}

#[test]
fn a_surface_force_is_statically_the_force_at_its_point() {
    // A force at a surface point splits onto the element's nodes with a couple: the sum is
    // the force and the moment about any point is the force's moment at the surface point.
    let mut rod = straight_rod(10);
    let (e, t) = (4usize, 0.3f64);
    let x = rod.rod().positions().to_vec();
    let axis = x[e] + (x[e + 1] - x[e]) * t;
    let lever = DVec3::new(0.0, 0.02, 0.005);
    let f = DVec3::new(0.3, -1.2, 0.7);
    rod.add_surface_force(e, t, lever, f, 50.0);
    let sum: DVec3 = rod.pending_forces().iter().copied().sum();
    assert!((sum - f).length() < 1e-12, "{sum} vs {f}");
    let about = DVec3::new(0.1, -0.3, 0.2);
    let moment: DVec3 = rod
        .pending_forces()
        .iter()
        .zip(&x)
        .map(|(g, p)| (*p - about).cross(*g))
        .sum::<DVec3>()
        + rod.pending_couples().iter().copied().sum::<DVec3>();
    let expected = (axis + lever - about).cross(f);
    assert!(
        (moment - expected).length() < 1e-12,
        "{moment} vs {expected}"
    );
    // The stiffness is shared as the force is.
    assert!(
        (rod.pending_stiffness()[e] - 35.0).abs() < 1e-12
            && (rod.pending_stiffness()[e + 1] - 15.0).abs() < 1e-12
    );
    // A bad element or value is ignored.
    rod.add_surface_force(99, t, lever, f, 1.0);
    rod.add_surface_force(e, t, lever, DVec3::NAN, 1.0);
    let again: DVec3 = rod.pending_forces().iter().copied().sum();
    assert_eq!(again, sum);
}

#[test]
fn a_stiff_given_load_does_not_ring() {
    // A load that pulls the mid-node back to where it started with a stiffness far above
    // the rod's, given as a force computed before each step (one step late): with its
    // stiffness declared the rod settles; without, it rings and grows.
    let run = |declared: bool| {
        let mut rod = straight_rod(10);
        let rest = rod.rod().positions()[5];
        let k = 2e5;
        let mut track = Vec::new();
        for _ in 0..400 {
            let x = rod.rod().positions()[5];
            let pull = DVec3::new(0.0, -0.5, 0.0) + (rest - x) * k;
            let stiffness = if declared { k } else { 0.0 };
            rod.add_surface_force(5, 0.0, DVec3::ZERO, pull, stiffness);
            rod.advance(1e-3);
            track.push(rod.rod().positions()[5]);
        }
        let last = track[track.len() - 1];
        let swing = track[300..]
            .iter()
            .map(|p| (*p - last).length())
            .fold(0.0f64, f64::max);
        (rod.rod().is_finite(), swing, (last - rest).length())
    };
    let (finite, swing, off) = run(true);
    // At rest within 0.1 um over the last 100 ms, a few um from where it started (the load's
    // 0.5 N over 2e5 N/m is 2.5 um; the rod's weight adds its sag).
    assert!(
        finite && swing < 1e-7 && off < 1e-5,
        "declared: swing {swing}, off {off}"
    );
    let (finite, swing, _) = run(false);
    assert!(!finite || swing > 1e-5, "undeclared: swing {swing}");
}
