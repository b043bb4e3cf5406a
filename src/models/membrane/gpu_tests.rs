//! The membrane's GPU kernel against its CPU step, on whatever Vulkan adapter there is (CI:
//! lavapipe): the same physics within float rounding, the same bytes run to run.

use super::gpu::{self, MembraneGpu};
use super::*;
use crate::gpu::Gpu;

pub(super) fn device() -> Gpu {
    Gpu::headless(false).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)")
}

/// A ring of four layers (periodic columns), radii growing outwards, 5 cm along x.
fn tube(rows: usize, cols: usize) -> Membrane {
    let shape = super::tests::tube(rows, cols, 0.05, [0.01, 0.012, 0.013, 0.016]);
    Membrane::new(shape, material()).expect("a valid tube")
}

/// The CPU tests' fat, with links of three stiffnesses (the kernel must take each layer's).
fn material() -> MembraneParams {
    MembraneParams {
        link_modulus_pa: [2e3, 4e3, 1e3],
        ..super::tests::params(Integrator::Symplectic)
    }
}

fn sheet(rows: usize, cols: usize) -> Membrane {
    Membrane::new(MembraneShape::sheet(rows, cols, 2e-3, 1e-3), material()).expect("a sheet")
}

/// The largest displacement difference between two runs from the same start, over the
/// largest displacement (each run's awake tiles brought up to date from its device first).
fn displacement_error(start: &Membrane, a: &mut Membrane, b: &mut Membrane) -> f32 {
    a.catch_up();
    b.catch_up();
    let (mut diff, mut most) = (0.0f32, 0.0f32);
    for node in 0..start.len() {
        let (da, db) = (
            a.position(node) - start.position(node),
            b.position(node) - start.position(node),
        );
        diff = diff.max((da - db).length());
        most = most.max(db.length());
    }
    diff / most
}

#[test]
fn the_gpu_substep_follows_the_cpu_within_float_rounding() {
    let gpu = device();
    for (name, m) in [("tube", tube(24, 40)), ("sheet", sheet(20, 33))] {
        let dt = 0.5 * m.explicit_step_limit();
        // Velocities after a few substeps from the pushed state.
        for layout in [gpu::Layout::Flat, gpu::Layout::Rows, gpu::Layout::Layers] {
            let v_err = gpu::compare(&gpu, &m, 10, dt, layout).expect("the kernel runs");
            assert!(
                v_err < 1e-4,
                "{name} {layout:?}: velocities differ by {v_err:e}"
            );
        }
        // Positions after 400 substeps from the built state, with a cut and a tool's force.
        // (From the pushed state, whose springs are all strained at random, a one-nanometre
        // nudge of one node changes the displacements by up to 0.5 % after 400 substeps; from
        // the built state by 2e-5 to 2e-4, the GPU's difference too.)
        let mut start = m.clone();
        start.cut_plane(start.position(start.node(1, 10, 5)), 0.004);
        let (mut cpu, mut dev) = (start.clone(), start.clone());
        let mut k = MembraneGpu::new(&gpu, &dev).expect("uploads");
        let push = Vec3::new(0.0, 0.02, 0.01);
        for _ in 0..40 {
            dev.add_force(dev.node(0, 12, 7), push);
            k.advance(&mut dev, 10.0 * dt, 10).expect("steps");
            for _ in 0..10 {
                cpu.add_force(cpu.node(0, 12, 7), push);
                cpu.step(dt);
            }
        }
        k.download(&mut dev).expect("reads back");
        let err = displacement_error(&start, &mut dev, &mut cpu);
        assert!(
            err < 1e-3,
            "{name}: displacements differ by {err:e} of the largest"
        );
        assert!(dev.is_finite());
    }
}

