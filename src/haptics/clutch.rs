//! Styluses bound to a procedure's instruments: each device drives one hand's instrument
//! through its own [`Workspace`], with a clutch that lets the trainee re-centre the hand.
//!
//! Buttons: bit 0 is the instrument's trigger (a laser cuts), bit 1 its grip (jaws close).
//! The clutch is the third button (bit 2) on a device that has one (Falcon); on a two-button
//! stylus (Phantom Omni, Touch) it is both buttons held together. While the clutch is held the
//! instrument stays where it is, its trigger and grip as they were, and the device renders no
//! force; when it is let go, the workspace is shifted so that the instrument carries on from
//! where it stayed, wherever the stylus now is (indexing, as on a surgical robot's master).

use super::device::{DeviceKind, DeviceState};
use super::render::Workspace;
use crate::procedures::ProcedureInfo;
use crate::sim::{Buttons, Hand, InputFrame, Pose};
use glam::Vec3;

/// The third button: the clutch on a device with three or more.
pub const CLUTCH_BUTTON: u32 = 1 << 2;
/// Both buttons of a two-button stylus: the clutch there.
pub const BOTH_BUTTONS: u32 = 0b11;
/// How far apart two devices' workspace origins land in the field, along x, m (each hand
/// works its own side of the procedure's target).
pub const HANDS_APART_M: f32 = 0.04;

impl DeviceKind {
    /// Buttons on the stylus or grip.
    pub fn buttons(self) -> u32 {
        match self {
            DeviceKind::PhantomOmni | DeviceKind::Touch => 2,
            DeviceKind::Simulated | DeviceKind::Falcon => 4,
            DeviceKind::Omega3 => 1,
        }
    }

    /// Whether `buttons` hold this device's clutch.
    pub fn clutched(self, buttons: u32) -> bool {
        if self.buttons() >= 3 {
            buttons & CLUTCH_BUTTON != 0
        } else {
            buttons & BOTH_BUTTONS == BOTH_BUTTONS
        }
    }
}

/// Where a device bound to `hand` starts: `scale` field metres per device metre, its origin
/// [`super::stand::ORIGIN_ABOVE_TARGET_M`] above the procedure's target, and, when `of_two`,
/// half of [`HANDS_APART_M`] to the hand's side.
pub fn hand_workspace(info: &ProcedureInfo, hand: Hand, of_two: bool, scale: f64) -> Workspace {
    let mut w = Workspace::for_procedure(info);
    w.scale = scale;
    if of_two {
        let side = match hand {
            Hand::Left => -0.5,
            Hand::Right => 0.5,
        };
        w.offset_m += Vec3::X * (side * HANDS_APART_M);
    }
    w
}

/// One device's binding: its hand, its workspace (moved by the clutch) and what its
/// instrument did last.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Binding {
    pub hand: Hand,
    pub kind: DeviceKind,
    pub workspace: Workspace,
    /// Whether the clutch was held at the last update.
    pub clutched: bool,
    /// The instrument's last position and buttons (held while clutched).
    pub tool_m: Vec3,
    pub buttons: Buttons,
    /// Times the clutch was let go (the workspace re-anchored).
    pub reanchors: u32,
}

impl Binding {
    pub fn new(hand: Hand, kind: DeviceKind, workspace: Workspace) -> Binding {
        Binding {
            hand,
            kind,
            workspace,
            clutched: false,
            tool_m: workspace.offset_m,
            buttons: Buttons::default(),
            reanchors: 0,
        }
    }

    /// Takes the stylus' newest state (a non-finite one changes nothing): the instrument
    /// follows it unless the clutch is held.
    pub fn update(&mut self, stylus: &DeviceState) {
        if !stylus.position_m.is_finite() {
            return;
        }
        let clutched = self.kind.clutched(stylus.buttons);
        if clutched {
            self.clutched = true;
            return;
        }
        if self.clutched {
            // Let go: the instrument carries on from where it stayed.
            let at = self.workspace.to_field(stylus.position_m);
            self.workspace.offset_m += self.tool_m - at;
            self.clutched = false;
            self.reanchors += 1;
        }
        self.tool_m = self.workspace.to_field(stylus.position_m);
        self.buttons = Buttons {
            trigger: f32::from(u8::from(stylus.buttons & 1 != 0)),
            grip: f32::from(u8::from(stylus.buttons & 2 != 0)),
            mark: false,
            pad: None,
        };
    }
}

