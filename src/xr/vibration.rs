//! What a Vive controller tells the hand through its vibration motor.
//!
//! Contact force: while an instrument presses tissue, the controller buzzes every frame with
//! an amplitude that grows with the logarithm of the force, from the weakest buzz the hand
//! notices at [`FORCE_FLOOR_N`] to full amplitude at the instrument's full-scale force. Force
//! perception follows Weber's law (a just-noticeable difference of roughly a tenth of the
//! force), so equal ratios of force give equal steps of amplitude: a light touch of 0.05 N
//! and a firm press of 0.5 N are both clearly felt and clearly different, where a linear
//! scale to a 3.5 N full scale would leave everything below 0.2 N at the floor.
//!
//! Events: grasping tissue, cutting it and a tear (an attachment or tie that ruptures) each
//! have a short pulse of their own, at a frequency and length unlike the contact buzz, so the
//! trainee can tell them apart without looking. A pulse is never cut short by the contact
//! buzz of the frames that follow it. A free instrument is silent.

use crate::procedures::{ToolInfo, ToolKind};
use crate::sim::EventKind;

/// The smallest contact force given a buzz of its own, newtons: below it (but above rounding
/// noise) the buzz stays at [`AMPLITUDE_FLOOR`], so a first touch is still felt.
pub const FORCE_FLOOR_N: f32 = 0.01;
/// The weakest amplitude used (0..1): the Vive's actuator is barely felt below about this.
pub const AMPLITUDE_FLOOR: f32 = 0.1;
/// Forces at or below this are rounding noise, not contact, newtons.
const NOISE_N: f32 = 1e-6;

/// One vibration command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Buzz {
    /// 0..1.
    pub amplitude: f32,
    pub frequency_hz: f32,
    pub duration_s: f64,
}

/// The contact buzz of one instrument.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HapticProfile {
    /// Force that gives full amplitude, newtons (the instrument's full-scale force).
    pub full_force_n: f32,
    /// Vibration frequency, Hz.
    pub frequency_hz: f32,
    /// Length of each pulse, seconds (pulses repeat every frame while contact lasts).
    pub pulse_s: f64,
}

impl HapticProfile {
    /// The contact buzz of an instrument: a soft 160 Hz buzz for instruments that hold or
    /// press (the Vive's actuator resonates near there), a sharper 250 Hz one for a laser or
    /// an energy hook.
    pub fn for_tool(tool: &ToolInfo) -> HapticProfile {
        let frequency_hz = match tool.kind {
            ToolKind::Laser | ToolKind::Hook => 250.0,
            ToolKind::Grasper | ToolKind::Probe | ToolKind::Steerable => 160.0,
        };
        HapticProfile {
            full_force_n: tool.full_scale_n.max(2.0 * FORCE_FLOOR_N),
            frequency_hz,
            pulse_s: 0.025,
        }
    }

    /// The amplitude for a frame's peak contact force; `None`: no contact (or no finite force).
    pub fn amplitude(&self, force_n: f32) -> Option<f32> {
        if !force_n.is_finite() || force_n <= NOISE_N {
            return None;
        }
        let span = (self.full_force_n / FORCE_FLOOR_N).ln();
        let s = ((force_n / FORCE_FLOOR_N).ln() / span).clamp(0.0, 1.0);
        Some(AMPLITUDE_FLOOR + (1.0 - AMPLITUDE_FLOOR) * s)
    }

    /// The contact buzz for a frame's peak force.
    pub fn buzz(&self, force_n: f32) -> Option<Buzz> {
        self.amplitude(force_n).map(|amplitude| Buzz {
            amplitude,
            frequency_hz: self.frequency_hz,
            duration_s: self.pulse_s,
        })
    }
}

/// An event felt as a pulse, weakest first (a frame with several gives the strongest).
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub enum Pulse {
    /// The instrument removed `faces` triangles.
    Cut { faces: u32 },
    /// The jaws took hold of tissue.
    Grasp,
    /// Tissue the instrument was touching or holding tore.
    Rupture,
}