#[test]
fn every_layout_of_the_workgroups_gives_the_same_bytes() {
    // Each node's substep is one invocation's work whatever workgroup holds it, so the
    // layouts differ only in what the GPU's cache holds: the same bytes. A tube (its columns
    // wrap round) of 72 columns (the last workgroup of 64 a row idles in part) and 9 rows,
    // with a cut and a pushed node.
    let gpu = device();
    let run = |layout| {
        let mut m = gpu::pushed(&tube(9, 72));
        m.cut_plane(m.position(m.node(1, 4, 30)), 0.003);
        let dt = 0.5 * m.explicit_step_limit();
        let mut k = MembraneGpu::with_layout(&gpu, &m, layout).expect("uploads");
        for _ in 0..10 {
            m.add_force(m.node(3, 2, 70), Vec3::new(0.0, 0.01, 0.0));
            k.advance(&mut m, 4.0 * dt, 4).expect("steps");
        }
        k.download(&mut m).expect("reads back");
        m.state_hash()
    };
    let flat = run(gpu::Layout::Flat);
    assert_ne!(flat, gpu::pushed(&tube(9, 72)).state_hash(), "it moved");
    assert_eq!(run(gpu::Layout::Rows), flat, "rows of 64");
    assert_eq!(run(gpu::Layout::Layers), flat, "the layers together");
}

#[test]
fn two_gpu_runs_give_the_same_bytes() {
    let gpu = device();
    let run = || {
        let mut m = gpu::pushed(&tube(16, 24));
        let dt = 0.5 * m.explicit_step_limit();
        let mut k = MembraneGpu::new(&gpu, &m).expect("uploads");
        for _ in 0..20 {
            m.add_force(m.node(0, 8, 3), Vec3::new(0.01, 0.0, 0.0));
            k.advance(&mut m, 5.0 * dt, 5).expect("steps");
        }
        k.download(&mut m).expect("reads back");
        m.state_hash()
    };
    let first = run();
    assert_eq!(first, run());
    assert_ne!(first, gpu::pushed(&tube(16, 24)).state_hash(), "it moved");
}

#[test]
fn a_cut_uploaded_to_the_gpu_frees_the_tissue_as_on_the_cpu() {
    let gpu = device();
    let start = sheet(12, 20);
    let dt = 0.5 * start.explicit_step_limit();
    let (mut cpu, mut dev) = (start.clone(), start.clone());
    let mut k = MembraneGpu::new(&gpu, &dev).expect("uploads");
    // Cut after the upload: the device needs the new springs.
    let at = dev.position(dev.node(1, 6, 10));
    assert!(dev.cut_plane(at, 0.003) > 0);
    cpu.cut_plane(at, 0.003);
    k.upload_springs(&dev);
    k.advance(&mut dev, 100.0 * dt, 100).expect("steps");
    k.download(&mut dev).expect("reads back");
    for _ in 0..100 {
        cpu.step(dt);
    }
    let err = displacement_error(&start, &mut dev, &mut cpu);
    assert!(err < 1e-3, "displacements differ by {err:e} of the largest");
}

/// The sleepy tube of the active set's tests at a third of its length: the same 0.25 mm
/// spacing, 6 x 4 tiles.
pub(super) fn sleepy(rows: usize, cols: usize) -> Membrane {
    let mut p = super::tests::params(Integrator::Symplectic);
    p.gravity = Vec3::ZERO;
    p.spring_damping_ratio = 0.5;
    p.link_damping_ratio = 0.5;
    p.damping_per_s = 20.0;
    let length = 0.032 * rows as f32 / 128.0;
    let shape = super::tests::tube(rows, cols, length, [0.01, 0.012, 0.013, 0.016]);
    let mut m = Membrane::new(shape, p).expect("membrane");
    m.use_active_set(ActivityParams::default());
    m
}

/// Step `k` of a session on `m`: a tool near layer 1's node at row 24, column 32 pulls it
/// along the tube for 40 steps (waking the tiles around it), then lets go.
pub(super) fn session_step(m: &mut Membrane, k: usize, out: &mut crate::sim::ModelOutput) {
    let node = m.node(1, 24, 32);
    if k < 40 {
        // The tool reads the node's tile, as an instrument's query does.
        m.read_tiles(&[m.tile_of(24, 32)]);
        let p = m.position(node);
        m.wake_near(&[(p - Vec3::splat(1e-3), p + Vec3::splat(1e-3))]);
        m.add_force(node, Vec3::X * 2e-4);
    }
    out.clear();
    crate::sim::TissueModel::step(m, 1e-3, &[], out);
}

