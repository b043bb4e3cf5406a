//! A model of a person operating: performs a task plan (a keyframed trace whose keys are the
//! places each instrument must reach and the buttons it must press there) as a person of a
//! given skill does, and writes the keyframed trace of that performance (smooth interpolation,
//! the hand's tremor), which the simulated headset or the headless player then plays.
//!
//! The model is the motor-control account of aimed movements that the surgical
//! motion-analysis literature rests on: a reach is a primary submovement that lands near the
//! target with an error growing with its length (and, in the unpractised, overshooting it),
//! followed by corrective submovements until the tip is close enough, each a smooth
//! start-stop motion; a person pauses to decide before a reach; the unpractised take
//! detours while they look for the target, act before they have settled, follow a path (a
//! cut, a retraction) less straight, hold longer and have a larger, slower tremor. Task errors
//! are not scripted: they follow from where the instrument really is when it acts (a clip put
//! on nothing, a hook overshooting onto tissue, a cut off the line).
//!
//! Both hands perform their plans in stretches between the plan's actions (a button changed
//! by either hand), each stretch as long as the slower hand needs, so what one hand does
//! still happens while the other holds, as the plan has it.

use super::KeyTrace;
use crate::sim::Hand;
use glam::Vec3;
use std::fmt::Write;

/// How a person operates: each range is drawn from once a session (`pace`, tremor) or once a
/// reach.
#[derive(Debug, Clone, PartialEq)]
pub struct Persona {
    pub name: &'static str,
    /// A reach or a path takes this many times the plan's time.
    pub pace: (f64, f64),
    /// Pause to decide before each reach, s.
    pub hesitation_s: (f64, f64),
    /// The chance of a long pause (lost, looking) before a reach, and its length, s.
    pub long_pause: (f64, (f64, f64)),
    /// The primary submovement's error: its standard deviation per axis as a share of the
    /// reach's length, and its mean overshoot along the reach as a share of it.
    pub endpoint_error: f64,
    pub overshoot: f64,
    /// Corrections go on until the tip is within this of the target, m.
    pub settle_m: f64,
    /// The chance of acting before the corrections (at the primary submovement's end).
    pub early_action: f64,
    /// The chance of a detour on a reach, and its size, m.
    pub wander: (f64, f64),
    /// Off the path on a stretch made with a button held (a cut, a retraction): standard
    /// deviation across it, m.
    pub path_deviation_m: f64,
    /// Holds take this many times the plan's.
    pub hold: (f64, f64),
    /// The hand's tremor: amplitude per axis, m, and frequency, Hz.
    pub tremor_m: (f64, f64),
    pub tremor_hz: (f64, f64),
}

/// Experienced surgeons: the plan's pace, no hesitation, a reach lands within 3 % and is
/// settled within 0.3 mm, a physiological tremor of 0.03-0.08 mm at 8-12 Hz.
pub const EXPERT: Persona = Persona {
    name: "expert",
    pace: (0.9, 1.15),
    hesitation_s: (0.0, 0.12),
    long_pause: (0.0, (0.0, 0.0)),
    endpoint_error: 0.03,
    overshoot: 0.0,
    settle_m: 0.0003,
    early_action: 0.0,
    wander: (0.0, 0.0),
    path_deviation_m: 0.0002,
    hold: (1.0, 1.1),
    tremor_m: (0.00003, 0.00008),
    tremor_hz: (8.0, 12.0),
};

/// First-week trainees: two to three times slower, a pause of 0.3-1 s before each reach and
/// now and then a long one, reaches that land 12 % off and overshoot by 15 %, settled only
/// within 1.5 mm, a third of actions started before settling, a detour on a third of the
/// reaches, paths 1 mm off the line, a tremor of 0.2-0.4 mm at 4-8 Hz (two sinusoids an
/// axis: up to about 0.6 mm).
pub const NOVICE: Persona = Persona {
    name: "novice",
    pace: (2.0, 3.0),
    hesitation_s: (0.3, 1.0),
    long_pause: (0.15, (1.5, 3.0)),
    endpoint_error: 0.12,
    overshoot: 0.15,
    settle_m: 0.0015,
    early_action: 0.3,
    wander: (0.35, 0.015),
    path_deviation_m: 0.001,
    hold: (1.0, 1.4),
    tremor_m: (0.0002, 0.0004),
    tremor_hz: (4.0, 8.0),
};

