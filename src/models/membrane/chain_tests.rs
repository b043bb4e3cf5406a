//! Layer 0's targets placed from a chain's pose: the formula against a turned frame, bad
//! bindings and poses refused by name, the CPU's lazy placing against placing every target
//! every step (the same bytes), and on a device (CI: lavapipe) the targets placed there, with
//! no attachment sent up, against the CPU.

use super::gpu_tests::{awake_tiles, device, session_step, sleepy};
use super::*;
use glam::{DVec3, Quat};

/// Segments of the test chain, along the tube's axis.
const SEGMENTS: usize = 4;

/// The tube's layer-0 nodes bound to a straight chain of `SEGMENTS` segments along x from 0
/// to `length`, its frames the identity (the frames blended as a rod's skin blends them).
fn bind_along(m: &mut Membrane, length: f32) {
    let per = length / SEGMENTS as f32;
    let bound = (0..m.rows() * m.cols())
        .map(|k| {
            let p = m.position(m.node(0, k / m.cols(), k % m.cols()));
            let e = ((p.x / per).floor().max(0.0) as usize).min(SEGMENTS - 1);
            let t = ((p.x - e as f32 * per) / per).clamp(0.0, 1.0);
            let s = e as f32 + t - 0.5;
            let pair = (s.floor().max(0.0) as usize).min(SEGMENTS - 2);
            let c = Vec3::new(e as f32 * per + t * per, 0.0, 0.0);
            ChainBinding {
                segment: e as u32,
                t,
                pair: pair as u32,
                w: (s - pair as f32).clamp(0.0, 1.0),
                offset: p - c,
            }
        })
        .collect();
    m.bind_targets(bound, SEGMENTS).expect("a valid binding");
}

/// The chain's pose at step `k`: straight along x, twisted about it (frame `s` turned by
/// `s + 1/2` quarters of `twist(k)`) and carried `k` micrometres along y.
fn pose(length: f32, k: usize) -> (Vec<DVec3>, Vec<Quat>) {
    let twist = 0.02 * (k.min(60) as f32 / 60.0);
    let shift = 1e-6 * k as f64;
    let points = (0..=SEGMENTS)
        .map(|s| DVec3::new(f64::from(length) * s as f64 / SEGMENTS as f64, shift, 0.0))
        .collect();
    let quats = (0..SEGMENTS)
        .map(|s| Quat::from_rotation_x(twist * (s as f32 + 0.5) / SEGMENTS as f32))
        .collect();
    (points, quats)
}

/// Length of the sleepy tube of `rows` rows (`gpu_tests::sleepy`).
fn length(rows: usize) -> f32 {
    0.032 * rows as f32 / 128.0
}

/// Node `k`'s target under `pose`, as the chain places it on the CPU.
fn expected(bound: &ChainBinding, (points, quats): &(Vec<DVec3>, Vec<Quat>)) -> Vec3 {
    let (e, p) = (bound.segment as usize, bound.pair as usize);
    let c = points[e] + (points[e + 1] - points[e]) * f64::from(bound.t);
    let q = (quats[p] * (1.0 - bound.w) + quats[p + 1] * bound.w).normalize();
    (c + (q * bound.offset).as_dvec3()).as_vec3()
}

#[test]
fn a_chain_places_a_target_at_its_segment_point_plus_the_turned_offset() {
    // One segment from (0,0,0) to (0.1,0,0), both frames a quarter turn about x: a node
    // bound half way along with offset (0, 0.01, 0) is held at (0.05, 0, 0.01).
    let mut m = sleepy(16, 32);
    let mut bound = vec![
        ChainBinding {
            segment: 0,
            t: 0.0,
            pair: 0,
            w: 0.0,
            offset: Vec3::ZERO,
        };
        16 * 32
    ];
    bound[5 * 32 + 7] = ChainBinding {
        segment: 0,
        t: 0.5,
        pair: 0,
        w: 0.25,
        offset: Vec3::new(0.0, 0.01, 0.0),
    };
    m.bind_targets(bound, 1).expect("binds");
    let q = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let points = [DVec3::ZERO, DVec3::new(0.1, 0.0, 0.0)];
    m.pose_targets(&points, &[q, q])
        .expect("a pose of one segment");
    m.place_all_targets();
    let (target, _) = m.anchor_pull(5, 7).expect("in the grid");
    let want = Vec3::new(0.05, 0.0, 0.01);
    assert!(
        (target - want).length() < 1e-8,
        "held at {target}, expected {want}"
    );
    // Every other node sits on the chain's first point.
    assert!(m.anchor_pull(0, 0).expect("in the grid").0.length() < 1e-12);
}

