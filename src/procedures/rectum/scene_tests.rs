use super::*;
use crate::collision::{Instrument, PointCloud};
use crate::procedures::rectum::regions::RegionKind;
use crate::procedures::rectum::{Anatomy, AnatomyParams};

/// A coarse anatomy (60 rows x 48 columns) and its scene.
fn scene() -> RectumScene {
    let a = Anatomy::generate(AnatomyParams {
        rows: 60,
        cols: 48,
        ..AnatomyParams::default()
    })
    .expect("anatomy");
    RectumScene::new(&a, SceneParams::default()).expect("scene")
}

/// Forward (-Z) pointing down (-Y), the hook (+Y) pointing along -Z.
fn from_above() -> Quat {
    Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
}

#[test]
fn lifting_the_rectum_carries_layer_zero_and_leaves_the_pelvis() {
    let mut s = scene();
    let (rows, cols) = (s.membrane().rows(), s.membrane().cols());
    let mid = rows / 2;
    let start: Vec<Vec3> = (0..s.membrane().len())
        .map(|n| s.membrane().position(n))
        .collect();
    // The grasper closes on the top of the rectum (column 0 faces +y) and lifts 6 mm in 0.3 s.
    let top = start[s.membrane().node(0, mid, 0)];
    let mut tools = ToolState {
        hook: None,
        cutting: false,
        grasper: Some((top, from_above(), true)),
        grasper_right: None,
    };
    for k in 0..300 {
        let lift = 0.006 * (k as f32 / 299.0);
        tools.grasper = Some((top + Vec3::Y * lift, from_above(), true));
        s.step(1e-3, &tools, 0, &mut Vec::new());
    }
    s.place_everything();
    let moved = |l: usize, i: usize, j: usize| {
        let n = s.membrane().node(l, i, j);
        s.membrane().position(n) - start[n]
    };
    // Under the grasp layer 0 rose most of the lift; near the clamped ends hardly at all.
    let under = moved(0, mid, 0).y;
    assert!(under > 0.003 && under < 0.0065, "{under}");
    assert!(moved(0, 1, 0).y.abs() < 0.25 * under, "{}", moved(0, 1, 0));
    // The pelvic side (layer 3) stays; the fasciae between rise by less than layer 0.
    for j in [0, cols / 4, cols / 2] {
        assert!(moved(3, mid, j).length() < 1e-4, "{}", moved(3, mid, j));
    }
    let fascia = moved(1, mid, 0).y;
    assert!(fascia > 0.0 && fascia < under, "{fascia} vs {under}");
}

#[test]
fn the_hook_pushes_the_membrane_and_feels_it_and_cuts_the_plane() {
    let mut s = scene();
    let mid = s.membrane().rows() / 2;
    // The dissection plane on top of the rectum, half way between layers 1 and 2.
    let plane = 0.5
        * (s.membrane().position(s.membrane().node(1, mid, 0))
            + s.membrane().position(s.membrane().node(2, mid, 0)));
    // The hook's end there, its shaft coming down from above through layers 2 and 3.
    let corner = plane + Vec3::new(0.0, 0.0, 0.006);
    let tools = ToolState {
        hook: Some((corner, from_above())),
        cutting: false,
        grasper: None,
        grasper_right: None,
    };
    let out = s.step(1e-3, &tools, 0, &mut Vec::new());
    assert!(out.hook_contacts > 0, "{out:?}");
    assert!(out.hook_n.length() > 0.0 && out.substeps >= 1, "{out:?}");
    // With the current on, the plane springs around the hook's end go.
    let cut = s.step(
        1e-3,
        &ToolState {
            cutting: true,
            ..tools
        },
        1,
        &mut Vec::new(),
    );
    assert!(cut.cut > 0, "{cut:?}");
    assert!(!s.membrane().link_alive(1, mid, 0));
    // Links 1-2 elsewhere are still there.
    assert!(s.membrane().link_alive(1, 2, s.membrane().cols() / 2));
    assert!(s.membrane().link_alive(0, mid, 0));
}

/// The hook's corner for its end to sit on node `(l, i, j)`, shaft from above.
fn hook_on(s: &RectumScene, l: usize, i: usize, j: usize) -> Vec3 {
    s.membrane().position(s.membrane().node(l, i, j)) + Vec3::new(0.0, 0.0, 0.006)
}

#[test]
fn regions_lie_where_the_anatomy_says() {
    let s = scene();
    let (rows, cols) = (s.membrane().rows(), s.membrane().cols());
    let name = |l, i, j| regions::region(s.region_of(s.membrane().node(l, i, j))).map(|r| r.name);
    // The plane (layers 1 and 2) in the middle, all round; not at the ends, not layer 0.
    assert_eq!(name(1, rows / 2, 0), Some("dissection_plane"));
    assert_eq!(name(2, rows / 2, cols / 2), Some("dissection_plane"));
    assert_eq!(name(1, 0, 0), None);
    assert_eq!(name(0, rows / 2, 0), None);
    // The ureters on layer 3 of the side walls (a quarter and three quarters round), high up.
    assert_eq!(name(3, rows / 5, cols / 4), Some("ureter_left"));
    assert_eq!(name(3, rows / 5, 3 * cols / 4), Some("ureter_right"));
    assert_eq!(name(3, 4 * rows / 5, cols / 4), None);
    // The plexus low down, in front of the side walls, over the plane's outer fascia.
    assert_eq!(name(2, 9 * rows / 10, cols / 6), Some("pelvic_plexus_left"));
}

