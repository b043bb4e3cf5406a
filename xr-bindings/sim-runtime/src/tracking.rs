//! Where things are: the head and the controllers move as the trace says (`[[head]]`,
//! `[[left]]`, `[[right]]` keys in the operating field's frame, placed in the room by
//! `xr_bindings::stage`, moving as its `interpolation` says and shaken by its `[[tremor]]`),
//! at any display time, so the app sees the same motion however fast it renders; and whether
//! a controller is there (the trace moves it and no injected loss covers the time).

use crate::pose::Rigid;
use crate::state::Runtime;
use crate::system::FIRST_DISPLAY_NS;
use glam::{Mat3, Quat, Vec3};

/// Trace time, seconds, of a display time in nanoseconds (0 at the first frame).
pub(crate) fn trace_time_s(display_ns: i64) -> f64 {
    ((display_ns - FIRST_DISPLAY_NS) as f64 / 1e9).max(0.0)
}

/// An orientation whose -Z points from `from` to `to`, +Y as near up as it can be (the head).
fn looking(from: Vec3, to: Vec3) -> Quat {
    let forward = (to - from).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
    let up = right.cross(forward);
    Quat::from_mat3(&Mat3::from_cols(right, up, -forward)).normalize()
}

/// The head (the eyes' midpoint) in STAGE at a display time.
pub(crate) fn head_at(rt: &Runtime, display_ns: i64) -> Rigid {
    let t = trace_time_s(display_ns);
    let (p, target) = match rt.trace.as_ref() {
        Some(trace) => trace.sample_head_of(t),
        None => xr_bindings::keyframes::sample_head(&[], t),
    };
    Rigid {
        rot: looking(p, target),
        pos: xr_bindings::stage::field_to_stage(p),
    }
}

/// A controller's aim pose in STAGE at a display time: where the trace puts the instrument,
/// its -Z towards the target (the app's convention), turned by its roll. `None` for a hand
/// the trace leaves out.
pub(crate) fn hand_at(rt: &Runtime, hand: usize, display_ns: i64) -> Option<Rigid> {
    let trace = rt.trace.as_ref()?;
    let s = trace.sample_hand_of(hand, trace_time_s(display_ns))?;
    Some(Rigid {
        rot: xr_bindings::keyframes::hand_orientation(s.position, s.target, s.roll_deg),
        pos: xr_bindings::stage::field_to_stage(s.position),
    })
}

/// Whether a hand's controller is there at a display time: the trace moves it and no injected
/// controller loss covers the time.
pub(crate) fn present(rt: &Runtime, hand: usize, display_ns: i64) -> bool {
    let t = trace_time_s(display_ns);
    let lost = rt.config.as_ref().is_some_and(|c| {
        c.inject
            .controller_loss
            .iter()
            .any(|l| l.hand.index() == hand && l.from_s <= t && t < l.to_s)
    });
    !lost && hand_at(rt, hand, display_ns).is_some()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_looking_orientation_points_minus_z_at_the_target_with_y_up() {
        let q = looking(Vec3::new(0.0, 1.6, 0.0), Vec3::new(0.0, 1.0, -0.6));
        let fwd = q * Vec3::NEG_Z;
        assert!((fwd - Vec3::new(0.0, -0.6, -0.6).normalize()).length() < 1e-5);
        assert!((q * Vec3::X - Vec3::X).length() < 1e-5, "no roll");
    }
}
