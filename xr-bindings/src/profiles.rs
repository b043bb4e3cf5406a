//! Interaction profiles as data: `profiles/*.toml` map Vesalius' actions to each controller's
//! input and output paths. The application suggests every profile's bindings to the runtime,
//! which picks the one matching the controllers in the trainee's hands.

use serde::Deserialize;
use std::collections::BTreeMap;

/// What an action reads or drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActionKind {
    Pose,
    Float,
    Bool,
    Vec2,
    Haptic,
}

/// Vesalius' actions, each on both hands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Action {
    /// Where the hand holds the controller: the instrument's handle.
    GripPose,
    /// The pointing ray: the laser pointer's beam.
    AimPose,
    /// 0..1: cut (laser), close the jaws (grasper).
    Trigger,
    /// Grip button: hold to clutch the instrument.
    Squeeze,
    /// Trackpad or thumbstick position, -1..1 each axis.
    Trackpad,
    TrackpadClick,
    Menu,
    /// Vibration on contact.
    Haptic,
}

impl Action {
    pub const ALL: [Action; 8] = [
        Action::GripPose,
        Action::AimPose,
        Action::Trigger,
        Action::Squeeze,
        Action::Trackpad,
        Action::TrackpadClick,
        Action::Menu,
        Action::Haptic,
    ];

    /// The action's name (also its key in the profile files and its OpenXR action name).
    pub fn name(self) -> &'static str {
        match self {
            Action::GripPose => "grip_pose",
            Action::AimPose => "aim_pose",
            Action::Trigger => "trigger",
            Action::Squeeze => "squeeze",
            Action::Trackpad => "trackpad",
            Action::TrackpadClick => "trackpad_click",
            Action::Menu => "menu",
            Action::Haptic => "haptic",
        }
    }

    pub fn kind(self) -> ActionKind {
        match self {
            Action::GripPose | Action::AimPose => ActionKind::Pose,
            Action::Trigger => ActionKind::Float,
            Action::Squeeze | Action::TrackpadClick | Action::Menu => ActionKind::Bool,
            Action::Trackpad => ActionKind::Vec2,
            Action::Haptic => ActionKind::Haptic,
        }
    }

    pub fn from_name(name: &str) -> Option<Action> {
        Action::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Every procedure needs these on both hands.
    pub fn required(self) -> bool {
        matches!(
            self,
            Action::GripPose | Action::AimPose | Action::Trigger | Action::Haptic
        )
    }
}

/// Which hand a path belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Hand {
    Left,
    Right,
}

impl Hand {
    pub const BOTH: [Hand; 2] = [Hand::Left, Hand::Right];

    pub fn path(self) -> &'static str {
        match self {
            Hand::Left => "/user/hand/left",
            Hand::Right => "/user/hand/right",
        }
    }
}

/// One binding: an action on one hand to one path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Binding {
    pub action: Action,
    pub hand: Hand,
    pub path: String,
}

/// An interaction profile and its bindings, checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Profile {
    /// OpenXR interaction profile path, e.g. `/interaction_profiles/htc/vive_controller`.
    pub path: String,
    /// For people: "HTC Vive controller".
    pub name: String,
    pub bindings: Vec<Binding>,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ProfileError {
    #[error("{file}: {message}")]
    Syntax { file: String, message: String },
    #[error("{file}: profile: expected an /interaction_profiles/<vendor>/<name> path, got '{got}'")]
    ProfilePath { file: String, got: String },
    #[error(
        "{file}: bindings.{key}: unknown action (expected one of grip_pose, aim_pose, trigger, squeeze, trackpad, trackpad_click, menu, haptic)"
    )]
    UnknownAction { file: String, key: String },
    #[error("{file}: bindings.{key}: '{path}' {why}")]
    BadPath {
        file: String,
        key: String,
        path: String,
        why: &'static str,
    },
    #[error("{file}: bindings.{key}: the {hand} hand is bound twice")]
    Twice {
        file: String,
        key: String,
        hand: &'static str,
    },
    #[error("{file}: bindings.{key}: missing for the {hand} hand (every profile needs it on both)")]
    Missing {
        file: String,
        key: &'static str,
        hand: &'static str,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    profile: String,
    name: String,
    bindings: BTreeMap<String, Vec<String>>,
}

/// An OpenXR path segment: lowercase letters, digits, '_', '-', '.', not empty.
fn segment_ok(s: &str) -> bool {
    !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b"_-.".contains(&b))
}