#[test]
fn bindings_and_poses_that_do_not_fit_the_chain_are_refused_by_name() {
    let mut m = sleepy(16, 32);
    let fine = ChainBinding {
        segment: 1,
        t: 0.5,
        pair: 0,
        w: 0.5,
        offset: Vec3::ZERO,
    };
    let all = |b: ChainBinding| vec![b; 16 * 32];
    let err = |m: &mut Membrane, bound: Vec<ChainBinding>, segments| {
        m.bind_targets(bound, segments)
            .expect_err("refused")
            .to_string()
    };
    assert!(err(&mut m, vec![fine; 10], 2).contains("10 bindings for 512"));
    assert!(err(&mut m, all(fine), 1).contains("segment 1 of a chain of 1"));
    let pair = ChainBinding { pair: 1, ..fine };
    assert!(err(&mut m, all(pair), 2).contains("frames 1 and 2 of 2"));
    let mut bad = all(fine);
    bad[77].offset = Vec3::NAN;
    let e = err(&mut m, bad, 2);
    assert!(e.contains("node 77") && e.contains("not finite"), "{e}");
    let q = [Quat::IDENTITY; 2];
    let e = m
        .pose_targets(&[DVec3::ZERO; 3], &q)
        .expect_err("no chain")
        .to_string();
    assert!(e.contains("no chain is bound"), "{e}");
    m.bind_targets(all(fine), 2).expect("binds");
    let e = m
        .pose_targets(&[DVec3::ZERO; 2], &q)
        .expect_err("too few points")
        .to_string();
    assert!(
        e.contains("2 points and 2 frames") && e.contains("expected 3 and 2"),
        "{e}"
    );
    let e = m
        .pose_targets(&[DVec3::ZERO, DVec3::NAN, DVec3::ZERO], &q)
        .expect_err("not finite")
        .to_string();
    assert!(e.contains("not finite"), "{e}");
    // Nothing was placed from a refused pose.
    let before = m.anchor_pull(3, 3).expect("in the grid").0;
    m.place_all_targets();
    assert_eq!(m.anchor_pull(3, 3).expect("in the grid").0, before);
}

#[test]
fn the_chain_places_on_the_cpu_what_placing_every_target_every_step_would() {
    // Two copies of a session whose chain twists and moves: one hands the chain its pose (it
    // places the targets of the awake tiles and the halo, and a waking tile's as it wakes),
    // the other sets every node's target every step. The same bytes, step by step.
    let (rows, len) = (48, length(48));
    let start = sleepy(rows, 64);
    let (mut lazy, mut every) = (start.clone(), start.clone());
    bind_along(&mut lazy, len);
    bind_along(&mut every, len);
    let bound = every.chain.as_deref().expect("bound").bound.clone();
    let mut out = crate::sim::ModelOutput::default();
    let mut most = 0;
    for k in 0..120 {
        let p = pose(len, k);
        lazy.pose_targets(&p.0, &p.1).expect("a pose");
        for (n, b) in bound.iter().enumerate() {
            every.set_target(n / every.cols(), n % every.cols(), expected(b, &p));
        }
        session_step(&mut lazy, k, &mut out);
        session_step(&mut every, k, &mut out);
        assert_eq!(lazy.state_hash(), every.state_hash(), "step {k}");
        most = most.max(awake_tiles(&lazy).len());
    }
    let (tr, tc) = lazy.tiles();
    assert!(most >= 2 && most < tr * tc, "{most} tiles woke");
    let moved = (0..lazy.len())
        .map(|n| (lazy.position(n) - start.position(n)).length())
        .fold(0.0f32, f32::max);
    assert!(moved > 5e-5, "the chain moved the tissue {moved:e} m");
}

