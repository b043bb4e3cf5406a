//! Writes the myotomy's demo trace (`assets/traces/myotomy-demo.toml`) to stdout: `cargo run
//! --release --example myotomy_trace > assets/traces/myotomy-demo.toml` (the esophagus's
//! precomputation is read from the cache, or built first). It plays the procedure on the
//! default scenario as it writes, and presses as a surgeon does, by feel: the grasper goes
//! down onto the sphincter until it feels it; the hook, its current on, goes down at the top
//! of the myotomy until it cuts to the middle of the band between the muscle's depth and the
//! mucosa, then draws the incision along the anterior wall onto the stomach at 10 mm/s,
//! raising or lowering itself every 20 ms to hold that depth. Positions in metres.

use glam::Vec3;
use vesalius::procedures::myotomy::{INFO, Myotomy, Scenario, build_procedure};
use vesalius::sim::EventKind;
use vesalius::trace::KeyTrace;

/// A hand's keyframes: time, position (the tip's centre), trigger, grip.
struct Hand {
    keys: Vec<(f64, Vec3, f32, f32)>,
    t: f64,
    at: Vec3,
    forward: Vec3,
}

impl Hand {
    fn new(at: Vec3, forward: Vec3) -> Hand {
        Hand {
            keys: vec![(0.0, at, 0.0, 0.0)],
            t: 0.0,
            at,
            forward,
        }
    }

    fn last(&self) -> (f32, f32) {
        self.keys.last().map_or((0.0, 0.0), |k| (k.2, k.3))
    }

    /// Moves to `p` over `dt` seconds, its buttons as they were.
    fn go(&mut self, dt: f64, p: Vec3) {
        let (tr, gr) = self.last();
        self.t += dt;
        self.at = p;
        self.keys.push((self.t, p, tr, gr));
    }

    /// Holds still for `dt`, with trigger and grip changed to these values over it.
    fn set(&mut self, dt: f64, trigger: f32, grip: f32) {
        self.t += dt;
        self.keys.push((self.t, self.at, trigger, grip));
    }

    /// Holds still until `t` (if later): a hold already running is made longer.
    fn wait(&mut self, t: f64) {
        if t <= self.t {
            return;
        }
        let n = self.keys.len();
        if n >= 2 && self.keys[n - 1].1 == self.keys[n - 2].1 {
            let (a, b) = (self.keys[n - 1], self.keys[n - 2]);
            if (a.2, a.3) == (b.2, b.3) {
                self.keys[n - 1].0 = t;
                self.t = t;
                return;
            }
        }
        let (tr, gr) = self.last();
        self.set(t - self.t, tr, gr);
    }

    /// The keys as TOML tables, times to the millisecond.
    fn toml(&self, side: &str) -> String {
        let mut out = String::new();
        for (t, p, trigger, grip) in &self.keys {
            let target = *p + self.forward;
            out += &format!("[[{side}]]\nt_s = {:.3}\n", (t * 1000.0).round() / 1000.0);
            out += &format!("position = [{:.5}, {:.5}, {:.5}]\n", p.x, p.y, p.z);
            out += &format!(
                "target = [{:.5}, {:.5}, {:.5}]\n",
                target.x, target.y, target.z
            );
            out += &format!("trigger = {trigger:.1}\ngrip = {grip:.1}\n\n");
        }
        out
    }
}

/// The procedure played along the trace as it is written.
struct Play {
    m: Myotomy,
    step: u64,
}

