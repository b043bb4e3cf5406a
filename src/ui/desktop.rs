//! The desktop's laparoscope: a camera that orbits, pans and zooms about a point in the
//! operating field, driven from the keyboard (the cholecystectomy paper adjusts its viewpoint
//! by keyboard), seen through one symmetric field of view.

use crate::procedures::{ProcedureInfo, ToolInfo, ToolKind, Viewpoint};
use crate::render::{EyeView, Fov};
use crate::sim::{Buttons, Hand, HandInput, InputFrame, PadDirection, Pose};
use glam::{Quat, Vec2, Vec3};

/// Vertical field of view of the desktop view, radians (a laparoscope's is wider than the
/// Vive's per-eye 110 degrees diagonal would make a monitor look; 50 degrees reads well).
pub const VERTICAL_FOV_RAD: f32 = 50.0 * std::f32::consts::PI / 180.0;

/// An orbiting camera: it looks at `target` from `distance_m` away, turned `yaw` about +Y
/// and tilted `pitch` above the horizontal (radians). SI units, field frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    pub target: Vec3,
    pub yaw: f32,
    pub pitch: f32,
    pub distance_m: f32,
}

/// Closest and furthest the camera comes to its target, metres.
const DISTANCE_RANGE_M: (f32, f32) = (0.03, 1.0);
/// The camera stays this far short of straight above or below, radians.
const PITCH_LIMIT: f32 = 1.5;

impl OrbitCamera {
    /// The camera at a procedure's viewpoint (the headless and headset one).
    pub fn at(view: &Viewpoint) -> OrbitCamera {
        OrbitCamera::looking(view.eye, view.target)
    }

    /// The camera at `eye` looking at `target`.
    pub fn looking(eye: Vec3, target: Vec3) -> OrbitCamera {
        let d = eye - target;
        let distance_m = d.length().max(DISTANCE_RANGE_M.0);
        OrbitCamera {
            target,
            yaw: d.x.atan2(d.z),
            pitch: (d.y / distance_m).clamp(-1.0, 1.0).asin(),
            distance_m,
        }
    }

    /// Where the camera is.
    pub fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + Vec3::new(sy * cp, sp, cy * cp) * self.distance_m
    }

    fn orientation(&self) -> Quat {
        Quat::from_rotation_y(self.yaw) * Quat::from_rotation_x(-self.pitch)
    }

    /// Turns about the target: `yaw` right, `pitch` up, radians.
    pub fn orbit(&mut self, yaw: f32, pitch: f32) {
        self.yaw += yaw;
        self.pitch = (self.pitch + pitch).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Moves camera and target together, in the view's right and up directions, metres.
    pub fn pan(&mut self, right_m: f32, up_m: f32) {
        let q = self.orientation();
        self.target += q * Vec3::X * right_m + q * Vec3::Y * up_m;
    }

    /// Moves toward the target by `factor` of the distance (negative: away), within range.
    pub fn zoom(&mut self, factor: f32) {
        self.distance_m =
            (self.distance_m * (1.0 - factor)).clamp(DISTANCE_RANGE_M.0, DISTANCE_RANGE_M.1);
    }

    /// The view for an image `aspect` (width / height) wide.
    pub fn view(&self, aspect: f32) -> EyeView {
        let half_v = VERTICAL_FOV_RAD * 0.5;
        let half_h = (half_v.tan() * aspect.max(1e-3)).atan();
        EyeView {
            position: self.eye(),
            orientation: self.orientation(),
            fov: Fov {
                left: -half_h,
                right: half_h,
                up: half_v,
                down: -half_v,
            },
        }
    }
}

/// The ray from the eye through a point of the image, `ndc` from (-1, -1) bottom left to
/// (1, 1) top right: its origin and unit direction.
pub fn ray(view: &EyeView, ndc: Vec2) -> (Vec3, Vec3) {
    let x = if ndc.x >= 0.0 {
        ndc.x * view.fov.right.tan()
    } else {
        -ndc.x * view.fov.left.tan()
    };
    let y = if ndc.y >= 0.0 {
        ndc.y * view.fov.up.tan()
    } else {
        -ndc.y * view.fov.down.tan()
    };
    let dir = view.orientation * Vec3::new(x, y, -1.0).normalize();
    (view.position, dir)
}

