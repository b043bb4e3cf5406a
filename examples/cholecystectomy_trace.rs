//! Writes the cholecystectomy's demo trace (`assets/traces/cholecystectomy-demo.toml`) to
//! stdout: `cargo run --release --example cholecystectomy_trace >
//! assets/traces/cholecystectomy-demo.toml` (about two minutes). It plays the procedure on
//! the default scenario as it writes, and aims each action at where the tissue is when the
//! action starts (the fat pulled away drags the ducts), as a surgeon does.
//!
//! Left (grasper): onto the front of the fundus, closes, retracts it 7 mm towards the
//! fundus's side, holds; at the end pulls it down and out, which tears the adhesions off the
//! liver bed. Right: its primary button hands over the grasper, which takes the fat over
//! Calot's triangle by its front and pulls it out of the triangle, tearing its loose tissue;
//! then the clip applier: three clips on the cystic duct, two on the cystic artery; then the
//! scissors: the duct cut between its first and second clips (two on the patient's side), the
//! artery beyond both of its clips; then the hook, out of the way. Every approach comes from
//! the laparoscope's side (+z), 2 cm out. Positions in metres.

use glam::Vec3;
use vesalius::procedures::cholecystectomy::anatomy::body;
use vesalius::procedures::cholecystectomy::{Cholecystectomy, INFO, Scenario, build_procedure};
use vesalius::sim::EventKind;
use vesalius::trace::KeyTrace;

/// A hand's keyframes: time, position (the jaws' middle), trigger, grip, mark.
struct Hand {
    keys: Vec<(f64, Vec3, f32, f32, bool)>,
    t: f64,
    at: Vec3,
}

/// The instruments point into the field along -z, tilted down a little.
const FORWARD: Vec3 = Vec3::new(0.0, -0.01, -0.05);
const OUT: Vec3 = Vec3::new(0.0, 0.0, 0.02);