impl Play {
    /// Plays the keys written so far up to `t_s`.
    fn to(&mut self, left: &Hand, right: &Hand, t_s: f64) {
        let mut text = String::from("procedure = \"myotomy\"\n");
        text += &left.toml("left");
        text += &right.toml("right");
        let keys = match KeyTrace::parse("the trace so far", &text) {
            Ok(k) => k,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let dt = f64::from(self.m.scenario.dt_s);
        let mut events = Vec::new();
        while (self.step as f64) * dt < t_s {
            let f = keys.sample(self.step as f64 * dt);
            self.m.step(&f, self.step, &mut events);
            self.step += 1;
        }
        for e in events {
            match e.kind {
                EventKind::TaskStep { name } => eprintln!("{:.2} s: {name}", e.step as f64 * dt),
                EventKind::Alarm { message, .. } => {
                    eprintln!("{:.2} s: alarm: {message}", e.step as f64 * dt)
                }
                _ => {}
            }
        }
    }

    /// The resting wall's top over `z` (the highest resting centroid of the anterior
    /// elements within 2 mm along), m.
    fn wall_top(&self, z: f32) -> f32 {
        let e = &self.m.esophagus;
        e.field
            .iter()
            .map(|&i| self.m.palpation().rest(i))
            .filter(|p| (p.z as f32 - z).abs() < 0.002)
            .map(|p| p.y as f32)
            .fold(0.0, f32::max)
    }
}

fn main() {
    let m = match Scenario::parse("builtin scenario", INFO.scenario) {
        Ok(s) => build_procedure(s, &vesalius::models::bem::cache::default_dir())
            .map_err(|e| e.to_string()),
        Err(e) => Err(e.to_string()),
    };
    let m = match m {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let s = m.scenario.clone();
    let (k, t) = (s.task, s.tools);
    let mut play = Play { m, step: 0 };
    let down = Vec3::new(0.0, -0.05, -0.02);
    let junction = k.junction_m as f32;
    let (rg, rh) = (t.grasper_radius_m as f32, t.hook_radius_m as f32);
    // Left: onto the sphincter, pressing down 0.5 mm every 0.1 s until it is felt.
    let mut left = Hand::new(Vec3::new(-0.012, 0.035, junction), down);
    let mut right = Hand::new(Vec3::new(0.012, 0.035, 0.015), down);
    let over = Vec3::new(0.0, play.wall_top(junction) + rg + 0.001, junction);
    left.go(0.4, over);
    right.wait(left.t);
    play.to(&left, &right, left.t);
    let mut y = over.y;
    while play.m.metrics.steps_done.is_empty() && y > over.y - 2.0 * rg {
        y -= 0.0005;
        left.go(0.1, Vec3::new(0.0, y, junction));
        right.wait(left.t);
        play.to(&left, &right, left.t);
    }
    left.set(0.2, 0.0, 0.0);
    left.go(0.2, over + Vec3::new(0.0, 0.01, 0.0));
    left.go(0.3, Vec3::new(-0.02, 0.03, junction));
    // Right: the hook over the top of the myotomy, 2 mm before it, then down with its
    // current on until it cuts to the middle of the band.
    let (from, to) = (
        (k.junction_m - k.above_m - 0.002) as f32,
        (k.junction_m + k.below_m + 0.002) as f32,
    );
    let aim = 0.5 * (k.muscle_m + s.esophagus.wall_m);
    let x = 0.0005;
    let start = Vec3::new(x, play.wall_top(from) + rh + 0.001, from);
    right.go(0.4, start);
    right.set(0.05, 1.0, 0.0);
    left.wait(right.t);
    play.to(&left, &right, right.t);
    let mut y = start.y;
    let mut z = from;
    while play.m.last_cut_m < 0.9 * aim && y > start.y - 2.0 * rh {
        y -= 0.0002;
        right.go(0.02, Vec3::new(x, y, z));
        left.wait(right.t);
        play.to(&left, &right, right.t);
    }
    // Along the wall at 10 mm/s, holding the depth: 0.2 mm deeper per millimetre too shallow.
    while z < to {
        z += 0.0002;
        let error = (aim - play.m.last_cut_m) as f32;
        y -= (0.2 * error).clamp(-0.0002, 0.0002);
        right.go(0.02, Vec3::new(x, y, z));
        left.wait(right.t);
        play.to(&left, &right, right.t);
    }
    right.set(0.05, 0.0, 0.0);
    right.go(0.3, Vec3::new(0.012, 0.035, to));
    left.wait(right.t);
    play.to(&left, &right, right.t + 0.1);
    let m = &play.m.metrics;
    eprintln!(
        "completed: {}, divided {:.1} of {:.1} mm, deepest {:.2} mm, perforations {}, \
         palpation {:.3} N, {} triangles",
        play.m.is_completed(),
        1e3 * m.divided_m,
        1e3 * m.required_m,
        1e3 * m.deepest_cut_m,
        m.perforations,
        m.palpation_force_n,
        m.triangles
    );
    println!(
        "# Demo: the myotomy (about {:.1} s), written by examples/myotomy_trace.rs as it played\n\
         # the procedure on the default scenario. Left: the grasper pressed onto the sphincter\n\
         # until it is felt, then out of the way. Right: the hook over the top of the myotomy,\n\
         # its current on, down until it cuts between the muscle's depth and the mucosa, then\n\
         # along the anterior wall across the junction onto the stomach at 10 mm/s, holding the\n\
         # depth by feel; current off, out.",
        right.t
    );
    println!("procedure = \"myotomy\"\n");
    print!("{}", left.toml("left"));
    print!("{}", right.toml("right"));
}