/// Depth range of the instrument driven by the mouse, along the cursor's ray, metres.
pub const DEPTH_RANGE_M: (f32, f32) = (0.04, 0.5);
/// Depth change per mouse-wheel notch, metres.
pub const WHEEL_STEP_M: f32 = 0.002;

/// The instruments on the desktop: the mouse drives the selected one. The grasper's tip sits
/// on the cursor's ray at a depth the wheel sets, pointing away from the eye (an instrument
/// through a port beside the laparoscope); the laser's beam leaves from just below the eye
/// along the cursor's ray, so it lands on what the cursor shows. Left button: grip (a
/// grasper) or trigger (a laser cuts); right button: mark (a laser marks the margin).
#[derive(Debug, Clone, PartialEq)]
pub struct DesktopHands {
    pub selected: Hand,
    /// Each instrument's depth along the cursor's ray, metres.
    pub depth_m: [f32; 2],
    pub frame: InputFrame,
    /// What each hand holds.
    pub tools: [ToolInfo; 2],
    /// The hand whose primary button drives the laparoscope.
    pub scope_hand: Option<Hand>,
    /// The other instruments a hand can change to with the right button, in turn.
    pub swap: &'static [ToolInfo],
    /// Where each hand's instrument enters the field (its port, where it is parked): a
    /// shaft runs from there to its tip.
    pub ports: [Vec3; 2],
    /// Camera motion is kept out of the instruments: per hand, how far its tip (and a laser's
    /// origin) lies from where the cursor alone would put it, once the camera has moved with
    /// the instrument in hand; and the last frame's camera, cursor, tips and origins.
    pub offset: [Vec3; 2],
    pub origin_offset: [Vec3; 2],
    last: Option<(Vec3, Quat, Vec2)>,
    tips: [Option<(Vec3, Vec3)>; 2],
    /// The procedure's imaging hand and the buttons its keys hold down (F: the pedal, C:
    /// contrast, M: the roadmap, for one published frame; the arrows: its pad), and the
    /// other hand's (shift and the arrows: its pad; Z: its centre click, once).
    pub imaging: Option<ImagingKeys>,
}

/// What the imaging keys hold down on each hand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImagingKeys {
    pub hand: Hand,
    pub own: Buttons,
    pub other: Buttons,
}

impl DesktopHands {
    /// Both instruments parked where the procedure says, over the field, pointing up and away
    /// from it (so nothing is touched or identified before the trainee moves); on the cursor,
    /// each 15 cm out.
    pub fn parked(info: &ProcedureInfo) -> Self {
        let mut frame = InputFrame::default();
        for (k, at) in info.desk_park.into_iter().enumerate() {
            frame.hands[k].pose = Pose::looking_at(at, at + Vec3::Y);
        }
        DesktopHands {
            selected: Hand::Right,
            depth_m: [0.15, 0.15],
            frame,
            tools: info.tools,
            scope_hand: info.options.scope_hand,
            swap: info.options.swap,
            ports: info.desk_park,
            offset: [Vec3::ZERO; 2],
            origin_offset: [Vec3::ZERO; 2],
            last: None,
            tips: [None; 2],
            imaging: info.options.imaging_hand.map(|hand| ImagingKeys {
                hand,
                own: Buttons::default(),
                other: Buttons::default(),
            }),
        }
    }

    /// An imaging key (F, C, M or Z, either case): the pedal and the contrast on or off, the
    /// roadmap pressed, the other hand's centre click (the zoom). False for any other key, or
    /// without an imaging hand.
    pub fn imaging_key(&mut self, key: &str) -> bool {
        let Some(k) = self.imaging.as_mut() else {
            return false;
        };
        let b = &mut k.own;
        let flip = |v: f32| if v > 0.5 { 0.0 } else { 1.0 };
        match key {
            "f" | "F" => b.trigger = flip(b.trigger),
            "c" | "C" => b.grip = flip(b.grip),
            "m" | "M" => b.mark = true,
            "z" | "Z" => k.other.mark = true,
            _ => return false,
        }
        true
    }