/// A small deterministic generator (xorshift64*), so a seed gives the same session anywhere.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        // SplitMix64 of the seed, never zero.
        let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        Rng((z ^ (z >> 31)) | 1)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let x = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, (lo, hi): (f64, f64)) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u = self.unit().max(1e-12);
        let v = self.unit();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
    fn normal3(&mut self) -> Vec3 {
        Vec3::new(
            self.normal() as f32,
            self.normal() as f32,
            self.normal() as f32,
        )
    }
}

/// One key of a plan or of a performance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub t_s: f64,
    pub position: Vec3,
    /// The pointed-at point minus the position (the instrument's direction and reach).
    pub aim: Vec3,
    pub trigger: f32,
    pub grip: f32,
    pub mark: bool,
    /// The wrist's roll, degrees (as the trace key).
    pub roll_deg: f32,
}

impl Step {
    fn buttons(&self) -> (f32, f32, bool) {
        (self.trigger, self.grip, self.mark)
    }
    fn busy(&self) -> bool {
        self.trigger > 0.5 || self.grip > 0.5
    }
}

fn plan_of(trace: &KeyTrace, hand: Hand) -> Vec<Step> {
    trace.keys[hand.index()]
        .iter()
        .map(|k| Step {
            t_s: k.t_s,
            position: Vec3::from(k.position),
            aim: Vec3::from(k.target) - Vec3::from(k.position),
            trigger: k.trigger,
            grip: k.grip,
            mark: k.mark,
            roll_deg: k.roll_deg,
        })
        .collect()
}

/// The plan's step of `plan` at `t` (linear, as the plan plays).
fn at(plan: &[Step], t: f64) -> Step {
    let Some(first) = plan.first() else {
        return Step {
            t_s: t,
            position: Vec3::ZERO,
            aim: Vec3::NEG_Z,
            trigger: 0.0,
            grip: 0.0,
            mark: false,
            roll_deg: 0.0,
        };
    };
    if t <= first.t_s {
        return Step { t_s: t, ..*first };
    }
    for w in plan.windows(2) {
        if t <= w[1].t_s {
            let span = w[1].t_s - w[0].t_s;
            let s = if span > 0.0 {
                ((t - w[0].t_s) / span) as f32
            } else {
                1.0
            };
            return Step {
                t_s: t,
                position: w[0].position.lerp(w[1].position, s),
                aim: w[0].aim.lerp(w[1].aim, s),
                trigger: w[0].trigger + (w[1].trigger - w[0].trigger) * s,
                grip: w[0].grip + (w[1].grip - w[0].grip) * s,
                mark: w[0].mark,
                roll_deg: w[0].roll_deg + (w[1].roll_deg - w[0].roll_deg) * s,
            };
        }
    }
    let last = plan[plan.len() - 1];
    Step { t_s: t, ..last }
}

/// One hand performing: its keys so far (times from the start of the session).
struct Performer<'a> {
    who: &'a Persona,
    rng: Rng,
    pace: f64,
    keys: Vec<Step>,
}