impl Pulse {
    /// The pulse's vibration. A cut: a crisp 320 Hz tick of 12 ms whose amplitude grows with
    /// the faces removed (0.3 for one, 0.8 from 32). A grasp: a firm 100 Hz knock of 40 ms.
    /// A tear: the strongest, a 60 Hz jolt of 150 ms at full amplitude.
    pub fn buzz(self) -> Buzz {
        match self {
            Pulse::Cut { faces } => {
                let s = ((faces.max(1) as f32).ln() / 32f32.ln()).clamp(0.0, 1.0);
                Buzz {
                    amplitude: 0.3 + 0.5 * s,
                    frequency_hz: 320.0,
                    duration_s: 0.012,
                }
            }
            Pulse::Grasp => Buzz {
                amplitude: 0.7,
                frequency_hz: 100.0,
                duration_s: 0.04,
            },
            Pulse::Rupture => Buzz {
                amplitude: 1.0,
                frequency_hz: 60.0,
                duration_s: 0.15,
            },
        }
    }

    fn stronger(a: Option<Pulse>, b: Pulse) -> Pulse {
        match (a, b) {
            (Some(Pulse::Cut { faces: x }), Pulse::Cut { faces: y }) => Pulse::Cut { faces: x + y },
            (Some(a), b) if a > b => a,
            _ => b,
        }
    }
}

/// What both hands felt over one displayed frame (several simulation steps).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameFeel {
    /// Peak contact force on each hand's instrument, newtons.
    pub peak_n: [f32; 2],
    /// The strongest event pulse of each hand.
    pub pulse: [Option<Pulse>; 2],
    /// Something tore: felt by every hand that touches tissue in this frame.
    pub tore: bool,
}

impl FrameFeel {
    /// Takes one step's contact forces.
    pub fn touch(&mut self, force_n: [f32; 2]) {
        for (p, f) in self.peak_n.iter_mut().zip(force_n) {
            if f.is_finite() {
                *p = p.max(f);
            }
        }
    }

    /// Takes one event: cuts go to the hands that hold a laser, a grasp to the hand it names
    /// (the world names tools by hand), a tear to the hands in contact (decided at the frame's end).
    pub fn note(&mut self, event: &EventKind, tools: &[ToolInfo; 2]) {
        match event {
            EventKind::Cut { faces, .. } if *faces > 0 => {
                for (k, t) in tools.iter().enumerate() {
                    if t.kind == ToolKind::Laser {
                        self.add(k, Pulse::Cut { faces: *faces });
                    }
                }
            }
            EventKind::Grasp { tool, .. } => {
                for (k, t) in tools.iter().enumerate() {
                    if t.hand.name() == tool.as_str() {
                        self.add(k, Pulse::Grasp);
                    }
                }
            }
            EventKind::Rupture { .. } | EventKind::TieBroken { .. } => self.tore = true,
            _ => {}
        }
    }

    fn add(&mut self, k: usize, p: Pulse) {
        self.pulse[k] = Some(Pulse::stronger(self.pulse[k], p));
    }

    /// Takes in what another stretch of steps felt: the greater peaks, the stronger pulses.
    pub fn merge(&mut self, other: &FrameFeel) {
        self.touch(other.peak_n);
        for (k, p) in other.pulse.iter().enumerate() {
            if let Some(p) = p {
                self.add(k, *p);
            }
        }
        self.tore |= other.tore;
    }
}

/// What to do with one controller this frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Order {
    Vibrate(Buzz),
    Stop,
    Nothing,
}

/// Turns each frame's feel into vibration commands for both controllers.
#[derive(Debug, Clone)]
pub struct Vibrator {
    profiles: [HapticProfile; 2],
    /// Until when (simulated seconds) each hand's last event pulse runs.
    pulse_until_s: [f64; 2],
    /// Whether each controller was last told to buzz (so that it is told to stop).
    buzzing: [bool; 2],
}

impl Vibrator {
    pub fn new(tools: &[ToolInfo; 2]) -> Vibrator {
        Vibrator {
            profiles: [
                HapticProfile::for_tool(&tools[0]),
                HapticProfile::for_tool(&tools[1]),
            ],
            pulse_until_s: [f64::NEG_INFINITY; 2],
            buzzing: [false; 2],
        }
    }

