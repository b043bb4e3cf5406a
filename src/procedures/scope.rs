//! The laparoscope a hand's device can drive (`ProcedureInfo::scope_hand`; the rectum paper:
//! "The left haptic device can also be used as a navigation camera"; the cholecystectomy
//! paper's camera tool). While that hand's primary button is held the device carries the
//! camera as if it held the scope: every motion of the device since the button went down
//! moves the camera's eye and target rigidly with it, and the hand's instrument stays where it
//! was. When the button comes up the instrument follows the device again from where it was
//! left (a clutch: the device's later motions move it, so nothing jumps).
//!
//! The camera is the procedure's state, driven by the recorded input: a replay shows the
//! same views, and the snapshot carries it to the renderers ([`crate::sim::ScopeView`]).

use crate::procedures::Viewpoint;
use crate::sim::Pose;
use glam::{Quat, Vec3};

/// A rigid motion: `p -> rotation * p + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rigid {
    rotation: Quat,
    translation: Vec3,
}

impl Rigid {
    const IDENTITY: Rigid = Rigid {
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
    };

    /// The motion that puts the origin's frame on `pose`.
    fn of(pose: &Pose) -> Rigid {
        Rigid {
            rotation: pose.orientation.normalize(),
            translation: pose.position,
        }
    }

    fn apply(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// `self` after `other`.
    fn then_after(&self, other: &Rigid) -> Rigid {
        Rigid {
            rotation: (self.rotation * other.rotation).normalize(),
            translation: self.rotation * other.translation + self.translation,
        }
    }

    fn inverse(&self) -> Rigid {
        let r = self.rotation.inverse();
        Rigid {
            rotation: r,
            translation: -(r * self.translation),
        }
    }

    fn pose(&self) -> Pose {
        Pose {
            position: self.translation,
            orientation: self.rotation,
        }
    }
}

/// The camera and the clutch between the left device and its instrument.
#[derive(Debug, Clone, PartialEq)]
pub struct Scope {
    view: Viewpoint,
    /// The procedure's own viewpoint, where the camera starts.
    home: Viewpoint,
    /// The instrument is this motion after the device.
    offset: Rigid,
    /// While the button is held: the device and the camera when it went down, and the
    /// instrument held where it was.
    held: Option<(Rigid, Viewpoint, Rigid)>,
}

impl Scope {
    pub fn new(home: Viewpoint) -> Scope {
        Scope {
            view: home,
            home,
            offset: Rigid::IDENTITY,
            held: None,
        }
    }

    /// One step: the left device's pose and whether its primary button is down. Returns the
    /// pose of the instrument in that hand.
    pub fn update(&mut self, device: &Pose, button: bool) -> Pose {
        if !device.is_finite() {
            return self.instrument_for(&Rigid::IDENTITY);
        }
        let now = Rigid::of(device);
        match (button, self.held) {
            (true, None) => {
                let tool = self.offset.then_after(&now);
                self.held = Some((now, self.view, tool));
                tool.pose()
            }
            (true, Some((from, view, tool))) => {
                // The device's motion since the button went down, applied to the camera.
                let moved = now.then_after(&from.inverse());
                self.view = Viewpoint {
                    eye: moved.apply(view.eye),
                    target: moved.apply(view.target),
                };
                tool.pose()
            }
            (false, Some((_, _, tool))) => {
                // Let go: the instrument stays, and follows the device from here on.
                self.offset = tool.then_after(&now.inverse());
                self.held = None;
                tool.pose()
            }
            (false, None) => self.offset.then_after(&now).pose(),
        }
    }

    fn instrument_for(&self, device: &Rigid) -> Pose {
        match self.held {
            Some((_, _, tool)) => tool.pose(),
            None => self.offset.then_after(device).pose(),
        }
    }

    /// The camera now.
    #[cfg(test)]
    fn view(&self) -> Viewpoint {
        self.view
    }

    /// The camera, once it has left the procedure's viewpoint.
    /// [`Scope::moved_view`] as the snapshot carries it.
    pub fn snapshot_view(&self) -> Option<crate::sim::ScopeView> {
        self.moved_view().map(|v| crate::sim::ScopeView {
            eye: v.eye,
            target: v.target,
        })
    }

    pub fn moved_view(&self) -> Option<Viewpoint> {
        (self.view != self.home).then_some(self.view)
    }

    /// Whether the device drives the camera now.
    #[cfg(test)]
    fn driving(&self) -> bool {
        self.held.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(p: Vec3, yaw: f32) -> Pose {
        Pose {
            position: p,
            orientation: Quat::from_rotation_y(yaw),
        }
    }

    fn home() -> Viewpoint {
        Viewpoint {
            eye: Vec3::new(0.0, 0.2, 0.1),
            target: Vec3::ZERO,
        }
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        a.distance(b) < 1e-5
    }

    #[test]
    fn the_device_carries_the_camera_while_held_and_the_instrument_waits() {
        let home = home();
        let mut s = Scope::new(home);
        // Free: the instrument is the device.
        let a = pose(Vec3::new(0.05, 0.1, 0.0), 0.0);
        assert_eq!(s.update(&a, false), a);
        assert_eq!(s.moved_view(), None);
        // Held: the device moves 2 cm along x and turns 90 degrees about y.
        let start = s.update(&a, true);
        assert_eq!(start, a);
        let b = pose(Vec3::new(0.07, 0.1, 0.0), std::f32::consts::FRAC_PI_2);
        let tool = s.update(&b, true);
        assert!(s.driving());
        assert!(close(tool.position, a.position), "{tool:?}");
        // The camera moved rigidly with the device: about the device's old place, turned,
        // then carried to its new place.
        let turn = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let expect = |p: Vec3| turn * (p - a.position) + b.position;
        let v = s.view();
        assert!(close(v.eye, expect(home.eye)), "{v:?}");
        assert!(close(v.target, expect(home.target)), "{v:?}");
        assert!(close(v.eye - v.target, turn * (home.eye - home.target)));
        // Let go: nothing jumps, and the device's next motion moves the instrument by as much
        // in the instrument's own frame.
        let left = s.update(&b, false);
        assert!(close(left.position, a.position));
        assert!(!s.driving());
        let c = pose(
            b.position + Vec3::new(0.0, 0.0, -0.01),
            std::f32::consts::FRAC_PI_2,
        );
        let after = s.update(&c, false);
        // The device went 1 cm along the world's -z, which is its own +x now that it is
        // turned; the instrument, unturned, goes along its own +x, the world's +x.
        assert!(
            close(after.position, a.position + Vec3::new(0.01, 0.0, 0.0)),
            "{after:?}"
        );
        // The camera stays where it was left.
        assert_eq!(s.view(), v);
        assert_eq!(s.moved_view(), Some(v));
    }

    #[test]
    fn a_device_pose_that_is_not_finite_moves_nothing() {
        let home = home();
        let mut s = Scope::new(home);
        let a = pose(Vec3::new(0.05, 0.1, 0.0), 0.0);
        s.update(&a, true);
        let bad = pose(Vec3::NAN, 0.0);
        let tool = s.update(&bad, true);
        assert_eq!(tool, a);
        assert_eq!(s.view(), home);
    }
}