/// Step `k` of the session above with a cut through the pulled tissue at step 20 (new
/// springs go up), a checkpoint at 25, and a rollback to it at 30 (everything goes up again).
fn cut_and_rollback_step(m: &mut Membrane, k: usize, out: &mut crate::sim::ModelOutput) {
    use crate::sim::TissueModel;
    match k {
        20 => {
            m.read_tiles(&[m.tile_of(24, 34)]);
            let at = m.position(m.node(1, 24, 34));
            assert!(m.cut_plane(at, 0.001) > 0);
        }
        25 => m.checkpoint(),
        30 => m.restore(),
        _ => {}
    }
    session_step(m, k, out);
}

/// A device, the sleepy tube, and two copies of it: one on the CPU, one on the device.
fn on_both() -> (Gpu, Membrane, Membrane, Membrane) {
    let gpu = device();
    let start = sleepy(48, 64);
    let (cpu, mut dev) = (start.clone(), start.clone());
    dev.use_gpu(&gpu).expect("uploads");
    (gpu, start, cpu, dev)
}

pub(super) fn awake_tiles(m: &Membrane) -> Vec<usize> {
    let (tr, tc) = m.tiles();
    (0..tr * tc).filter(|&t| m.tile_awake(t)).collect()
}

#[test]
fn the_active_set_steps_on_the_gpu_as_on_the_cpu() {
    let (_gpu, start, mut cpu, mut dev) = on_both();
    let mut out = crate::sim::ModelOutput::default();
    let mut most = 0;
    for k in 0..60 {
        for m in [&mut cpu, &mut dev] {
            cut_and_rollback_step(m, k, &mut out);
            assert!(out.events.is_empty(), "{:?}", out.events);
        }
        assert_eq!(awake_tiles(&dev), awake_tiles(&cpu), "step {k}");
        most = most.max(awake_tiles(&dev).len());
    }
    let (tr, tc) = dev.tiles();
    assert!(most >= 2 && most < tr * tc, "{most} tiles woke");
    let err = displacement_error(&start, &mut dev, &mut cpu);
    assert!(err < 1e-3, "displacements differ by {err:e} of the largest");
    assert!(dev.gpu_adapter().is_some());
    assert!(cpu.gpu_adapter().is_none());
}

#[test]
fn a_lost_device_hands_the_membrane_to_the_cpu_with_an_event_and_loses_nothing() {
    // A device of its own: the test destroys it. Every awake tile comes back with each step
    // here, so the CPU's copy is the newest state when the device goes, and the CPU goes
    // on from it.
    let (_gpu, start, mut cpu, mut dev) = on_both();
    dev.gpu_read_back_everything(true);
    let mut out = crate::sim::ModelOutput::default();
    for k in 0..30 {
        session_step(&mut cpu, k, &mut out);
        if k == 10 {
            assert_eq!(dev.gpu_tiles_behind(), Some(0));
            assert!(dev.inject_device_loss());
        }
        session_step(&mut dev, k, &mut out);
        let fell_back: Vec<_> = out
            .events
            .iter()
            .filter(|e| matches!(e, crate::sim::EventKind::ComputeFallback { .. }))
            .collect();
        assert_eq!(
            fell_back.len(),
            usize::from(k == 10),
            "step {k}: {:?}",
            out.events
        );
    }
    assert!(dev.gpu_adapter().is_none(), "on the CPU from the loss on");
    assert_eq!(awake_tiles(&dev), awake_tiles(&cpu));
    let err = displacement_error(&start, &mut dev, &mut cpu);
    assert!(err < 1e-3, "displacements differ by {err:e} of the largest");
    assert!(dev.is_finite());
}

