//! Checkpoints of a membrane stepping on a device (lavapipe here): an announced checkpoint
//! takes the tiles that lag on the CPU from the step before it, not from a round trip of
//! its own, and a device lost between that step and its checkpoint loses nothing.

use super::Membrane;
use super::gpu_tests::{device, session_step, sleepy};
use crate::sim::{ModelOutput, TissueModel};
use glam::Vec3;

/// The sleepy tube twice on one device, with a tile woken far from the tool in both (read by
/// nothing, so its newest state stays on the device).
pub(super) fn two_on_one_device() -> (crate::gpu::Gpu, Membrane, Membrane) {
    let gpu = device();
    let start = sleepy(48, 64);
    let far = {
        let p = start.position(start.node(1, 44, 4));
        (p - Vec3::splat(1e-4), p + Vec3::splat(1e-4))
    };
    let (mut told, mut untold) = (start.clone(), start);
    for m in [&mut told, &mut untold] {
        m.use_gpu(&gpu).expect("uploads");
        m.wake_near(&[far]);
    }
    (gpu, told, untold)
}

fn catch_ups(m: &Membrane) -> u64 {
    m.gpu_readback_counts().map_or(0, |(_, c)| c)
}

#[test]
fn an_announced_checkpoint_takes_the_lagging_tiles_from_its_step_without_a_round_trip() {
    // Both take a checkpoint every 8 steps and go back to one at step 29; only one announces
    // its checkpoints before the step, as a world does. A test build checks every checkpoint
    // against the device's whole state (`Membrane::save`), and the two end on the same bytes.
    let (_gpu, mut told, mut untold) = two_on_one_device();
    let mut out = ModelOutput::default();
    let mut lagging_at_checkpoints = 0;
    for k in 0..40 {
        for (m, announce) in [(&mut told, true), (&mut untold, false)] {
            let due = k % 8 == 7;
            if announce && due {
                m.checkpoint_follows();
            }
            session_step(m, k, &mut out);
            if due {
                let (lagging, before) = (m.gpu_tiles_behind().unwrap_or(0), catch_ups(m));
                m.checkpoint();
                if announce {
                    lagging_at_checkpoints += lagging;
                    assert_eq!(catch_ups(m), before, "step {k}: a round trip");
                    assert_eq!(m.gpu_tiles_behind(), Some(lagging), "step {k}");
                } else if lagging > 0 {
                    assert_eq!(catch_ups(m), before + 1, "step {k}");
                    assert_eq!(m.gpu_tiles_behind(), Some(0), "step {k}");
                }
            }
            if k == 29 {
                m.restore();
            }
        }
    }
    assert!(lagging_at_checkpoints > 0, "no tile lagged at a checkpoint");
    assert!(told.gpu_adapter().is_some() && untold.gpu_adapter().is_some());
    assert_eq!(told.state_hash(), untold.state_hash());
}

#[test]
fn a_device_lost_between_an_announced_step_and_its_checkpoint_loses_nothing() {
    // The step before a checkpoint leaves a tile lagging (its newest nodes only in the
    // checkpoint's copy and on the device), then the device goes while the CPU reads it. The
    // membrane goes on on the CPU from its newest state: the state of the run whose device
    // stays, brought up to date, to the bit, and no word of a rollback.
    let (_gpu, mut told, mut untold) = two_on_one_device();
    let mut out = ModelOutput::default();
    for k in 0..8 {
        if k == 7 {
            told.checkpoint_follows();
        }
        session_step(&mut told, k, &mut out);
        session_step(&mut untold, k, &mut out);
    }
    assert!(told.gpu_tiles_behind().is_some_and(|n| n > 0), "none lags");
    untold.catch_up();
    assert!(told.inject_device_loss());
    told.catch_up();
    assert!(told.gpu_adapter().is_none(), "on the CPU from the loss on");
    let note = told.take_device_note().unwrap_or_default();
    assert!(!note.is_empty() && !note.contains("checkpoint"), "{note}");
    assert_eq!(told.state_hash(), untold.state_hash());
    // The world's checkpoint follows, and a rollback to it finds the same state.
    told.checkpoint();
    told.restore();
    assert_eq!(told.state_hash(), untold.state_hash());
    assert!(told.is_finite());
}
