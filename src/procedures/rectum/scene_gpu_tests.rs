//! The rectum's scene with its membrane on a device (lavapipe in CI): what comes back each
//! step changes no bytes.

use super::*;
use crate::procedures::rectum::{Anatomy, AnatomyParams};

/// Forward (-Z) pointing down (-Y), the hook (+Y) pointing along -Z.
fn from_above() -> Quat {
    Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2)
}

/// What one run of the session gives: each step's outcome and awake tiles, the state's hash
/// at the end, the tiles that came back with the steps and the round trips that brought
/// lagging tiles up to date, and the most tiles that lagged after a step.
struct Run {
    outcomes: Vec<StepOutcome>,
    awake: Vec<Vec<usize>>,
    hash: u64,
    back: u64,
    catch_ups: u64,
    most_behind: usize,
}

/// A coarse rectum (120 x 96 a layer) on `gpu`, every awake tile read back each step where
/// `eager`: a grasper lifts the rectum a fifth of the way along (waking the tissue there,
/// which no instrument reads) while the hook comes down into the plane at the middle and
/// cuts its way along it.
fn session(gpu: &crate::gpu::Gpu, eager: bool) -> Run {
    let a = Anatomy::generate(AnatomyParams {
        rows: 120,
        cols: 96,
        ..AnatomyParams::default()
    })
    .expect("anatomy");
    let mut s = RectumScene::new(&a, SceneParams::default()).expect("scene");
    s.membrane_mut().use_gpu(gpu).expect("on the device");
    s.membrane_mut().gpu_read_back_everything(eager);
    let m = s.membrane();
    let (rows, mid) = (m.rows(), m.rows() / 2);
    let plane = |i: usize| {
        0.5 * (m.position(m.node(1, i, 0)) + m.position(m.node(2, i, 0))) + Vec3::Z * 0.006
    };
    let (from, to) = (plane(mid - 8), plane(mid + 8));
    let top = m.position(m.node(0, rows / 5, 0));
    let mut run = Run {
        outcomes: Vec::new(),
        awake: Vec::new(),
        hash: 0,
        back: 0,
        catch_ups: 0,
        most_behind: 0,
    };
    for k in 0..120u64 {
        let f = k as f32 / 119.0;
        let tools = ToolState {
            hook: Some((from.lerp(to, f) - Vec3::Y * 0.0005 * f, from_above())),
            cutting: k >= 20,
            grasper: Some((top + Vec3::Y * 0.003 * f, from_above(), true)),
            grasper_right: None,
        };
        run.outcomes.push(s.step(1e-3, &tools, k, &mut Vec::new()));
        let m = s.membrane();
        let (tr, tc) = m.tiles();
        run.awake
            .push((0..tr * tc).filter(|&t| m.tile_awake(t)).collect());
        run.most_behind = run.most_behind.max(m.gpu_tiles_behind().unwrap_or(0));
    }
    assert!(
        s.membrane().gpu_adapter().is_some(),
        "it stayed on the device"
    );
    run.hash = s.membrane().state_hash();
    (run.back, run.catch_ups) = s.membrane().gpu_readback_counts().expect("on the device");
    run
}

#[test]
fn reading_back_only_what_the_cpu_reads_next_changes_no_bytes() {
    let gpu = crate::gpu::Gpu::headless(false).expect("a Vulkan adapter");
    let every = session(&gpu, true);
    let near = session(&gpu, false);
    // The session did what it is for: the hook touched and cut, tissue woke by the grasper.
    let cut: u32 = every.outcomes.iter().map(|o| o.cut).sum();
    let touched = every
        .outcomes
        .iter()
        .filter(|o| o.hook_contacts > 0)
        .count();
    assert!(
        cut > 0 && touched > 20,
        "{cut} springs cut, {touched} steps touched"
    );
    for (k, (a, b)) in every.outcomes.iter().zip(&near.outcomes).enumerate() {
        assert_eq!(a, b, "step {k}");
        assert_eq!(every.awake[k], near.awake[k], "step {k}");
    }
    assert_eq!(every.hash, near.hash, "the state at the end");
    // Fewer tiles came back, some lagged after a step, and every awake tile came back with
    // each step when asked to (nothing lagged).
    assert_eq!(every.most_behind, 0);
    assert!(near.most_behind > 0, "no tile lagged");
    assert!(
        near.back < every.back,
        "{} tiles came back against {}",
        near.back,
        every.back
    );
    // The world's checkpoints (every 16 steps) read every tile: those came back with the
    // step before each, and no query here met a lagging tile, so nothing took a round trip
    // of its own to catch up.
    assert_eq!(near.catch_ups, 0, "round trips to catch up");
    eprintln!(
        "tiles back: {} of {} ({} round trips to catch up, at most {} tiles lagging)",
        near.back, every.back, near.catch_ups, near.most_behind
    );
}