#[test]
fn a_device_lost_while_it_holds_the_newest_state_sends_the_membrane_back_to_its_checkpoint() {
    // A tile woken far from the tool is read by nothing, so its newest state stays on the
    // device. The device goes at step 10: the membrane goes back to the checkpoint taken at
    // step 8 (as its world takes them) and goes on on the CPU, saying so. A run on the CPU
    // that goes back to its own checkpoint at step 10 ends where it does.
    use crate::sim::TissueModel;
    let (_gpu, start, mut cpu, mut dev) = on_both();
    let far = {
        let p = start.position(start.node(1, 44, 4));
        (p - Vec3::splat(1e-4), p + Vec3::splat(1e-4))
    };
    let mut out = crate::sim::ModelOutput::default();
    let mut note = String::new();
    for k in 0..30 {
        for m in [&mut cpu, &mut dev] {
            if k == 0 {
                m.wake_near(&[far]);
            }
            if k == 8 {
                m.checkpoint();
            }
        }
        if k == 10 {
            assert!(dev.gpu_tiles_behind().is_some_and(|n| n > 0), "none behind");
            assert!(dev.inject_device_loss());
            cpu.restore();
        }
        session_step(&mut cpu, k, &mut out);
        session_step(&mut dev, k, &mut out);
        for e in &out.events {
            if let crate::sim::EventKind::ComputeFallback { reason, .. } = e {
                note.clone_from(reason);
            }
        }
    }
    assert!(dev.gpu_adapter().is_none(), "on the CPU from the loss on");
    assert!(note.contains("last checkpoint"), "{note}");
    assert_eq!(awake_tiles(&dev), awake_tiles(&cpu));
    let err = displacement_error(&start, &mut dev, &mut cpu);
    assert!(err < 1e-3, "displacements differ by {err:e} of the largest");
    assert!(dev.is_finite());
}

#[test]
fn on_one_adapter_the_active_set_on_the_gpu_gives_the_same_bytes() {
    let gpu = device();
    let run = || {
        let mut m = sleepy(48, 64);
        m.use_gpu(&gpu).expect("uploads");
        let mut out = crate::sim::ModelOutput::default();
        for k in 0..50 {
            session_step(&mut m, k, &mut out);
        }
        assert!(m.gpu_adapter().is_some());
        m.state_hash()
    };
    let first = run();
    assert_eq!(first, run());
    assert_ne!(first, sleepy(48, 64).state_hash(), "it moved");
}

#[test]
fn tiles_the_device_holds_do_not_go_up_again_and_the_bytes_are_the_same() {
    // The session of the test above with a cut, a checkpoint and a rollback, once sending
    // every synced tile's state up each step and once only what the device lacks (the halo
    // placed at its anchors, tiles that woke, everything after the rollback).
    let gpu = device();
    let run = |resend: bool| {
        // Packed and unpacked tile by tile when everything goes up, through the pool when
        // only what the device lacks does: the same bytes either way.
        crate::models::membrane::active::ALWAYS_THREADS.with(|a| a.set(!resend));
        let mut m = sleepy(48, 64);
        m.use_gpu(&gpu).expect("uploads");
        m.gpu_resend_every_step(resend);
        let mut out = crate::sim::ModelOutput::default();
        for k in 0..60 {
            cut_and_rollback_step(&mut m, k, &mut out);
        }
        assert!(m.gpu_adapter().is_some());
        (m.state_hash(), m.gpu_tiles_sent().expect("on the device"))
    };
    let (all, sent_all) = run(true);
    let (lacking, sent_lacking) = run(false);
    assert_eq!(all, lacking, "the same bytes either way");
    assert_ne!(all, sleepy(48, 64).state_hash(), "it moved");
    assert!(
        sent_lacking < sent_all,
        "{sent_lacking} tiles went up against {sent_all}"
    );
}

#[test]
fn the_device_refuses_tiles_its_kernels_do_not_step_with_a_clear_error() {
    let gpu = device();
    let mut m = tube(16, 32);
    m.use_active_set(ActivityParams {
        tile_rows: 4,
        tile_cols: 4,
        ..ActivityParams::default()
    });
    let e = m.use_gpu(&gpu).expect_err("4 x 4 tiles refused");
    assert!(matches!(e, crate::gpu::RenderError::Unsupported(_)), "{e}");
    let text = e.to_string();
    assert!(text.contains("8 x 16") && text.contains("4 x 4"), "{text}");
    // It stays on the CPU, and steps there.
    assert!(m.gpu_adapter().is_none());
    m.wake(0);
    m.advance(1e-3, 0.9);
    assert!(crate::sim::TissueModel::state_is_finite(&m));
}