#[test]
fn a_sleeping_tile_is_drawn_where_the_chain_carries_it_before_its_targets_are_placed() {
    let (rows, len) = (48, length(48));
    let mut m = sleepy(rows, 64);
    bind_along(&mut m, len);
    let p = pose(len, 0);
    m.pose_targets(&p.0, &p.1).expect("a pose");
    m.place_all_targets();
    m.place_sleeping();
    // Every tile sleeps: none of its targets is placed by the next pose, 30 um along y.
    let n = m.node(0, 40, 10);
    let before = m.carried_position(n);
    let shifted: Vec<DVec3> =
        p.0.iter()
            .map(|x| *x + DVec3::new(0.0, 3e-5, 0.0))
            .collect();
    m.pose_targets(&shifted, &p.1).expect("a pose");
    let moved = m.carried_position(n) - before;
    assert!(
        (moved - Vec3::new(0.0, 3e-5, 0.0)).length() < 1e-9,
        "drawn {moved} from where it was"
    );
    assert_eq!(m.position(n), before, "its state is left as it was");
}

#[test]
fn a_drawn_grid_holds_where_each_of_its_nodes_is_drawn() {
    // A twisting session's first 60 steps, then a pose no step has met: an awake tile's node
    // is drawn where it is, a sleeping one's where the chain now carries it.
    let (rows, len) = (48, length(48));
    let mut m = sleepy(rows, 64);
    bind_along(&mut m, len);
    let mut out = crate::sim::ModelOutput::default();
    for k in 0..60 {
        let p = pose(len, k);
        m.pose_targets(&p.0, &p.1).expect("a pose");
        session_step(&mut m, k, &mut out);
    }
    let awake = awake_tiles(&m).len();
    let p = pose(len, 90);
    m.pose_targets(&p.0, &p.1).expect("a pose");
    // Every third row and every other column, and one row past the grid's last.
    let rs: Vec<usize> = (0..m.rows()).step_by(3).chain([m.rows()]).collect();
    let cs: Vec<usize> = (0..m.cols()).step_by(2).collect();
    let layers = [0, 1, 2, 3];
    let grid = m.carried_grid(&layers, &rs, &cs);
    assert_eq!(grid.len(), layers.len() * rs.len() * cs.len());
    let (mut k, mut carried, mut outside) = (0, 0, 0);
    for l in layers {
        for &i in &rs {
            for &j in &cs {
                if i >= m.rows() {
                    assert_eq!(grid[k], Vec3::ZERO, "({l}, {i}, {j})");
                    outside += 1;
                } else {
                    let n = m.node(l, i, j);
                    assert_eq!(grid[k], m.carried_position(n), "({l}, {i}, {j})");
                    carried += usize::from(grid[k] != m.position(n));
                }
                k += 1;
            }
        }
    }
    assert!(awake > 0, "no tile awake");
    assert!(carried > 0, "no node drawn off its state");
    assert_eq!(outside, layers.len() * cs.len());
}