/// One step's input: each bound instrument where its stylus puts it, pointing down; an
/// instrument no device holds parked where the desktop mode parks it.
pub fn bound_frame(info: &ProcedureInfo, bindings: &[Binding]) -> InputFrame {
    let down = |p: Vec3| Pose::looking_at(p, p - Vec3::Y);
    let mut frame = InputFrame::default();
    for h in Hand::BOTH {
        frame.hands[h.index()].pose = down(info.desk_park[h.index()]);
    }
    for b in bindings {
        let hand = &mut frame.hands[b.hand.index()];
        hand.pose = down(b.tool_m);
        hand.buttons = b.buttons;
    }
    frame
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::haptics::stand::device_position_for;

    fn state(w: &Workspace, at: Vec3, buttons: u32) -> DeviceState {
        DeviceState {
            position_m: device_position_for(w, at),
            buttons,
            ..DeviceState::default()
        }
    }

    #[test]
    fn the_clutch_holds_the_instrument_and_lets_it_carry_on_from_there() {
        let info = &crate::procedures::sandbox::INFO;
        let w = hand_workspace(info, Hand::Right, false, 2.0);
        let mut b = Binding::new(Hand::Right, DeviceKind::Falcon, w);
        // Follows the stylus, scaled: 1 cm of device is 2 cm of field.
        let start = DeviceState {
            position_m: glam::DVec3::new(0.01, 0.0, 0.0),
            buttons: 2,
            ..DeviceState::default()
        };
        b.update(&start);
        assert!(b.tool_m.distance(w.offset_m + Vec3::X * 0.02) < 1e-6);
        assert_eq!((b.buttons.trigger, b.buttons.grip), (0.0, 1.0));
        let held = b.tool_m;
        // Clutch held: the stylus moves 3 cm, the instrument stays, jaws as they were.
        let mut moved = start;
        moved.position_m.x += 0.03;
        moved.buttons = CLUTCH_BUTTON;
        b.update(&moved);
        assert_eq!(b.tool_m, held);
        assert_eq!(b.buttons.grip, 1.0);
        assert!(b.clutched);
        // Let go: no jump; then it follows again from there.
        moved.buttons = 0;
        b.update(&moved);
        assert!(b.tool_m.distance(held) < 1e-6, "{} vs {held}", b.tool_m);
        assert_eq!((b.reanchors, b.clutched, b.buttons.grip), (1, false, 0.0));
        moved.position_m.y -= 0.005;
        b.update(&moved);
        assert!(b.tool_m.distance(held - Vec3::Y * 0.01) < 1e-6);
        // A non-finite reading changes nothing.
        moved.position_m.x = f64::NAN;
        let before = b;
        b.update(&moved);
        assert_eq!(b, before);
    }

    #[test]
    fn a_two_button_stylus_clutches_with_both_buttons() {
        assert!(DeviceKind::PhantomOmni.clutched(BOTH_BUTTONS));
        assert!(!DeviceKind::PhantomOmni.clutched(1));
        assert!(!DeviceKind::PhantomOmni.clutched(2));
        assert!(!DeviceKind::Falcon.clutched(BOTH_BUTTONS));
        assert!(DeviceKind::Falcon.clutched(CLUTCH_BUTTON | 1));
    }

    #[test]
    fn two_devices_drive_both_hands_side_by_side() {
        let info = &crate::procedures::nephrectomy::INFO;
        let l = hand_workspace(info, Hand::Left, true, 1.0);
        let r = hand_workspace(info, Hand::Right, true, 1.0);
        assert!((r.offset_m - l.offset_m - Vec3::X * HANDS_APART_M).length() < 1e-6);
        let mut left = Binding::new(Hand::Left, DeviceKind::PhantomOmni, l);
        let mut right = Binding::new(Hand::Right, DeviceKind::PhantomOmni, r);
        let target = info.view.target;
        left.update(&state(&l, target - Vec3::X * 0.01, 1));
        right.update(&state(&r, target + Vec3::X * 0.01, 0));
        let f = bound_frame(info, &[left, right]);
        assert!(
            f.hand(Hand::Left)
                .pose
                .position
                .distance(target - Vec3::X * 0.01)
                < 1e-6
        );
        assert!(
            f.hand(Hand::Right)
                .pose
                .position
                .distance(target + Vec3::X * 0.01)
                < 1e-6
        );
        assert_eq!(f.hand(Hand::Left).buttons.trigger, 1.0);
        assert!(f.hand(Hand::Left).pose.forward().distance(-Vec3::Y) < 1e-6);
        // One device: the other instrument is parked.
        let f = bound_frame(info, &[right]);
        assert_eq!(f.hand(Hand::Left).pose.position, info.desk_park[0]);
    }
}