#[test]
fn the_device_measures_tiles_falling_asleep_and_waking_as_the_cpu_does() {
    // The pulled tissue settles after the tool lets go: tiles fall asleep on the speeds the
    // device measured (their offsets then taken on the CPU) and the boxes the broad phase
    // reads come from its measures too. Step by step, the same tiles sleep as on the CPU.
    let (_gpu, _start, mut cpu, mut dev) = on_both();
    let mut out = crate::sim::ModelOutput::default();
    let (mut most, mut fell) = (0usize, 0usize);
    for k in 0..260 {
        for m in [&mut cpu, &mut dev] {
            session_step(m, k, &mut out);
            assert!(out.events.is_empty(), "{:?}", out.events);
        }
        let (c, d) = (awake_tiles(&cpu), awake_tiles(&dev));
        assert_eq!(d, c, "step {k}");
        fell = fell.max(most.saturating_sub(d.len()));
        most = most.max(d.len());
        let p = cpu.position(cpu.node(1, 24, 32));
        let (mut near_cpu, mut near_dev) = (Vec::new(), Vec::new());
        cpu.awake_tiles_near(p, p, 2e-3, &mut near_cpu);
        dev.awake_tiles_near(p, p, 2e-3, &mut near_dev);
        assert_eq!(near_dev, near_cpu, "step {k}: the boxes");
    }
    assert!(dev.gpu_adapter().is_some(), "it stayed on the device");
    assert!(fell >= 2, "{fell} of {most} tiles fell asleep");
}

#[test]
fn the_device_places_the_halo_so_only_tiles_that_woke_go_up() {
    // The same session on two devices, one placing the halo (the sleeping tiles beside the
    // awake ones, which change as tiles wake and sleep) itself, one taking it from the CPU
    // as before. Placed on the device, a tile's state goes up only when it woke (at most
    // once a wake, after the first step sends everything); the same tiles sleep and wake
    // as on the CPU, the positions within float rounding.
    let (gpu, start, mut cpu, mut dev) = on_both();
    let mut up = start.clone();
    up.use_gpu(&gpu).expect("uploads");
    up.gpu_place_halo_on_cpu(true);
    let mut out = crate::sim::ModelOutput::default();
    let (mut woke, mut most) = (0usize, 0.0f32);
    let mut before = Vec::new();
    for k in 0..200 {
        for m in [&mut cpu, &mut dev, &mut up] {
            session_step(m, k, &mut out);
            assert!(out.events.is_empty(), "{:?}", out.events);
        }
        let now = awake_tiles(&dev);
        assert_eq!(now, awake_tiles(&cpu), "step {k}");
        assert_eq!(now, awake_tiles(&up), "step {k}");
        woke += now.iter().filter(|t| !before.contains(*t)).count();
        before = now;
        most = (0..cpu.len())
            .map(|n| (cpu.position(n) - start.position(n)).length())
            .fold(most, f32::max);
    }
    let (placed, sent) = (dev.gpu_tiles_sent(), up.gpu_tiles_sent());
    let (placed, sent) = (placed.expect("on the device"), sent.expect("on the device"));
    assert!(woke >= 4, "{woke} tiles woke");
    assert!(
        placed as usize <= woke,
        "{placed} tiles went up for {woke} wakes"
    );
    assert!(
        placed < sent,
        "{placed} tiles went up against {sent} with the CPU's halo"
    );
    // Against the largest displacement of the session (the tissue has settled back since).
    for m in [&mut dev, &mut up] {
        m.catch_up();
        let diff = (0..m.len())
            .map(|n| (m.position(n) - cpu.position(n)).length())
            .fold(0.0f32, f32::max);
        assert!(
            diff < 1e-3 * most,
            "positions differ by {diff:e} m, the most moved {most:e} m"
        );
    }
}