#[test]
fn a_drawn_grid_kept_from_frame_to_frame_follows_tiles_falling_asleep_and_waking() {
    // The pull of `session_step` twice, at steps 0-39 and 160-199, on a twisting chain; a
    // frame every 9 steps from one grid kept throughout. Its tiles fall asleep with new
    // offsets and wake again between frames: each frame must still place every node where
    // `carried_position` does, bit for bit.
    let (rows, len) = (48, length(48));
    let mut m = sleepy(rows, 64);
    bind_along(&mut m, len);
    let rs: Vec<usize> = (0..m.rows()).step_by(3).collect();
    let cs: Vec<usize> = (0..m.cols()).step_by(2).chain([m.cols() + 1]).collect();
    let layers = [1, 2, 3, 4];
    let mut grid = DrawnGrid::new(&layers, &rs, &cs);
    let mut out = crate::sim::ModelOutput::default();
    let (mut before, mut fell_asleep, mut woke, mut frames) = (awake_tiles(&m), 0, 0, 0);
    for k in 0..=400 {
        // A frame before the first step too: every tile's parts are copied while it sleeps.
        if k > 0 {
            let p = pose(len, k);
            m.pose_targets(&p.0, &p.1).expect("a pose");
            session_step(&mut m, (k - 1) % 200, &mut out);
            if k % 9 != 0 {
                continue;
            }
        }
        let now = awake_tiles(&m);
        fell_asleep += before.iter().filter(|t| !now.contains(t)).count();
        woke += now.iter().filter(|t| !before.contains(t)).count();
        before = now;
        let drawn = m.place_drawn(&mut grid);
        assert_eq!(drawn.len(), grid.len());
        let mut at = drawn.iter();
        for l in layers {
            for &i in &rs {
                for &j in &cs {
                    let p = *at.next().expect("a node");
                    let want = if l < LAYERS && j < m.cols() {
                        m.carried_position(m.node(l, i, j))
                    } else {
                        Vec3::ZERO
                    };
                    assert_eq!(
                        p.to_array().map(f32::to_bits),
                        want.to_array().map(f32::to_bits),
                        "step {k}: ({l}, {i}, {j})"
                    );
                }
            }
        }
        frames += 1;
    }
    assert!(frames > 30);
    assert!(
        woke > 0 && fell_asleep > 0,
        "woke {woke}, fell asleep {fell_asleep}"
    );
}

#[test]
fn the_device_places_the_targets_from_the_pose_and_none_go_up() {
    // The twisting session on the CPU, on a device placing the targets itself, and on a
    // device taking them from the CPU as before: the same tiles sleep and wake at every
    // step, the positions agree within float rounding of the largest displacement, and no
    // attachment goes up where the device places the targets.
    let gpu = device();
    let (rows, len) = (48, length(48));
    let start = sleepy(rows, 64);
    let mut runs: Vec<Membrane> = (0..3).map(|_| start.clone()).collect();
    for m in &mut runs {
        bind_along(m, len);
    }
    runs[1].use_gpu(&gpu).expect("uploads");
    runs[2].use_gpu(&gpu).expect("uploads");
    runs[2].gpu_place_targets_on_cpu(true);
    let mut out = crate::sim::ModelOutput::default();
    let mut most = 0.0f32;
    for k in 0..160 {
        let p = pose(len, k);
        for m in &mut runs {
            m.pose_targets(&p.0, &p.1).expect("a pose");
            session_step(m, k, &mut out);
            assert!(out.events.is_empty(), "{:?}", out.events);
        }
        let now = awake_tiles(&runs[0]);
        assert_eq!(awake_tiles(&runs[1]), now, "step {k}");
        assert_eq!(awake_tiles(&runs[2]), now, "step {k}");
        most = (0..start.len())
            .map(|n| (runs[0].position(n) - start.position(n)).length())
            .fold(most, f32::max);
    }
    assert!(most > 5e-5, "the session moved the tissue {most:e} m");
    for m in &mut runs[1..] {
        m.catch_up();
    }
    for m in &runs[1..] {
        let diff = (0..m.len())
            .map(|n| (m.carried_position(n) - runs[0].carried_position(n)).length())
            .fold(0.0f32, f32::max);
        assert!(
            diff < 1e-3 * most,
            "positions differ by {diff:e} m, the most moved {most:e} m"
        );
    }
    assert_eq!(runs[1].gpu_attachments_sent(), Some(0));
    assert!(runs[2].gpu_attachments_sent().is_some_and(|n| n > 0));
    assert!(runs[1].gpu_adapter().is_some(), "it stayed on the device");
}