    /// The contact profile of hand `k`.
    pub fn profile(&self, k: usize) -> &HapticProfile {
        &self.profiles[k]
    }

    /// Forgets what the controllers were doing (a new XR session starts silent).
    pub fn reset(&mut self) {
        self.pulse_until_s = [f64::NEG_INFINITY; 2];
        self.buzzing = [false; 2];
    }

    /// The commands for a frame that ends at simulated time `now_s`. Hands not `tracked` get
    /// nothing but a stop, if they were buzzing.
    pub fn orders(&mut self, now_s: f64, feel: &FrameFeel, tracked: [bool; 2]) -> [Order; 2] {
        let mut out = [Order::Nothing; 2];
        for (k, order) in out.iter_mut().enumerate() {
            let contact = self.profiles[k].buzz(feel.peak_n[k]);
            let mut pulse = feel.pulse[k];
            if feel.tore && contact.is_some() {
                pulse = Some(Pulse::stronger(pulse, Pulse::Rupture));
            }
            let busy = now_s < self.pulse_until_s[k];
            *order = match (tracked[k], pulse, contact) {
                (true, Some(p), _) => {
                    let b = p.buzz();
                    self.pulse_until_s[k] = now_s + b.duration_s;
                    Order::Vibrate(b)
                }
                // A pulse still running: the contact buzz waits for it to end.
                (true, None, Some(_)) if busy => Order::Nothing,
                (true, None, Some(b)) => Order::Vibrate(b),
                _ if self.buzzing[k] => Order::Stop,
                _ => Order::Nothing,
            };
            match order {
                Order::Vibrate(_) => self.buzzing[k] = true,
                Order::Stop => self.buzzing[k] = false,
                Order::Nothing => {}
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Hand;

    fn tool(hand: Hand, name: &'static str, kind: ToolKind, full_scale_n: f32) -> ToolInfo {
        ToolInfo {
            hand,
            name,
            kind,
            full_scale_n,
        }
    }

    fn tools() -> [ToolInfo; 2] {
        [
            tool(Hand::Left, "grasper", ToolKind::Grasper, 3.5),
            tool(Hand::Right, "laser", ToolKind::Laser, 1.0),
        ]
    }

    fn cut_event(faces: u32) -> EventKind {
        EventKind::Cut {
            model: "tissue".into(),
            faces,
            length_m: 0.001,
        }
    }

    #[test]
    fn amplitude_is_logarithmic_in_force_between_the_floor_and_full_scale() {
        let g = HapticProfile::for_tool(&tools()[0]);
        assert_eq!(g.amplitude(0.0), None);
        assert_eq!(g.amplitude(1e-7), None);
        assert_eq!(g.amplitude(f32::NAN), None);
        assert_eq!(g.amplitude(f32::INFINITY), None);
        assert_eq!(g.amplitude(1e-4), Some(AMPLITUDE_FLOOR));
        assert_eq!(g.amplitude(FORCE_FLOOR_N), Some(AMPLITUDE_FLOOR));
        assert_eq!(g.amplitude(3.5), Some(1.0));
        assert_eq!(g.amplitude(50.0), Some(1.0));
        // Weber: each doubling of force adds the same amplitude, ln 2 / ln 350 of the range.
        let step = 0.9 * 2f32.ln() / 350f32.ln();
        for f in [0.02f32, 0.05, 0.2, 1.0] {
            let (a, b) = (g.amplitude(f).expect("a"), g.amplitude(2.0 * f).expect("b"));
            assert!((b - a - step).abs() < 1e-5, "{f} N: {a} -> {b}");
        }
        // A light touch and a firm press are far apart, neither at the floor or full scale.
        let (light, firm) = (g.amplitude(0.05).expect("l"), g.amplitude(0.5).expect("f"));
        assert!(
            light > 0.3 && firm > light + 0.3 && firm < 0.8,
            "{light} {firm}"
        );
    }

    #[test]
    fn events_give_distinct_pulses_to_the_hands_they_concern() {
        let t = tools();
        let mut v = Vibrator::new(&t);
        // Free instruments are silent.
        let free = FrameFeel::default();
        assert_eq!(v.orders(0.0, &free, [true; 2]), [Order::Nothing; 2]);
        // A cut goes to the laser hand, and grows with the faces removed.
        let cut = |faces| {
            let mut f = FrameFeel::default();
            f.note(&cut_event(faces), &t);
            f
        };
        let one = cut(1);
        assert_eq!(one.pulse, [None, Some(Pulse::Cut { faces: 1 })]);
        let [l, r] = v.orders(0.1, &one, [true; 2]);
        assert_eq!(l, Order::Nothing);
        let Order::Vibrate(small) = r else {
            panic!("no cut pulse: {r:?}")
        };
        let Order::Vibrate(big) = v.orders(0.2, &cut(40), [true; 2])[1] else {
            panic!("no cut pulse")
        };
        assert!((small.amplitude - 0.3).abs() < 1e-6, "{small:?}");
        assert!((big.amplitude - 0.8).abs() < 1e-6, "{big:?}");
        assert_eq!(small.frequency_hz, 320.0);
        // After the pulse, with nothing felt, the laser is told to stop once.
        assert_eq!(
            v.orders(0.3, &free, [true; 2]),
            [Order::Nothing, Order::Stop]
        );
        assert_eq!(v.orders(0.31, &free, [true; 2]), [Order::Nothing; 2]);
        // A grasp knocks the grasper's hand, not the laser's, and differs from its buzz.
        let mut g = FrameFeel::default();
        g.touch([0.2, 0.0]);
        g.note(
            &EventKind::Grasp {
                tool: Hand::Left.name().into(),
                model: "tissue".into(),
                vertices: 12,
            },
            &t,
        );
        let [l, r] = v.orders(1.0, &g, [true; 2]);
        let contact = v.profile(0).buzz(0.2).expect("contact");
        assert_eq!(l, Order::Vibrate(Pulse::Grasp.buzz()));
        assert_ne!(Pulse::Grasp.buzz().frequency_hz, contact.frequency_hz);
        assert_eq!(r, Order::Nothing);
        // The contact buzz does not cut the 40 ms knock short, and resumes after it.
        let mut press = FrameFeel::default();
        press.touch([0.2, 0.0]);
        assert_eq!(v.orders(1.011, &press, [true; 2])[0], Order::Nothing);
        assert_eq!(v.orders(1.033, &press, [true; 2])[0], Order::Nothing);
        assert_eq!(
            v.orders(1.044, &press, [true; 2])[0],
            Order::Vibrate(contact)
        );
        // A tear jolts the hands in contact only.
        let mut tear = press;
        tear.note(
            &EventKind::Rupture {
                what: "attachment".into(),
                models: ["tissue".into(), "vessel".into()],
                force_n: 4.0,
            },
            &t,
        );
        assert_eq!(
            v.orders(2.0, &tear, [true; 2]),
            [Order::Vibrate(Pulse::Rupture.buzz()), Order::Nothing]
        );
        // An untracked controller is only told to stop.
        assert_eq!(v.orders(3.0, &press, [false, true])[0], Order::Stop);
        assert_eq!(v.orders(3.1, &press, [false, true])[0], Order::Nothing);
    }

    #[test]
    fn the_strongest_event_of_a_frame_wins_and_cuts_add_up() {
        let t = tools();
        let mut f = FrameFeel::default();
        for faces in [3, 4] {
            f.note(&cut_event(faces), &t);
        }
        assert_eq!(f.pulse[1], Some(Pulse::Cut { faces: 7 }));
        f.add(1, Pulse::Rupture);
        f.add(1, Pulse::Cut { faces: 2 });
        f.add(1, Pulse::Grasp);
        assert_eq!(f.pulse[1], Some(Pulse::Rupture));
        // Non-finite forces are not contact.
        f.touch([f32::NAN, 0.5]);
        assert_eq!(f.peak_n, [0.0, 0.5]);
    }
}