#[test]
fn touching_a_ureter_raises_its_alarm_at_once_and_only_once() {
    let mut s = scene();
    let (rows, cols) = (s.membrane().rows(), s.membrane().cols());
    let (l, i, j) = (3, rows / 5, cols / 4);
    let ureter = 1 << s.region_of(s.membrane().node(l, i, j));
    let tools = ToolState {
        hook: Some((hook_on(&s, l, i, j), from_above())),
        cutting: false,
        grasper: None,
        grasper_right: None,
    };
    let first = s.step(1e-3, &tools, 0, &mut Vec::new());
    assert!(first.hook_contacts > 0, "{first:?}");
    assert_eq!(first.alarms & ureter, ureter, "{first:?}");
    let second = s.step(1e-3, &tools, 0, &mut Vec::new());
    assert_eq!(second.touching & ureter, ureter, "{second:?}");
    assert_eq!(second.alarms, 0, "{second:?}");
}

#[test]
fn cutting_on_the_rectal_wall_raises_an_alarm_and_cutting_in_the_plane_does_not() {
    let mut s = scene();
    let mid = s.membrane().rows() / 2;
    let plane = 0.5
        * (s.membrane().position(s.membrane().node(1, mid, 0))
            + s.membrane().position(s.membrane().node(2, mid, 0)));
    let in_plane = ToolState {
        hook: Some((plane + Vec3::new(0.0, 0.0, 0.006), from_above())),
        cutting: true,
        grasper: None,
        grasper_right: None,
    };
    let out = s.step(1e-3, &in_plane, 0, &mut Vec::new());
    assert!(out.cut > 0 && out.alarms == 0, "{out:?}");
    let mut s = scene();
    let wall = ToolState {
        hook: Some((hook_on(&s, 0, mid, 0), from_above())),
        cutting: true,
        grasper: None,
        grasper_right: None,
    };
    let out = s.step(1e-3, &wall, 0, &mut Vec::new());
    assert_eq!(out.alarms & ALARM_RECTAL_WALL, ALARM_RECTAL_WALL, "{out:?}");
}

/// The rod's node displacements from rest after `steps` of 1 ms with `load` (N) on the
/// fat's nodes over the top of the rectum's middle (layer 1, 5 x 5 nodes), every tile
/// awake; without `wall` the pelvic side is let go, so the membrane hangs on the rod alone;
/// `direct` puts the same load on the rod's surface under the patch instead. Returns the
/// rod's largest displacement along the load, and the membrane's last load on the rod.
fn carry(load: Vec3, steps: usize, direct: bool, wall: bool) -> (f64, Vec3) {
    let mut s = scene();
    if !wall {
        s.membrane_mut().detach_layer(LAYERS - 1);
    }
    s.membrane_mut().stay_awake();
    let (rows, cols) = (s.membrane().rows(), s.membrane().cols());
    let mid = rows / 2;
    let patch = s.top_patch(1, 2);
    let rest: Vec<glam::DVec3> = s.rod().rod().positions().to_vec();
    let (e, u, _) = s.skin_binding(mid * cols).expect("bound");
    let idle = ToolState {
        hook: None,
        cutting: false,
        grasper: None,
        grasper_right: None,
    };
    let mut pull = Vec3::ZERO;
    for _ in 0..steps {
        if direct {
            let x = s.rod().rod().positions();
            let axis = x[e] + (x[e + 1] - x[e]) * f64::from(u);
            let at = s.membrane().anchor_pull(mid, 0).expect("node").0.as_dvec3();
            s.rod_mut()
                .add_surface_force(e, f64::from(u), at - axis, load.as_dvec3(), 0.0);
        } else {
            for &n in &patch {
                s.membrane_mut().add_force(n, load / patch.len() as f32);
            }
        }
        pull = s.step(1e-3, &idle, 0, &mut Vec::new()).membrane_on_rod_n;
    }
    let along = load.as_dvec3().normalize();
    let most = s
        .rod()
        .rod()
        .positions()
        .iter()
        .zip(&rest)
        .map(|(x, r)| (*x - *r).dot(along))
        .fold(0.0, f64::max);
    (most, pull)
}