    /// An arrow key down (`Some`) or up (`None`): the imaging hand's pad held at that edge,
    /// or the other hand's. False without an imaging hand.
    pub fn pad_key(&mut self, pad: Option<PadDirection>, other_hand: bool) -> bool {
        let Some(k) = self.imaging.as_mut() else {
            return false;
        };
        if other_hand {
            k.other.pad = pad;
        } else {
            k.own.pad = pad;
        }
        true
    }

    /// The frame to publish: the hands, the imaging keys' buttons added to each hand's own
    /// (a held pad clicks, as on the controller). A roadmap or zoom press is published once.
    pub fn published(&mut self) -> InputFrame {
        let mut f = self.frame;
        if let Some(k) = self.imaging.as_mut() {
            let hand = k.hand.index();
            for (i, b) in [(hand, &mut k.own), (1 - hand, &mut k.other)] {
                let held = &mut f.hands[i].buttons;
                held.trigger = held.trigger.max(b.trigger);
                held.grip = held.grip.max(b.grip);
                held.mark |= b.mark || b.pad.is_some();
                held.pad = held.pad.or(b.pad);
                b.mark = false;
            }
        }
        f
    }
}

/// The mouse over the 3D view this frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pointer {
    /// Where the cursor is, in the view's normalised coordinates; none: not over the view.
    pub ndc: Option<Vec2>,
    pub primary_down: bool,
    pub secondary_down: bool,
    /// Wheel notches this frame (away from the user: positive).
    pub wheel: f32,
}

impl DesktopHands {
    /// Moves the selected instrument with the mouse, seen through `view`. The camera's own
    /// motion moves no instrument (nor adds to its path): when the camera has moved since the
    /// last frame, the instrument stays where it was in the field and the mouse moves it on
    /// from there, by what the cursor's motion would move a point at its depth in the new view.
    pub fn pointer(&mut self, view: &EyeView, p: Pointer) {
        let k = self.selected.index();
        self.depth_m[k] =
            (self.depth_m[k] + p.wheel * WHEEL_STEP_M).clamp(DEPTH_RANGE_M.0, DEPTH_RANGE_M.1);
        let Some(ndc) = p.ndc else {
            // Off the view: the instrument stays, its buttons let go.
            self.frame.hands[k].buttons = Buttons::default();
            return;
        };
        let ndc = ndc.clamp(Vec2::splat(-1.0), Vec2::splat(1.0));
        let (eye, dir) = ray(view, ndc);
        let down = view.orientation * Vec3::NEG_Y;
        let beside = eye + down * 0.01;
        if let Some((position, orientation, seen)) = self.last
            && (position != view.position || orientation != view.orientation)
            && let Some((tip, origin)) = self.tips[k]
        {
            // Where the last frame's cursor points in the new view: the instrument stays.
            let (_, was) = ray(view, seen);
            self.offset[k] = tip - (eye + was * self.depth_m[k]);
            self.origin_offset[k] = origin - beside;
        }
        self.last = Some((view.position, view.orientation, ndc));
        // A laparoscopic instrument's shaft comes from its port to the tip under the cursor
        // (not straight away from the eye, which shows only its end); a port behind the tip
        // as the eye sees it would turn the shaft towards the eye: then along the ray.
        let tip = eye + dir * self.depth_m[k] + self.offset[k];
        let origin = beside + self.origin_offset[k];
        self.tips[k] = Some((tip, origin));
        let from_port = (tip - self.ports[k]).normalize_or_zero();
        let shaft = if from_port.dot(dir) > 0.2 {
            from_port
        } else {
            dir
        };
        // The right button is the hand's primary button where the procedure gives it a use:
        // driving the laparoscope, changing the instrument (the left button then works
        // whichever instrument the hand holds).
        let primary = p.secondary_down
            && (self.scope_hand.is_some_and(|h| h.index() == k)
                || self.swap.iter().any(|s| s.hand.index() == k));
        self.frame.hands[k] = match self.tools[k].kind {
            ToolKind::Grasper | ToolKind::Probe => HandInput {
                pose: Pose::looking_at(tip, tip + shaft),
                buttons: Buttons {
                    grip: if p.primary_down { 1.0 } else { 0.0 },
                    mark: primary,
                    ..Buttons::default()
                },
            },
            ToolKind::Hook => HandInput {
                pose: Pose::looking_at(tip, tip + shaft),
                buttons: Buttons {
                    trigger: if p.primary_down { 1.0 } else { 0.0 },
                    mark: primary,
                    ..Buttons::default()
                },
            },
            // The handle where the pointer is (its travel along the entry pushes the
            // instrument in); the left button bends the tip, the right button twists it.
            ToolKind::Steerable => HandInput {
                pose: Pose::looking_at(tip, tip + dir),
                buttons: Buttons {
                    trigger: if p.primary_down { 1.0 } else { 0.0 },
                    grip: if p.secondary_down { 1.0 } else { 0.0 },
                    ..Buttons::default()
                },
            },
            ToolKind::Laser => HandInput {
                pose: Pose::looking_at(origin, tip),
                buttons: Buttons {
                    trigger: if p.primary_down { 1.0 } else { 0.0 },
                    mark: p.secondary_down,
                    ..Buttons::default()
                },
            },
        };
    }