/// Whether `s` is a well-formed OpenXR path: '/'-separated, non-empty segments of lowercase
/// letters, digits, '_', '-' and '.'.
pub fn is_path(s: &str) -> bool {
    s.strip_prefix('/')
        .is_some_and(|rest| rest.split('/').all(segment_ok))
}

fn check_path(kind: ActionKind, path: &str) -> Result<Hand, &'static str> {
    let hand = if path.starts_with("/user/hand/left/") {
        Hand::Left
    } else if path.starts_with("/user/hand/right/") {
        Hand::Right
    } else {
        return Err("is not under /user/hand/left or /user/hand/right");
    };
    let rest = &path[hand.path().len() + 1..];
    if !rest.split('/').all(segment_ok) {
        return Err("has an empty segment or a character OpenXR paths do not allow");
    }
    let is_output = rest.starts_with("output/");
    match kind {
        ActionKind::Haptic if rest != "output/haptic" => Err("is not an output/haptic path"),
        ActionKind::Haptic => Ok(hand),
        _ if is_output || !rest.starts_with("input/") => Err("is not an input path"),
        ActionKind::Pose if !rest.ends_with("/pose") => Err("is not a pose (…/pose)"),
        ActionKind::Pose => Ok(hand),
        _ if rest.ends_with("/pose") => Err("is a pose, not a button or axis"),
        ActionKind::Vec2 if rest.split('/').count() != 2 => {
            Err("is not a 2-axis input (…/input/trackpad or …/input/thumbstick)")
        }
        _ => Ok(hand),
    }
}

impl Profile {
    /// Parses and checks a profile file; `file` names it in errors.
    pub fn parse(file: &str, text: &str) -> Result<Profile, ProfileError> {
        let raw: ProfileFile = toml::from_str(text).map_err(|e| ProfileError::Syntax {
            file: file.to_string(),
            message: e.to_string(),
        })?;
        let parts: Vec<&str> = raw.profile.split('/').collect();
        if parts.len() != 4
            || !parts[0].is_empty()
            || parts[1] != "interaction_profiles"
            || !parts[2..].iter().all(|s| segment_ok(s))
        {
            return Err(ProfileError::ProfilePath {
                file: file.to_string(),
                got: raw.profile,
            });
        }
        let mut bindings = Vec::new();
        for (key, paths) in &raw.bindings {
            let action = Action::from_name(key).ok_or_else(|| ProfileError::UnknownAction {
                file: file.to_string(),
                key: key.clone(),
            })?;
            let mut seen = [false; 2];
            for path in paths {
                let hand =
                    check_path(action.kind(), path).map_err(|why| ProfileError::BadPath {
                        file: file.to_string(),
                        key: key.clone(),
                        path: path.clone(),
                        why,
                    })?;
                let k = hand as usize;
                if seen[k] {
                    return Err(ProfileError::Twice {
                        file: file.to_string(),
                        key: key.clone(),
                        hand: hand_name(hand),
                    });
                }
                seen[k] = true;
                bindings.push(Binding {
                    action,
                    hand,
                    path: path.clone(),
                });
            }
        }
        for action in Action::ALL.into_iter().filter(|a| a.required()) {
            for hand in Hand::BOTH {
                if !bindings
                    .iter()
                    .any(|b| b.action == action && b.hand == hand)
                {
                    return Err(ProfileError::Missing {
                        file: file.to_string(),
                        key: action.name(),
                        hand: hand_name(hand),
                    });
                }
            }
        }
        bindings.sort_by_key(|b| (b.action, b.hand));
        Ok(Profile {
            path: raw.profile,
            name: raw.name,
            bindings,
        })
    }

    /// The path bound to `action` on `hand`, if any.
    pub fn binding(&self, action: Action, hand: Hand) -> Option<&str> {
        self.bindings
            .iter()
            .find(|b| b.action == action && b.hand == hand)
            .map(|b| b.path.as_str())
    }
}

fn hand_name(h: Hand) -> &'static str {
    match h {
        Hand::Left => "left",
        Hand::Right => "right",
    }
}