impl Performer<'_> {
    fn now(&self) -> Step {
        self.keys[self.keys.len() - 1]
    }
    fn push(&mut self, dt: f64, position: Vec3, like: &Step) {
        let t_s = self.now().t_s + dt.max(0.0);
        self.keys.push(Step {
            t_s,
            position,
            ..*like
        });
    }
    /// A smooth start-stop submovement to `p` over `dt`, buttons as `like`.
    fn reach(&mut self, dt: f64, p: Vec3, like: &Step) {
        self.push(dt.max(0.08), p, like);
    }

    /// Reaching `goal` with no button held (the plan took `plan_dt`).
    fn transport(&mut self, plan_dt: f64, goal: &Step) {
        let from = self.now();
        let d = goal.position - from.position;
        let len = d.length();
        let mut pause = self.rng.range(self.who.hesitation_s);
        if self.rng.chance(self.who.long_pause.0) {
            pause += self.rng.range(self.who.long_pause.1);
        }
        if pause > 0.0 {
            self.push(pause, from.position, &from);
        }
        let mut time = (plan_dt * self.pace).max(0.1);
        if len > 0.002 && self.rng.chance(self.who.wander.0) {
            // A detour: off to one side of the way, then on.
            let side = d.cross(Vec3::Y).normalize_or(Vec3::X);
            let up = side.cross(d).normalize_or(Vec3::Y);
            let a = self.rng.range((0.0, std::f64::consts::TAU));
            let off = (side * a.cos() as f32 + up * a.sin() as f32) * self.who.wander.1 as f32;
            let via = from.position + d * 0.5 + off;
            self.push(time * 0.6, via, goal);
            time *= 0.8;
        }
        let error = self.rng.normal3() * (self.who.endpoint_error as f32 * len);
        let primary = goal.position + d * self.who.overshoot as f32 + error;
        self.reach(time, primary, goal);
        if self.rng.chance(self.who.early_action) {
            return;
        }
        // Corrections: each takes away most of what is left, until within the settling
        // distance of the goal (what is left then stays: the hand's precision).
        let left =
            self.rng.normal3().normalize_or(Vec3::X) * (self.who.settle_m * self.rng.unit()) as f32;
        let target = goal.position + left;
        for _ in 0..4 {
            let off = self.now().position - target;
            if off.length() <= self.who.settle_m as f32 {
                break;
            }
            let next = target + off * self.rng.range((0.1, 0.3)) as f32;
            let dt = (0.12 + 0.05 * (1.0 + off.length() as f64 / 0.001).log2()) * self.pace.sqrt();
            self.reach(dt, next, goal);
        }
        if self.now().position.distance(target) > self.who.settle_m as f32 {
            self.reach(0.15 * self.pace.sqrt(), target, goal);
        }
    }

    /// Following the plan to `goal` with a button held (a cut, a retraction) or changing the
    /// buttons on the spot: off the line by the persona's deviation.
    fn follow(&mut self, plan_dt: f64, goal: &Step, moving: bool) {
        let mut p = goal.position;
        let factor = if moving {
            self.pace
        } else {
            self.rng.range(self.who.hold)
        };
        if moving {
            let d = goal.position - self.now().position;
            let side = d.cross(Vec3::Y).normalize_or(Vec3::X);
            let up = side.cross(d).normalize_or(Vec3::Y);
            p += (side * self.rng.normal() as f32 + up * self.rng.normal() as f32)
                * self.who.path_deviation_m as f32;
        } else if self.now().position.distance(p) < 0.01 {
            // On the spot: the hand stays where it is.
            p = self.now().position;
        }
        // A button change keeps the plan's time (it is what the tissue sees); a hold or a
        // path takes the persona's.
        let dt = if goal.buttons() != self.now().buttons() && !moving {
            plan_dt
        } else {
            plan_dt * factor
        };
        self.push(dt, p, goal);
    }
}

/// Performs `plan` as `who` (the seed draws everything that varies). The result keeps the
/// plan's procedure and its head's first key.
pub fn perform(plan: &KeyTrace, who: &Persona, seed: u64) -> Performance {
    let mut rng = Rng::new(seed);
    let pace = rng.range(who.pace);
    let plans = Hand::BOTH.map(|h| plan_of(plan, h));
    let mut hands: Vec<Performer> = Hand::BOTH
        .iter()
        .map(|&h| {
            let first = plans[h.index()]
                .first()
                .copied()
                .unwrap_or_else(|| at(&[], 0.0));
            Performer {
                who,
                rng: Rng::new(seed ^ (0x51ed_27a3 + h.index() as u64)),
                pace,
                keys: vec![Step { t_s: 0.0, ..first }],
            }
        })
        .collect();
    // The stretches: between the plan's actions (a button changed by either hand).
    let mut cuts: Vec<f64> = Vec::new();
    for p in &plans {
        for w in p.windows(2) {
            if w[0].buttons() != w[1].buttons() {
                cuts.push(w[0].t_s);
                cuts.push(w[1].t_s);
            }
        }
        if let Some(l) = p.last() {
            cuts.push(l.t_s);
        }
    }
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let mut from = 0.0;
    let mut clock = 0.0;
    for &to in cuts.iter().filter(|&&t| t > 1e-9) {
        for (k, h) in hands.iter_mut().enumerate() {
            let plan = &plans[k];
            let mut goals: Vec<Step> = plan
                .iter()
                .filter(|s| s.t_s > from + 1e-9 && s.t_s < to - 1e-9)
                .copied()
                .collect();
            // The stretch's end, where the plan has no key there, is a point passed through.
            let passing = !plan.iter().any(|s| (s.t_s - to).abs() < 1e-9);
            goals.push(at(plan, to));
            let mut prev = at(plan, from);
            let last = goals.len() - 1;
            for (i, g) in goals.into_iter().enumerate() {
                let plan_dt = g.t_s - prev.t_s;
                let moves = g.position.distance(prev.position) > 1e-6;
                if moves && passing && i == last && !g.busy() {
                    h.push((plan_dt * h.pace).max(0.02), g.position, &g);
                } else if moves && !prev.busy() && !g.busy() {
                    h.transport(plan_dt, &g);
                } else {
                    h.follow(plan_dt, &g, moves);
                }
                prev = g;
            }
        }
        // The stretch lasts as long as the slower hand; the other holds at its end.
        let end = hands.iter().map(|h| h.now().t_s).fold(clock, f64::max);
        for h in &mut hands {
            let now = h.now();
            if now.t_s < end - 1e-9 {
                h.keys.push(Step { t_s: end, ..now });
            }
        }
        clock = end;
        from = to;
    }
    let tremor = Hand::BOTH.map(|h| {
        let mut r = Rng::new(seed ^ (0x7e30_0000 + h.index() as u64));
        (0..2)
            .map(|_| Tremor {
                amplitude_m: [0; 3].map(|_| r.range(who.tremor_m) / 2f64.sqrt()),
                hz: r.range(who.tremor_hz),
                phase: r.range((0.0, std::f64::consts::TAU)),
            })
            .collect()
    });
    Performance {
        procedure: plan.procedure.clone(),
        persona: who.name,
        seed,
        pace,
        keys: [hands[0].keys.clone(), hands[1].keys.clone()],
        tremor,
        head: plan.head.first().map(|k| (k.position, k.target)),
    }
}