    /// The key map shown under the view.
    pub fn key_map(&self) -> Vec<(String, String)> {
        let [left, right] = self.tools.map(|t| t.name);
        let does = |t: &ToolInfo| match t.kind {
            ToolKind::Grasper => format!("grip ({})", t.name),
            ToolKind::Laser | ToolKind::Hook => format!("cut ({})", t.name),
            ToolKind::Probe => format!("press ({})", t.name),
            ToolKind::Steerable => format!("bend ({})", t.name),
        };
        let mut lines = vec![
            ("1 / 2".to_string(), format!("{left} / {right}")),
            ("mouse".to_string(), "move the instrument".to_string()),
            ("wheel".to_string(), "deeper / shallower".to_string()),
            (
                "left button".to_string(),
                format!("{}, {}", does(&self.tools[0]), does(&self.tools[1])),
            ),
        ];
        if let Some(l) = self.tools.iter().find(|t| t.kind == ToolKind::Laser) {
            lines.push((
                "right button".to_string(),
                format!("mark the margin ({})", l.name),
            ));
        }
        if let Some(c) = self.tools.iter().find(|t| t.kind == ToolKind::Steerable) {
            lines.push((
                "right button".to_string(),
                format!("twist ({}): half a turn while held", c.name),
            ));
        }
        if self.imaging.is_some() {
            lines.push(("F".to_string(), "fluoroscopy pedal on / off".to_string()));
            lines.push(("C".to_string(), "contrast puff on / off".to_string()));
            lines.push(("M".to_string(), "roadmap on / off".to_string()));
            lines.push((
                "arrows".to_string(),
                "over the X-ray: turn the C-arm (LAO / RAO, cranial / caudal)".to_string(),
            ));
            lines.push((
                "shift + arrows".to_string(),
                "over the X-ray: move the table".to_string(),
            ));
            lines.push(("Z".to_string(), "the next zoom field".to_string()));
            lines.push((
                "T".to_string(),
                "the X-ray / the 3D teaching view".to_string(),
            ));
        }
        if let Some(s) = self.swap.first() {
            let others: Vec<&str> = self.swap.iter().map(|t| t.name).collect();
            lines.push((
                "right button".to_string(),
                format!(
                    "with the {} selected: change it for the {} (in turn, then back)",
                    self.tools[s.hand.index()].name,
                    others.join(", then the ")
                ),
            ));
        }
        if let Some(h) = self.scope_hand {
            lines.push((
                "right button".to_string(),
                format!(
                    "with the {} selected: move the laparoscope with it",
                    self.tools[h.index()].name
                ),
            ));
        }
        let camera = [
            ("arrows", "orbit the camera"),
            ("shift + arrows", "pan"),
            ("PgUp / PgDn", "zoom"),
            ("R", "reset the camera"),
        ];
        lines.extend(
            camera
                .into_iter()
                .map(|(k, v)| (k.to_string(), v.to_string())),
        );
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        a.distance(b) < 1e-5
    }