#[test]
fn the_membrane_hands_a_load_on_its_fat_to_the_rod() {
    // 50 mN pressing down on the fat over the top of the rectum.
    let load = Vec3::new(0.0, -0.05, 0.0);
    let (through, pull) = carry(load, 800, false, false);
    let (direct, _) = carry(load, 800, true, false);
    // At rest the free membrane passes the whole load on (its own forces sum to zero) ...
    assert!(
        (pull - load).length() < 0.05 * load.length(),
        "pull {pull} for a load of {load}"
    );
    // ... and the rod bends as it does under the load put straight on it.
    assert!(
        direct > 1e-5,
        "the rod moved {direct} m under the direct load"
    );
    assert!(
        (through - direct).abs() < 0.1 * direct,
        "through the membrane {through} m, directly {direct} m"
    );
    // Held by the pelvic wall too, the tissue shares the load: the rod takes a part of it,
    // and the coupling stays at rest (it rang and grew without the load's stiffness).
    let (held, part) = carry(load, 800, false, true);
    let share = part.dot(load) / load.length_squared();
    assert!(
        share > 0.02 && share < 0.9,
        "the rod takes {share} of the load"
    );
    assert!(
        held > 0.0 && held < through,
        "{held} m held, {through} m hanging"
    );
}

#[test]
fn the_broad_phase_finds_what_testing_every_node_finds() {
    // Everything awake and moved a little (tile boxes as a step leaves them), the hook in the
    // plane at the front, then with its end on the left ureter: the tiles near the hook give
    // the same contacts as every node, and the same nearest vulnerable node within the near
    // distance (none at the front).
    let mut s = scene();
    s.membrane_mut().stay_awake();
    let (rows, cols) = (s.membrane().rows(), s.membrane().cols());
    let mid = rows / 2;
    let plane = 0.5
        * (s.membrane().position(s.membrane().node(1, mid, 0))
            + s.membrane().position(s.membrane().node(2, mid, 0)));
    let corners = [
        plane + Vec3::new(0.0, 0.0, 0.006),
        hook_on(&s, 3, rows / 5, cols / 4),
    ];
    for (k, corner) in corners.into_iter().enumerate() {
        let tools = ToolState {
            hook: Some((corner, from_above())),
            cutting: false,
            grasper: None,
            grasper_right: None,
        };
        for _ in 0..3 {
            s.step(1e-3, &tools, 0, &mut Vec::new());
        }
        let hook = Instrument::l_hook(corner, from_above()).expect("hook");
        s.joints.near_vulnerable = None;
        s.press_membrane(&hook);
        let mut near: Vec<u32> = s
            .joints
            .contacts
            .iter()
            .map(|c| s.joints.nodes[c.vertex as usize])
            .collect();
        near.sort_unstable();
        let tested = s.joints.nodes.len();
        let everything: Vec<Vec3> = (0..s.membrane().len())
            .map(|n| s.membrane().position(n))
            .collect();
        let mut all = Vec::new();
        hook.contacts_all(PointCloud::from_points(&everything), &mut all);
        let mut all: Vec<u32> = all.iter().map(|c| c.vertex).collect();
        all.sort_unstable();
        assert_eq!(near, all, "corner {k}");
        assert!(k == 1 || !all.is_empty(), "corner {k}: the hook touches");
        assert!(
            tested < s.membrane().len() / 4,
            "corner {k}: {tested} nodes tested"
        );
        let end = hook.cylinders()[1].p1();
        let nearest = (0..s.membrane().len())
            .filter(|&n| {
                regions::region(s.region_of(n)).is_some_and(|r| r.kind == RegionKind::Vulnerable)
            })
            .map(|n| (s.region_of(n), s.membrane().position(n).distance(end)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|n| n.1 <= s.params.near_m);
        assert_eq!(nearest.is_some(), k == 1, "corner {k}: {nearest:?}");
        assert_eq!(
            s.joints.near_vulnerable.filter(|n| n.1 <= s.params.near_m),
            nearest
        );
    }
}

#[test]
fn the_membrane_holds_layer_zero_where_the_skin_places_it_on_the_bent_rod() {
    // The membrane places layer 0's targets from the rod's pose with the skin's bindings
    // (`Membrane::pose_targets`): after a lift has bent the rod, every target is where the
    // skin itself places its node, to the bit.
    use crate::models::cosserat::skin::Selection;
    let mut s = scene();
    let mid = s.membrane().rows() / 2;
    let top = s.membrane().position(s.membrane().node(0, mid, 0));
    for k in 0..120 {
        let lift = 0.004 * (k as f32 / 119.0);
        let tools = ToolState {
            hook: None,
            cutting: false,
            grasper: Some((top + Vec3::Y * lift, from_above(), true)),
            grasper_right: None,
        };
        s.step(1e-3, &tools, 0, &mut Vec::new());
    }
    s.place_everything();
    let m = s.membrane();
    let mut placed = vec![Vec3::ZERO; m.rows() * m.cols()];
    s.joints
        .skin
        .place(s.rod(), Selection::All, &mut placed)
        .expect("the skin places every node");
    let mut differ = 0;
    for (k, p) in placed.iter().enumerate() {
        let (target, _) = m
            .anchor_pull(k / m.cols(), k % m.cols())
            .expect("in the grid");
        differ += usize::from(target != *p);
    }
    assert_eq!(differ, 0, "{differ} of {} targets differ", placed.len());
    let bent = (placed[m.cols() * mid] - top).y;
    assert!(bent > 0.002, "the rod rose {bent} m under the grasp");
}
