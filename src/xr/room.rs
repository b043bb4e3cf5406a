//! The headset's room for a procedure whose scenario shows a monitor
//! ([`crate::scenario::HeadsetView::Monitor`]): where the monitor stands, and the ports the
//! laparoscopic instruments pass through.
//!
//! The trainee stands as in the scope view (the field where the hands work, 16 cm ahead of and
//! 7 cm below the eyes; see `xr_bindings::stage`), but the eyes look past it at a monitor
//! across the table, as a laparoscopic surgeon does. Each laparoscopic instrument's shaft then
//! runs from its port to the tip in the trainee's hand: the controller gives the tip and the
//! roll about the shaft, the port the shaft's direction (a trocar's fulcrum).

use crate::procedures::{ProcedureInfo, ToolKind};
use crate::render::monitor::MonitorSpec;
use crate::sim::Pose;
use glam::{Quat, Vec3};
use xr_bindings::stage::{DEFAULT_HEAD, stage_to_field};

/// The monitor's centre in STAGE coordinates, metres: 1 m ahead of a trainee's eyes, its
/// centre 5 cm below them (a boom monitor across the table).
pub const MONITOR_IN_STAGE_M: [f32; 3] = [0.0, 1.55, -1.0];
/// The screen's width, metres: a 36-inch 16:9 surgical monitor (0.8 m wide), which at 1 m
/// spans 44 degrees, about two fifths of a Vive's view.
pub const MONITOR_WIDTH_M: f32 = 0.8;
/// The picture's size, pixels (16:9; across 44 degrees the Vive's eye shows about 430 of
/// them, so the picture is not what limits the detail).
pub const MONITOR_PIXELS: (u32, u32) = (960, 540);
/// Closer to its port than this, a tip keeps the controller's own direction (the shaft's
/// direction is undefined at the port), metres.
pub const MIN_PORT_DISTANCE_M: f32 = 0.01;

/// The monitor for a procedure: its laparoscope's view (the procedure's viewpoint and its
/// scope's angle) on a screen facing the default head.
pub fn monitor(info: &ProcedureInfo) -> MonitorSpec {
    let centre = stage_to_field(Vec3::from(MONITOR_IN_STAGE_M));
    let head = Vec3::from(DEFAULT_HEAD.0);
    MonitorSpec::facing(
        centre,
        head,
        MONITOR_WIDTH_M,
        MONITOR_PIXELS,
        info.view,
        (info.field)().scope.fov_deg,
    )
}

/// The port each hand's instrument passes through in the monitor's room: the procedure's
/// parking point over the field for a laparoscopic instrument (grasper, probe, hook), none
/// for a laser or a steerable instrument (held freely).
pub fn ports(info: &ProcedureInfo) -> [Option<Vec3>; 2] {
    let mut out = [None; 2];
    for (k, tool) in info.tools.iter().enumerate() {
        if matches!(
            tool.kind,
            ToolKind::Grasper | ToolKind::Probe | ToolKind::Hook
        ) {
            out[k] = Some(info.desk_park[k]);
        }
    }
    out
}

/// An instrument whose tip is at `pose` and whose shaft passes through `port`: the shaft runs
/// from the port through the tip, turned the least from the controller's aim, so the roll
/// about it is the controller's. A tip within [`MIN_PORT_DISTANCE_M`] of its port keeps the
/// controller's pose.
pub fn through_port(pose: Pose, port: Vec3) -> Pose {
    let d = pose.position - port;
    let length = d.length();
    if !pose.is_finite() || !length.is_finite() || length < MIN_PORT_DISTANCE_M {
        return pose;
    }
    let turn = Quat::from_rotation_arc(pose.forward().normalize_or(Vec3::NEG_Z), d / length);
    Pose {
        position: pose.position,
        orientation: (turn * pose.orientation).normalize(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shaft_runs_from_its_port_through_the_tip_keeping_the_hands_roll() {
        let port = Vec3::new(0.0, 0.1, 0.1);
        let tip = Vec3::new(0.02, 0.0, 0.0);
        // The controller aims somewhere else, rolled 40 degrees about its aim.
        let aim = Quat::from_rotation_arc(Vec3::NEG_Z, Vec3::new(0.3, -0.2, -1.0).normalize())
            * Quat::from_rotation_z(40f32.to_radians());
        let held = Pose {
            position: tip,
            orientation: aim,
        };
        let p = through_port(held, port);
        assert_eq!(p.position, tip);
        let shaft = (tip - port).normalize();
        assert!(p.forward().dot(shaft) > 1.0 - 1e-6, "{}", p.forward());
        // The roll: the least turn carries the controller's up along; its part across the
        // shaft is what the hand's up is across the shaft.
        let up = |q: Quat| q * Vec3::Y;
        let across = |v: Vec3, axis: Vec3| (v - axis * v.dot(axis)).normalize();
        let was = across(up(aim), aim * Vec3::NEG_Z);
        let turn = Quat::from_rotation_arc(aim * Vec3::NEG_Z, shaft);
        assert!(across(up(p.orientation), shaft).dot(turn * was) > 1.0 - 1e-5);
        // Already along the shaft: unchanged.
        let along = Pose::looking_at(tip, tip + shaft);
        let q = through_port(along, port);
        assert!(q.orientation.dot(along.orientation).abs() > 1.0 - 1e-6);
        // At the port: the controller's own pose.
        let at = Pose {
            position: port + Vec3::X * 0.005,
            orientation: aim,
        };
        assert_eq!(through_port(at, port), at);
    }

    #[test]
    fn the_monitor_stands_across_the_table_facing_the_trainee() {
        let head = Vec3::from(DEFAULT_HEAD.0);
        for info in crate::registry::REGISTRY {
            let m = monitor(info);
            // Ahead of the eyes, beyond the field, its picture toward them and upright.
            assert!((m.centre - head).length() > 0.9);
            let normal = m.half_width.cross(m.half_height).normalize();
            assert!(normal.dot((head - m.centre).normalize()) > 0.99, "{normal}");
            assert!((2.0 * m.half_width.length() - MONITOR_WIDTH_M).abs() < 1e-6);
            assert_eq!(m.view, info.view);
            // Laparoscopic instruments pass ports; a laser or a steerable one is held freely.
            for (tool, port) in info.tools.iter().zip(ports(info)) {
                let through = !matches!(tool.kind, ToolKind::Laser | ToolKind::Steerable);
                assert_eq!(port.is_some(), through, "{}: {:?}", info.name, tool.kind);
            }
        }
    }
}