    #[test]
    fn the_target_is_in_the_middle_of_the_view_wherever_the_camera_goes() {
        let view = crate::registry::REGISTRY[0].view;
        let mut c = OrbitCamera::at(&view);
        assert!(close(c.eye(), view.eye), "{}", c.eye());
        for (yaw, pitch, pan, zoom) in [
            (0.0, 0.0, (0.0, 0.0), 0.0),
            (0.7, 0.3, (0.01, -0.02), 0.5),
            (-2.0, -0.9, (-0.03, 0.0), -0.4),
        ] {
            c.orbit(yaw, pitch);
            c.pan(pan.0, pan.1);
            c.zoom(zoom);
            let v = c.view(16.0 / 9.0);
            let p = v.project(c.target, (1600, 900)).expect("in front");
            assert!(
                (p.x - 800.0).abs() < 0.01 && (p.y - 450.0).abs() < 0.01,
                "{p}"
            );
            // Up in the field stays up on screen.
            let above = v
                .project(c.target + Vec3::Y * 0.01, (1600, 900))
                .expect("in front");
            assert!(above.y < p.y);
            assert!((c.eye().distance(c.target) - c.distance_m).abs() < 1e-5);
        }
    }

    #[test]
    fn orbit_pitch_and_zoom_stay_in_range() {
        let mut c = OrbitCamera::at(&crate::registry::REGISTRY[0].view);
        c.orbit(0.0, 10.0);
        assert_eq!(c.pitch, PITCH_LIMIT);
        for _ in 0..100 {
            c.zoom(0.5);
        }
        assert_eq!(c.distance_m, DISTANCE_RANGE_M.0);
        for _ in 0..100 {
            c.zoom(-0.5);
        }
        assert_eq!(c.distance_m, DISTANCE_RANGE_M.1);
    }
}

#[cfg(test)]
mod hand_tests {
    use super::*;

    #[test]
    fn the_grasper_goes_under_the_cursor_at_the_wheel_depth_and_grips_with_the_button() {
        let cam = OrbitCamera::at(&crate::registry::REGISTRY[0].view);
        let view = cam.view(1.5);
        let mut h = DesktopHands {
            selected: Hand::Left,
            ..DesktopHands::parked(crate::registry::REGISTRY[0])
        };
        let laser_before = h.frame.hands[1];
        let at = Vec2::new(0.25, -0.5);
        h.pointer(
            &view,
            Pointer {
                ndc: Some(at),
                primary_down: true,
                wheel: 5.0,
                ..Pointer::default()
            },
        );
        let g = h.frame.hands[0];
        assert!((h.depth_m[0] - 0.16).abs() < 1e-6);
        assert!((g.pose.position.distance(view.position) - 0.16).abs() < 1e-5);
        // It lands where the cursor is, in a 1500 x 1000 image.
        let px = view
            .project(g.pose.position, (1500, 1000))
            .expect("in front");
        let want = Vec2::new((at.x * 0.5 + 0.5) * 1500.0, (0.5 - at.y * 0.5) * 1000.0);
        assert!(px.distance(want) < 0.05, "{px} vs {want}");
        assert_eq!(g.buttons.grip, 1.0);
        assert!(g.pose.forward().dot(g.pose.position - view.position) > 0.0);
        // Its shaft comes from its port, not from the eye: seen from the side, not end-on.
        let from_port = (g.pose.position - h.ports[0]).normalize();
        assert!(g.pose.forward().dot(from_port) > 0.9999);
        assert!(
            g.pose
                .forward()
                .dot((g.pose.position - view.position).normalize())
                < 0.999
        );
        assert_eq!(h.frame.hands[1], laser_before, "the other instrument stays");
        // Off the view, it stays and lets go.
        h.pointer(&view, Pointer::default());
        assert_eq!(h.frame.hands[0].pose, g.pose);
        assert_eq!(h.frame.hands[0].buttons.grip, 0.0);
    }

