use super::*;
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
    let (rows, cols) = (s.membrane.rows(), s.membrane.cols());
    let mid = rows / 2;
    let start: Vec<Vec3> = (0..s.membrane.len())
        .map(|n| s.membrane.position(n))
        .collect();
    // The grasper closes on the top of the rectum (column 0 faces +y) and lifts 6 mm in 0.3 s.
    let top = start[s.membrane.node(0, mid, 0)];
    let mut tools = ToolState {
        hook: None,
        cutting: false,
        grasper: Some((top, from_above(), true)),
    };
    for k in 0..300 {
        let lift = 0.006 * (k as f32 / 299.0);
        tools.grasper = Some((top + Vec3::Y * lift, from_above(), true));
        s.step(1e-3, &tools);
    }
    s.place_everything();
    let moved = |l: usize, i: usize, j: usize| {
        let n = s.membrane.node(l, i, j);
        s.membrane.position(n) - start[n]
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
    let mid = s.membrane.rows() / 2;
    // The dissection plane on top of the rectum, half way between layers 1 and 2.
    let plane = 0.5
        * (s.membrane.position(s.membrane.node(1, mid, 0))
            + s.membrane.position(s.membrane.node(2, mid, 0)));
    // The hook's end there, its shaft coming down from above through layers 2 and 3.
    let corner = plane + Vec3::new(0.0, 0.0, 0.006);
    let tools = ToolState {
        hook: Some((corner, from_above())),
        cutting: false,
        grasper: None,
    };
    let out = s.step(1e-3, &tools);
    assert!(out.hook_contacts > 0, "{out:?}");
    assert!(out.hook_n.length() > 0.0 && out.substeps >= 1, "{out:?}");
    // With the current on, the plane springs around the hook's end go.
    let cut = s.step(
        1e-3,
        &ToolState {
            cutting: true,
            ..tools
        },
    );
    assert!(cut.cut > 0, "{cut:?}");
    assert!(!s.membrane.link_alive(1, mid, 0));
    // Links 1-2 elsewhere are still there.
    assert!(s.membrane.link_alive(1, 2, s.membrane.cols() / 2));
    assert!(s.membrane.link_alive(0, mid, 0));
}