#[test]
fn sleeping_tiles_are_drawn_where_their_anchors_carry_them_though_the_device_placed_them() {
    // Tiles wake round the pulled node; then every layer-0 target moves 0.1 mm (half the
    // wake distance) and both step once. The CPU places the halo on its own copy; the device on its, and the copy the CPU
    // holds of a model on a device lags by the move. Drawn (`carried_position`), the halo is
    // where the CPU put it.
    let (_gpu, _start, mut cpu, mut dev) = on_both();
    let mut out = crate::sim::ModelOutput::default();
    for k in 0..40 {
        session_step(&mut cpu, k, &mut out);
        session_step(&mut dev, k, &mut out);
    }
    let shift = Vec3::new(0.0, 1e-4, 0.0);
    for m in [&mut cpu, &mut dev] {
        m.catch_up();
        for i in 0..m.rows() {
            for j in 0..m.cols() {
                let (target, _) = m.anchor_pull(i, j).expect("in the grid");
                m.set_target(i, j, target + shift);
            }
        }
        session_step(m, 40, &mut out);
    }
    let awake = awake_tiles(&cpu);
    assert_eq!(awake, awake_tiles(&dev));
    let (tr, tc) = cpu.tiles();
    let halo: Vec<usize> = (0..tr * tc)
        .filter(|t| !awake.contains(t))
        .filter(|&t| {
            awake
                .iter()
                .any(|&a| (a / tc).abs_diff(t / tc) <= 1 && (a % tc).abs_diff(t % tc) <= 1)
        })
        .collect();
    assert!(!halo.is_empty(), "awake {awake:?} of {tr} x {tc}");
    let (mut drawn, mut lag) = (0.0f32, 0.0f32);
    for &t in &halo {
        let ([r0, r1], [c0, c1]) = cpu.tile_span(t);
        for (i, j) in (r0..r1).flat_map(|i| (c0..c1).map(move |j| (i, j))) {
            let n = cpu.node(0, i, j);
            drawn = drawn.max((dev.carried_position(n) - cpu.position(n)).length());
            lag = lag.max((dev.position(n) - cpu.position(n)).length());
        }
    }
    assert!(
        lag > 0.9e-4,
        "the device's halo is not on the CPU's copy: {lag:e} m"
    );
    assert!(
        drawn < 1e-7,
        "drawn {drawn:e} m from where the CPU placed it"
    );
}

#[test]
fn tiles_cut_short_by_the_grid_come_back_by_runs_as_the_cpu_steps_them() {
    // 45 x 72 nodes: the last row of tiles holds 5 rows, the last column of tiles 8
    // columns. A tool pulls in that corner and the tiles round it wake; they come back in
    // runs of tiles side by side, the narrow ones among them, each stretch copied into its
    // row. The same tiles wake and sleep as on the CPU, the displacements within float
    // rounding of the largest.
    let gpu = device();
    let start = sleepy(45, 72);
    let (mut cpu, mut dev) = (start.clone(), start.clone());
    dev.use_gpu(&gpu).expect("uploads");
    let node = start.node(1, 42, 68);
    let mut out = crate::sim::ModelOutput::default();
    let (mut most, mut side_by_side) = (0, false);
    for k in 0..60 {
        for m in [&mut cpu, &mut dev] {
            if k < 40 {
                m.read_tiles(&[m.tile_of(42, 68)]);
                let p = m.position(node);
                m.wake_near(&[(p - Vec3::splat(1e-3), p + Vec3::splat(1e-3))]);
                m.add_force(node, Vec3::X * 2e-4);
            }
            out.clear();
            crate::sim::TissueModel::step(m, 1e-3, &[], &mut out);
            assert!(out.events.is_empty(), "{:?}", out.events);
        }
        let awake = awake_tiles(&dev);
        assert_eq!(awake, awake_tiles(&cpu), "step {k}");
        most = most.max(awake.len());
        // The corner tile (row of tiles 5, column 4) and the one before it, in one run.
        side_by_side |= awake.contains(&28) && awake.contains(&29);
    }
    assert_eq!(dev.tiles(), (6, 5));
    assert!(side_by_side, "the corner's tiles never woke side by side");
    assert!(most >= 4, "{most} tiles woke");
    let err = displacement_error(&start, &mut dev, &mut cpu);
    assert!(err < 1e-3, "displacements differ by {err:e} of the largest");
    assert!(dev.gpu_adapter().is_some());
}

#[test]
fn the_sleep_check_tells_the_quarantine_of_a_nan_on_the_device_as_on_the_cpu() {
    // After a few steps the last check found every awake position finite; a NaN put into an
    // awake tile's velocity is stepped into its positions, and the next check (the device's
    // where it steps, the CPU's pass where it does) says so without another pass.
    use crate::sim::TissueModel;
    let (_gpu, _start, mut cpu, mut dev) = on_both();
    let mut out = crate::sim::ModelOutput::default();
    for m in [&mut cpu, &mut dev] {
        for k in 0..10 {
            session_step(m, k, &mut out);
        }
        let measured = |m: &Membrane| m.activity.as_ref().and_then(|a| a.measured_finite);
        assert_eq!(measured(m), Some(true));
        assert!(m.state_is_finite());
        assert!(m.inject_nan());
        assert_eq!(measured(m), None, "the check no longer holds");
        session_step(m, 10, &mut out);
        assert_eq!(measured(m), Some(false));
        assert!(!m.state_is_finite());
    }
    assert!(dev.gpu_adapter().is_some(), "it stayed on the device");
}