    #[test]
    fn moving_the_camera_moves_no_instrument_and_the_mouse_moves_it_on_from_there() {
        let info = crate::registry::REGISTRY[0];
        let mut cam = OrbitCamera::at(&info.view);
        let mut h = DesktopHands::parked(info);
        let at = Vec2::new(0.1, 0.05);
        let still = Pointer {
            ndc: Some(at),
            ..Pointer::default()
        };
        for hand in [Hand::Right, Hand::Left] {
            h.selected = hand;
            let k = hand.index();
            h.pointer(&cam.view(1.5), still);
            let before = h.frame.hands[k].pose;
            // The camera orbits and zooms in; the cursor stays: the instrument stays.
            cam.orbit(0.3, -0.1);
            cam.zoom(0.8);
            let view = cam.view(1.5);
            h.pointer(&view, still);
            let after = h.frame.hands[k].pose;
            assert!(after.position.distance(before.position) < 1e-6, "{hand:?}");
            assert!(
                after.forward().dot(before.forward()) > 0.999_999,
                "{hand:?}"
            );
            // The mouse moves: the instrument's tip (a laser's aim) moves by what the
            // cursor's ray moves at its depth in the new view.
            let next = Vec2::new(0.2, -0.05);
            h.pointer(
                &view,
                Pointer {
                    ndc: Some(next),
                    ..Pointer::default()
                },
            );
            let moved = h.frame.hands[k].pose;
            let (_, d0) = ray(&view, at);
            let (_, d1) = ray(&view, next);
            let shift = (d1 - d0) * h.depth_m[k];
            match h.tools[k].kind {
                ToolKind::Laser => {
                    // The origin stays; the beam turns to the shifted aim.
                    assert!(moved.position.distance(after.position) < 1e-6);
                    let aim = h.tips[k].expect("aimed").0;
                    let was = aim - shift;
                    let old = (was - after.position).normalize();
                    assert!(after.forward().dot(old) > 0.999_99);
                    assert!(moved.forward().dot((aim - moved.position).normalize()) > 0.999_99);
                }
                _ => {
                    let step = moved.position - after.position;
                    assert!(step.distance(shift) < 1e-6, "{step} vs {shift}");
                }
            }
        }
    }

    #[test]
    fn the_laser_beam_follows_the_cursor_ray_and_cuts_or_marks_with_the_buttons() {
        let view = OrbitCamera::at(&crate::registry::REGISTRY[0].view).view(16.0 / 9.0);
        let mut h = DesktopHands::parked(crate::registry::REGISTRY[0]);
        assert_eq!(h.selected, Hand::Right);
        h.pointer(
            &view,
            Pointer {
                ndc: Some(Vec2::new(-0.3, 0.2)),
                primary_down: true,
                secondary_down: true,
                ..Pointer::default()
            },
        );
        let l = h.frame.hands[1];
        let (eye, dir) = ray(&view, Vec2::new(-0.3, 0.2));
        // The beam starts 1 cm below the eye and crosses the cursor ray at the laser's depth.
        assert!((l.pose.position.distance(eye) - 0.01).abs() < 1e-5);
        let hit = eye + dir * h.depth_m[1];
        let along = (hit - l.pose.position).normalize();
        assert!(l.pose.forward().dot(along) > 0.99999);
        assert_eq!((l.buttons.trigger, l.buttons.mark), (1.0, true));
        // The wheel stops at the depth range.
        h.pointer(
            &view,
            Pointer {
                wheel: -1000.0,
                ..Pointer::default()
            },
        );
        assert_eq!(h.depth_m[1], DEPTH_RANGE_M.0);
    }