/// The shipped profiles, HTC Vive first.
pub const BUILTIN: [(&str, &str); 4] = [
    (
        "xr-bindings/profiles/htc_vive.toml",
        include_str!("../profiles/htc_vive.toml"),
    ),
    (
        "xr-bindings/profiles/valve_index.toml",
        include_str!("../profiles/valve_index.toml"),
    ),
    (
        "xr-bindings/profiles/oculus_touch.toml",
        include_str!("../profiles/oculus_touch.toml"),
    ),
    (
        "xr-bindings/profiles/khr_simple.toml",
        include_str!("../profiles/khr_simple.toml"),
    ),
];

/// Parses the shipped profiles.
pub fn builtin() -> Result<Vec<Profile>, ProfileError> {
    BUILTIN
        .iter()
        .map(|(file, text)| Profile::parse(file, text))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_profiles_parse_with_the_vive_first() {
        let all = builtin().expect("shipped profiles are valid");
        assert_eq!(all[0].path, "/interaction_profiles/htc/vive_controller");
        let paths: Vec<&str> = all.iter().map(|p| p.path.as_str()).collect();
        assert_eq!(
            paths,
            [
                "/interaction_profiles/htc/vive_controller",
                "/interaction_profiles/valve/index_controller",
                "/interaction_profiles/oculus/touch_controller",
                "/interaction_profiles/khr/simple_controller",
            ]
        );
        let vive = &all[0];
        assert_eq!(vive.bindings.len(), 16, "8 actions on both hands");
        assert_eq!(
            vive.binding(Action::AimPose, Hand::Right),
            Some("/user/hand/right/input/aim/pose")
        );
        assert_eq!(
            vive.binding(Action::Trigger, Hand::Left),
            Some("/user/hand/left/input/trigger/value")
        );
        // The simple controller has no squeeze or trackpad; Touch has menu on the left only.
        assert_eq!(all[3].binding(Action::Squeeze, Hand::Left), None);
        assert_eq!(all[2].binding(Action::Menu, Hand::Right), None);
        for p in &all {
            for a in Action::ALL.into_iter().filter(|a| a.required()) {
                for h in Hand::BOTH {
                    assert!(p.binding(a, h).is_some(), "{} {:?} {:?}", p.name, a, h);
                }
            }
        }
    }

    fn vive_with(from: &str, to: &str) -> Result<Profile, ProfileError> {
        let text = BUILTIN[0].1.replace(from, to);
        assert_ne!(text, BUILTIN[0].1, "the edit applies");
        Profile::parse("test.toml", &text)
    }

    #[test]
    fn bad_profiles_get_errors_naming_the_file_key_and_reason() {
        let e = vive_with("\nmenu = ", "\nmenus = ").unwrap_err();
        assert!(matches!(&e, ProfileError::UnknownAction { key, .. } if key == "menus"));
        assert!(
            e.to_string()
                .starts_with("test.toml: bindings.menus: unknown action")
        );
        let e = vive_with("right/input/aim/pose", "right/input/trigger/click").unwrap_err();
        assert!(
            e.to_string().contains("bindings.aim_pose") && e.to_string().contains("not a pose"),
            "{e}"
        );
        let e = vive_with("right/output/haptic", "right/input/haptic").unwrap_err();
        assert!(e.to_string().contains("output/haptic"), "{e}");
        let e =
            vive_with("/user/hand/right/input/trigger/value", "/user/head/input/x").unwrap_err();
        assert!(e.to_string().contains("/user/hand/left or"), "{e}");
        let e = vive_with("right/input/menu/click", "right/input/Menu/click").unwrap_err();
        assert!(e.to_string().contains("character"), "{e}");
        let e = vive_with(
            "/user/hand/right/input/grip/pose",
            "/user/hand/left/input/grip/pose",
        )
        .unwrap_err();
        assert_eq!(
            e,
            ProfileError::Twice {
                file: "test.toml".into(),
                key: "grip_pose".into(),
                hand: "left"
            }
        );
        let e = vive_with(", \"/user/hand/right/output/haptic\"", "").unwrap_err();
        assert!(
            e.to_string()
                .contains("bindings.haptic: missing for the right hand"),
            "{e}"
        );
        let e = vive_with("/interaction_profiles/htc/vive_controller", "htc/vive").unwrap_err();
        assert!(matches!(e, ProfileError::ProfilePath { .. }));
        let e = vive_with("name = ", "nam = ").unwrap_err();
        assert!(matches!(e, ProfileError::Syntax { .. }), "{e}");
        let e = vive_with("right/input/trackpad\"", "right/input/trackpad/x\"").unwrap_err();
        assert!(e.to_string().contains("2-axis"), "{e}");
    }
}