#[test]
fn the_bench_line_reads_a_step_and_its_time_on_the_gpu_clock_in_one_round_trip() {
    // Each timed step's probe of the state and the pass's timestamps come back together:
    // the GPU's own time of a step's substeps is read from the same mapping as the probe,
    // so it must be positive and within the wall time of the steps it was summed over.
    let gpu = device();
    let m = sleepy(24, 32);
    let line = super::gpu::bench_line(&gpu, &m, 1e-3, 0.9, 0.2, super::gpu::Layout::Flat)
        .expect("a line on the adapter there is");
    let c = &line.compute;
    assert!(line.steps >= 5, "{} steps", line.steps);
    let n = c.substeps_per_step.expect("substeps");
    assert_eq!(n, m.substeps_for(1e-3, 0.9));
    let check = c.check_rel_err.expect("checked against the CPU");
    assert!(check.is_finite() && check < 1e-3, "{check}");
    let wall = c.wall_s.expect("wall time");
    let p99 = c.latency_p99_ms.expect("latency") * 1e-3;
    assert!(p99 > 0.0 && p99 <= wall, "p99 {p99} s of {wall} s");
    let timestamps = gpu
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY);
    assert_eq!(c.kernel_s.is_some(), timestamps);
    if let Some(k) = c.kernel_s {
        assert!(k > 0.0 && k < wall, "{k} s on the GPU's clock in {wall} s");
    }
}

#[test]
fn a_query_brings_back_the_tiles_a_millimetre_beyond_its_reach_and_no_others() {
    use crate::sim::TissueModel;
    let gpu = device();
    let mut m = sleepy(48, 64);
    m.use_gpu(&gpu).expect("uploads");
    let mut out = crate::sim::ModelOutput::default();
    // Every tile awake (none still long enough to be about to fall asleep).
    let everywhere = (Vec3::splat(-1.0), Vec3::splat(1.0));
    for _ in 0..3 {
        m.wake_near(&[everywhere]);
        out.clear();
        TissueModel::step(&mut m, 1e-3, &[], &mut out);
    }
    let (tr, tc) = m.tiles();
    let awake: Vec<usize> = (0..tr * tc).filter(|&t| m.tile_awake(t)).collect();
    assert_eq!(awake.len(), tr * tc);
    // How far each tile's box lies from the point, along the axis where it lies furthest.
    m.catch_up();
    let p = m.position(m.node(1, 24, 32));
    let gap = |m: &Membrane, t: usize| {
        let (lo, hi) = m
            .activity
            .as_ref()
            .and_then(|a| a.tile_box(t))
            .expect("a box");
        (lo - p).max(p - hi).max(Vec3::ZERO).max_element()
    };
    let within = |m: &Membrane, reach: f32| -> Vec<usize> {
        awake
            .iter()
            .copied()
            .filter(|&t| gap(m, t) <= reach)
            .collect()
    };
    // Tiles lie 0, 0.26, 0.98 (two), 2.04 (two) mm and further from it.
    let margin = 0.5e-3;
    let reach_ahead = margin + super::active::AHEAD_M;
    let (read_expected, ahead) = (within(&m, margin), within(&m, reach_ahead));
    let mut read = Vec::new();
    m.awake_tiles_near(p, p, margin, &mut read);
    assert_eq!(read, read_expected);
    assert!(
        read.len() < ahead.len() && ahead.len() < awake.len(),
        "{} read, {} within a millimetre more, {} awake",
        read.len(),
        ahead.len(),
        awake.len()
    );
    out.clear();
    TissueModel::step(&mut m, 1e-3, &[], &mut out);
    // Those within the reach and the millimetre beyond came back with the step; the others
    // lag on the CPU until something reads them.
    for &t in &awake {
        assert_eq!(
            m.gpu_tile_behind(t),
            Some(!ahead.contains(&t)),
            "tile {t}, {:.2} mm away",
            gap(&m, t) * 1e3
        );
    }
}