/// One sinusoid of a hand's tremor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tremor {
    pub amplitude_m: [f64; 3],
    pub hz: f64,
    pub phase: f64,
}

/// A performed plan, ready to be written as a trace.
#[derive(Debug, Clone, PartialEq)]
pub struct Performance {
    pub procedure: String,
    pub persona: &'static str,
    pub seed: u64,
    pub pace: f64,
    pub keys: [Vec<Step>; 2],
    pub tremor: [Vec<Tremor>; 2],
    pub head: Option<([f32; 3], [f32; 3])>,
}

impl Performance {
    pub fn duration_s(&self) -> f64 {
        self.keys
            .iter()
            .filter_map(|k| k.last())
            .map(|k| k.t_s)
            .fold(0.0, f64::max)
    }

    /// The keyframed trace (`interpolation = "smooth"`, the tremor, one line a key).
    pub fn toml(&self, header: &str) -> String {
        let mut out = String::new();
        for line in header.lines() {
            let _ = writeln!(out, "# {line}");
        }
        let _ = writeln!(out, "procedure = \"{}\"", self.procedure);
        let _ = writeln!(out, "interpolation = \"smooth\"");
        if let Some((p, t)) = self.head {
            let _ = writeln!(
                out,
                "head = [{{ t_s = 0.0, position = {}, target = {} }}]",
                v3(Vec3::from(p)),
                v3(Vec3::from(t))
            );
        }
        let _ = writeln!(out, "tremor = [");
        for (h, list) in Hand::BOTH.iter().zip(&self.tremor) {
            for t in list {
                let _ = writeln!(
                    out,
                    "  {{ hand = \"{}\", amplitude_m = [{:.6}, {:.6}, {:.6}], hz = {:.3}, phase = {:.3} }},",
                    h.name(),
                    t.amplitude_m[0],
                    t.amplitude_m[1],
                    t.amplitude_m[2],
                    t.hz,
                    t.phase
                );
            }
        }
        let _ = writeln!(out, "]");
        for (h, keys) in Hand::BOTH.iter().zip(&self.keys) {
            let _ = writeln!(out, "{} = [", h.name());
            let mut last_t = -1.0;
            for k in keys {
                // Times to the millisecond, never two keys at one time.
                let t = ((k.t_s * 1000.0).round() / 1000.0).max(last_t + 0.001);
                last_t = t;
                let mut extra = String::new();
                if k.trigger != 0.0 {
                    let _ = write!(extra, ", trigger = {:.3}", k.trigger);
                }
                if k.grip != 0.0 {
                    let _ = write!(extra, ", grip = {:.3}", k.grip);
                }
                if k.mark {
                    extra.push_str(", mark = true");
                }
                if k.roll_deg != 0.0 {
                    let _ = write!(extra, ", roll_deg = {:.2}", k.roll_deg);
                }
                let _ = writeln!(
                    out,
                    "  {{ t_s = {t:.3}, position = {}, target = {}{extra} }},",
                    v3(k.position),
                    v3(k.position + k.aim)
                );
            }
            let _ = writeln!(out, "]");
        }
        out
    }
}

fn v3(v: Vec3) -> String {
    format!("[{:.5}, {:.5}, {:.5}]", v.x, v.y, v.z)
}

#[cfg(test)]
#[path = "operator_tests.rs"]
mod tests;
