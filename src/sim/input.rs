use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};
pub use xr_bindings::keyframes::PadDirection;

/// Which hand. Index 0 is left, 1 is right.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Hand {
    Left,
    Right,
}

impl Hand {
    pub const BOTH: [Hand; 2] = [Hand::Left, Hand::Right];
    pub fn index(self) -> usize {
        match self {
            Hand::Left => 0,
            Hand::Right => 1,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Hand::Left => "left",
            Hand::Right => "right",
        }
    }
}

/// A rigid pose: position in metres, orientation as a unit quaternion. The instrument points
/// along its local -Z axis (the OpenXR aim-pose convention).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: Vec3,
    pub orientation: Quat,
}

impl Default for Pose {
    fn default() -> Self {
        Self {
            position: Vec3::ZERO,
            orientation: Quat::IDENTITY,
        }
    }
}

impl Pose {
    pub fn forward(&self) -> Vec3 {
        self.orientation * Vec3::NEG_Z
    }

    /// A pose at `position` whose forward axis points at `target`.
    pub fn looking_at(position: Vec3, target: Vec3) -> Self {
        let dir = (target - position).normalize_or_zero();
        let orientation = if dir == Vec3::ZERO {
            Quat::IDENTITY
        } else {
            Quat::from_rotation_arc(Vec3::NEG_Z, dir)
        };
        Self {
            position,
            orientation,
        }
    }

    pub fn is_finite(&self) -> bool {
        self.position.is_finite() && self.orientation.is_finite()
    }
}

/// Buttons and analogue triggers, each in [0, 1].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Buttons {
    /// Trigger: cuts with the laser.
    pub trigger: f32,
    /// Grip: closes the grasper.
    pub grip: f32,
    /// Primary button: places a margin mark where the laser points.
    pub mark: bool,
    /// The trackpad clicked at an edge (or the thumbstick pushed and pressed): a d-pad press,
    /// which a procedure may use for controls of its own (a C-arm's angles). The click is
    /// down with it (`mark`).
    #[serde(default)]
    pub pad: Option<PadDirection>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct HandInput {
    pub pose: Pose,
    pub buttons: Buttons,
}

/// Everything the devices said for one simulation step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct InputFrame {
    pub hands: [HandInput; 2],
}

impl InputFrame {
    pub fn hand(&self, h: Hand) -> &HandInput {
        &self.hands[h.index()]
    }

    /// How far each hand (left, right) has moved since `prev`, metres.
    pub fn moved_since(&self, prev: &InputFrame) -> [f32; 2] {
        [0, 1].map(|k| {
            self.hands[k]
                .pose
                .position
                .distance(prev.hands[k].pose.position)
        })
    }

    pub fn is_finite(&self) -> bool {
        self.hands.iter().all(|h| {
            h.pose.is_finite() && h.buttons.trigger.is_finite() && h.buttons.grip.is_finite()
        })
    }
}