impl Hand {
    fn new(at: Vec3) -> Hand {
        Hand {
            keys: vec![(0.0, at, 0.0, 0.0, false)],
            t: 0.0,
            at,
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
        self.keys.push((self.t, p, tr, gr, false));
    }

    /// Holds still for `dt`, with trigger and grip changed to these values over it.
    fn set(&mut self, dt: f64, trigger: f32, grip: f32) {
        self.t += dt;
        self.keys.push((self.t, self.at, trigger, grip, false));
    }

    /// A press of the primary button.
    fn press(&mut self) {
        let (tr, gr) = self.last();
        self.t += 0.02;
        self.keys.push((self.t, self.at, tr, gr, true));
        self.t += 0.03;
        self.keys.push((self.t, self.at, tr, gr, false));
    }

    /// A close (trigger) and open on the spot.
    fn squeeze(&mut self) {
        self.set(0.04, 1.0, 0.0);
        self.set(0.04, 1.0, 0.0);
        self.set(0.04, 0.0, 0.0);
    }

    /// The keys as TOML tables. Times are written to the millisecond and rounded up (a
    /// key is never earlier than the step it was played at).
    fn toml(&self, side: &str) -> String {
        let mut out = String::new();
        for (t, p, trigger, grip, mark) in &self.keys {
            let target = *p + FORWARD;
            out += &format!("[[{side}]]\nt_s = {:.3}\n", (t * 1000.0).round() / 1000.0);
            out += &format!("position = [{:.5}, {:.5}, {:.5}]\n", p.x, p.y, p.z);
            out += &format!(
                "target = [{:.5}, {:.5}, {:.5}]\n",
                target.x, target.y, target.z
            );
            out += &format!("trigger = {trigger:.1}\ngrip = {grip:.1}\n");
            if *mark {
                out += "mark = true\n";
            }
            out += "\n";
        }
        out
    }
}

/// The procedure played along the trace as it is written.
struct Play {
    c: Cholecystectomy,
    step: u64,
}

impl Play {
    /// Plays the keys written so far up to `t_s`.
    fn to(&mut self, left: &Hand, right: &Hand, t_s: f64) {
        let mut text = String::from("procedure = \"cholecystectomy\"\n");
        text += &left.toml("left");
        text += &right.toml("right");
        let keys = match KeyTrace::parse("the trace so far", &text) {
            Ok(k) => k,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        let dt = f64::from(self.c.scenario.dt_s);
        let mut events = Vec::new();
        while (self.step as f64) * dt < t_s {
            let f = keys.sample(self.step as f64 * dt);
            self.c.step(&f, self.step, &mut events);
            self.step += 1;
        }
        for e in events {
            if let EventKind::TaskStep { name } = e.kind {
                eprintln!("{:.2} s: {name}", e.step as f64 * dt);
            }
        }
    }

    fn x(&self, i: u32) -> Vec3 {
        self.c.scene.solver().particles.x[i as usize]
    }

    /// A point a fraction of the way along a vessel's chain now.
    fn along(&self, v: usize, f: f32) -> Vec3 {
        let c = &self.c.scene.anatomy.vessels[v].chain;
        let s = f * (c.len() - 1) as f32;
        let (k, t) = (s.floor() as usize, s.fract());
        self.x(c[k]).lerp(self.x(c[(k + 1).min(c.len() - 1)]), t)
    }
}

fn main() {
    let c = match Scenario::parse("builtin scenario", INFO.scenario)
        .and_then(|s| build_procedure("builtin scenario", s))
    {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let mut play = Play { c, step: 0 };
    let an = &play.c.scene.anatomy;
    let p = &play.c.scene.solver().particles;
    let x = |i: u32| p.x[i as usize];
    // The fundus's front: the gallbladder's surface particle nearest the laparoscope beyond
    // 2.5 cm along it.
    let gb = &an.organs[1];
    let fundus = gb
        .surface
        .iter()
        .copied()
        .filter(|&i| x(i).x > 0.025)
        .max_by(|&a, &b| x(a).z.total_cmp(&x(b).z))
        .map_or(Vec3::ZERO, x);
    // The fat's front, over its middle.
    let fat = &an.organs[2];
    let centre = fat.range.clone().map(x).sum::<Vec3>() / fat.range.len().max(1) as f32;
    let fat_front = fat
        .surface
        .iter()
        .copied()
        .filter(|&i| p.body[i as usize] == body::FAT)
        .min_by(|&a, &b| {
            let d = |i: u32| (x(i) - Vec3::new(centre.x, centre.y, x(i).z)).length() - x(i).z;
            d(a).total_cmp(&d(b))
        })
        .map_or(centre, x);
    let mut left = Hand::new(fundus + Vec3::new(0.0, 0.0, 0.03));
    left.go(0.4, fundus);
    left.set(0.05, 0.0, 1.0);
    left.go(0.6, fundus + Vec3::new(0.007, 0.0, 0.002));
    let mut right = Hand::new(fat_front + Vec3::new(0.0, 0.0, 0.03));
    right.set(0.1, 0.0, 0.0);
    for _ in 0..3 {
        right.press();
    }
    right.go(0.4, fat_front);
    right.set(0.05, 1.0, 0.0);
    right.go(1.5, fat_front + Vec3::new(-0.02, -0.01, 0.05));
    right.set(0.1, 1.0, 0.0);
    right.set(0.05, 0.0, 0.0);
    // Hook, then the clip applier.
    right.press();
    right.press();
    // The left hand holds while the right works: its keys are written as the right's are.
    let hold = |left: &mut Hand, until: f64| {
        if until > left.t {
            left.set(until - left.t, 0.0, 1.0);
        }
    };
    let aim = |play: &mut Play, left: &mut Hand, right: &mut Hand, v: usize, f: f32| {
        // Out and over first; then in to where the vessel is by then.
        let from = right.at;
        right.go(0.1, from + OUT);
        hold(left, right.t);
        play.to(left, right, right.t);
        let target = play.along(v, f);
        right.go(0.2, target + OUT);
        right.go(0.15, target);
        hold(left, right.t);
        play.to(left, right, right.t);
        // The vessel under the jaw now.
        let target = play.along(v, f);
        right.go(0.05, target);
        right.squeeze();
        hold(left, right.t);
    };
    for f in [0.25, 0.45, 0.75] {
        aim(&mut play, &mut left, &mut right, 0, f);
    }
    for f in [0.3, 0.5] {
        aim(&mut play, &mut left, &mut right, 3, f);
    }
    // The scissors.
    right.press();
    aim(&mut play, &mut left, &mut right, 0, 0.35);
    aim(&mut play, &mut left, &mut right, 3, 0.75);
    // The grasper, then the hook, out of the way.
    right.press();
    right.press();
    let away = right.at + Vec3::new(0.0, -0.02, 0.03);
    right.go(0.3, away);
    // Then the left pulls the fundus down and out.
    hold(&mut left, right.t);
    let here = left.at;
    left.go(2.0, here + Vec3::new(0.015, -0.045, 0.015));
    left.set(0.5, 0.0, 1.0);
    right.set(left.t - right.t, 0.0, 0.0);
    play.to(&left, &right, left.t);
    let m = &play.c.metrics;
    eprintln!(
        "completed: {} ({:?}), clips {}, cuts {}, errors {}",
        play.c.is_completed(),
        m.steps_done,
        m.clips.clips.len(),
        m.clips.cuts.len(),
        m.errors
    );
    println!(
        "# Demo: the cholecystectomy (about {:.1} s), written by \
         examples/cholecystectomy_trace.rs",
        left.t
    );
    println!("# as it played the procedure on the default scenario. Left: grasper on the");
    println!("# fundus, retracted 7 mm, held; at the end pulled down and out (the adhesions");
    println!("# tear off the liver bed). Right: the grasper (three presses of the primary");
    println!("# button) pulls the fat out of Calot's triangle; the clip applier puts three");
    println!("# clips on the cystic duct and two on the cystic artery; the scissors cut the");
    println!("# duct between its first and second clips and the artery beyond its clips; then");
    println!("# the hook, out of the way.");
    println!("procedure = \"cholecystectomy\"");
    println!();
    print!("{}", left.toml("left"));
    print!("{}", right.toml("right"));
}