    #[test]
    fn the_right_button_is_the_primary_button_only_where_the_procedure_uses_it() {
        let reg = crate::registry::REGISTRY;
        // A procedure whose hands both use their primary buttons: one changes instrument,
        // the other drives the laparoscope.
        let info = reg
            .iter()
            .copied()
            .find(|p| !p.options.swap.is_empty() && p.options.scope_hand.is_some())
            .expect("a procedure with both");
        let (swap, scope) = (
            info.options.swap[0],
            info.options.scope_hand.expect("scope"),
        );
        let view = OrbitCamera::at(&info.view).view(16.0 / 9.0);
        let mut h = DesktopHands::parked(info);
        let both = Pointer {
            ndc: Some(Vec2::new(0.1, 0.1)),
            primary_down: true,
            secondary_down: true,
            ..Pointer::default()
        };
        for hand in [swap.hand, scope] {
            h.selected = hand;
            h.pointer(&view, both);
            let b = h.frame.hands[hand.index()].buttons;
            assert!(b.mark, "{hand:?}");
            assert_eq!(b.trigger.max(b.grip), 1.0, "the left button still works");
        }
        let keys = h.key_map();
        let change = format!("change it for the {}", swap.name);
        assert!(
            keys.iter()
                .any(|(k, v)| k == "right button" && v.contains(&change)),
            "{keys:?}"
        );
        // A procedure with neither: the right button does nothing to a grasper.
        let plain = reg
            .iter()
            .copied()
            .find(|p| {
                p.options.swap.is_empty()
                    && p.options.scope_hand.is_none()
                    && p.tools[0].kind == ToolKind::Grasper
            })
            .expect("a plain procedure");
        let mut h = DesktopHands::parked(plain);
        h.selected = Hand::Left;
        h.pointer(&view, both);
        assert!(!h.frame.hands[0].buttons.mark);
    }

    /// A procedure's imaging keys hold its imaging hand's buttons down whatever the
    /// mouse does with it: F the pedal, C the contrast (each on until pressed again), M one
    /// roadmap press; a procedure without imaging takes none of them.
    #[test]
    fn the_imaging_keys_work_the_imaging_hands_buttons() {
        let reg = crate::registry::REGISTRY;
        let info = reg
            .iter()
            .copied()
            .find(|p| p.options.imaging_hand.is_some())
            .expect("a procedure with imaging");
        let hand = info.options.imaging_hand.expect("its hand").index();
        let mut h = DesktopHands::parked(info);
        assert!(h.imaging_key("F") && h.imaging_key("c") && h.imaging_key("m"));
        assert!(!h.imaging_key("x"));
        let b = h.published().hands[hand].buttons;
        assert_eq!((b.trigger, b.grip, b.mark), (1.0, 1.0, true));
        // The press is published once; the pedal and the contrast stay on.
        let b = h.published().hands[hand].buttons;
        assert_eq!((b.trigger, b.grip, b.mark), (1.0, 1.0, false));
        // With the imaging hand selected the mouse's buttons add to the keys'.
        h.selected = Hand::BOTH[hand];
        let view = OrbitCamera::at(&info.view).view(16.0 / 9.0);
        let over = Pointer {
            ndc: Some(Vec2::ZERO),
            ..Pointer::default()
        };
        h.pointer(&view, over);
        assert_eq!(h.published().hands[hand].buttons.trigger, 1.0);
        // F again: the pedal is up.
        h.imaging_key("f");
        assert_eq!(h.published().hands[hand].buttons.trigger, 0.0);
        // An arrow held: the imaging hand's pad at that edge, clicked, until it is let go;
        // with shift, the other hand's; Z: the other hand's click, once.
        assert!(h.pad_key(Some(PadDirection::Left), false));
        h.pad_key(Some(PadDirection::Up), true);
        for _ in 0..2 {
            let f = h.published();
            let (own, other) = (f.hands[hand].buttons, f.hands[1 - hand].buttons);
            assert_eq!((own.pad, own.mark), (Some(PadDirection::Left), true));
            assert_eq!((other.pad, other.mark), (Some(PadDirection::Up), true));
        }
        h.pad_key(None, false);
        h.pad_key(None, true);
        assert!(h.imaging_key("z"));
        let f = h.published();
        let (own, other) = (f.hands[hand].buttons, f.hands[1 - hand].buttons);
        assert_eq!((own.pad, other.pad, other.mark), (None, None, true));
        assert!(!h.published().hands[1 - hand].buttons.mark);
        assert!(
            h.key_map()
                .iter()
                .any(|(k, v)| k == "F" && v.contains("pedal"))
        );
        // Without imaging, the keys do nothing.
        let plain = reg
            .iter()
            .copied()
            .find(|p| p.options.imaging_hand.is_none())
            .expect("a procedure without");
        let mut h = DesktopHands::parked(plain);
        assert!(!h.imaging_key("f"));
        assert!(!h.pad_key(Some(PadDirection::Up), false));
        assert_eq!(h.published(), h.frame);
    }
}
