use super::*;
use crate::procedures::cholecystectomy::{INFO, Scenario, build_procedure};
use crate::sim::{Buttons, Pose};

/// The default scenario at a coarse lattice (some 3,000 particles), laid out.
fn coarse() -> Cholecystectomy {
    let text = INFO
        .scenario
        .replace("liver_spacing_m = 0.0035", "liver_spacing_m = 0.007")
        .replace("organ_spacing_m = 0.0025", "organ_spacing_m = 0.004")
        .replace("settle_s = 0.5", "settle_s = 0.2");
    let s = Scenario::parse("coarse", &text).expect("coarse scenario");
    build_procedure("coarse", s).expect("builds")
}

/// Both hands pointing into the field (-z); the left parked out of the way, open.
fn frame(right: Vec3, trigger: f32, mark: bool) -> InputFrame {
    let mut f = InputFrame::default();
    let park = Vec3::new(0.05, -0.05, 0.08);
    f.hands[0].pose = Pose::looking_at(park, park - Vec3::Z);
    f.hands[1] = HandInput {
        pose: Pose::looking_at(right, right - Vec3::Z),
        buttons: Buttons {
            trigger,
            grip: 0.0,
            mark,
            pad: None,
        },
    };
    f
}

struct Run {
    c: Cholecystectomy,
    step: u64,
    events: Vec<SimEvent>,
}

impl Run {
    fn go(&mut self, f: &InputFrame) {
        self.c.step(f, self.step, &mut self.events);
        self.step += 1;
    }

    /// A press of the right hand's primary button, at `at`.
    fn next_instrument(&mut self, at: Vec3) {
        self.go(&frame(at, 0.0, true));
        self.go(&frame(at, 0.0, false));
    }

    /// A squeeze of the right trigger at `at`.
    fn squeeze(&mut self, at: Vec3) {
        self.go(&frame(at, 0.0, false));
        self.go(&frame(at, 1.0, false));
        self.go(&frame(at, 0.0, false));
    }

    /// A point a fraction of the way along vessel `v`'s chain now.
    fn along(&self, v: usize, f: f32) -> Vec3 {
        let s = &self.c.scene;
        let chain = &s.anatomy.vessels[v].chain;
        let k = ((f * (chain.len() - 1) as f32).round() as usize).min(chain.len() - 1);
        s.solver().particles.x[chain[k] as usize]
    }

    fn named(&self, name: &str) -> Vec<&crate::sim::ProcedureEvent> {
        self.events
            .iter()
            .filter_map(|e| match &e.kind {
                EventKind::Procedure(p) if p.name == name => Some(p),
                _ => None,
            })
            .collect()
    }
}

/// A coarse session at its start, and a place away from every vessel.
fn fresh() -> (Run, Vec3) {
    let r = Run {
        c: coarse(),
        step: 0,
        events: Vec::new(),
    };
    (r, Vec3::new(-0.03, -0.04, 0.08))
}

/// Left alone, nothing on the coarse lattice swings in place: a particle's speed is what its
/// path over the step says (a swing of period two substeps goes nowhere in a step at full
/// speed). With one solve of each strand a sweep, the strands' interior particles swung at
/// 4.1 m/s here (three solves, `STRAND_NEWTON_STEPS`: 0.7 m/s); in the demo this shook a
/// cystic artery particle 0.7 mm at 0.46 m/s. What is left on the organs and vessels is a
/// tremor of some 0.025 m/s, 12 um a substep.
#[test]
fn left_alone_nothing_swings_in_place() {
    use crate::procedures::cholecystectomy::anatomy::body;
    let (mut r, away) = fresh();
    let f = frame(away, 0.0, false);
    let dt = 1e-3;
    let (mut strands, mut tissue) = (0.0f32, 0.0f32);
    let mut last = r.c.scene.solver().particles.x.clone();
    for k in 0..600 {
        r.go(&f);
        let p = &r.c.scene.solver().particles;
        if k >= 100 {
            for i in 0..p.len() {
                let swing = p.v[i].length() - p.x[i].distance(last[i]) / dt;
                if p.body[i] == body::ADHESION {
                    strands = strands.max(swing);
                } else if (body::LIVER..=body::FASCIA).contains(&p.body[i]) {
                    tissue = tissue.max(swing);
                }
            }
        }
        last.clone_from(&p.x);
    }
    assert!(strands < 2.0, "a strand's particle swings at {strands} m/s");
    assert!(
        tissue < 0.1,
        "a particle of the tissue swings at {tissue} m/s"
    );
}

#[test]
fn clips_and_cuts_land_in_the_report_and_a_cut_short_of_two_clips_is_an_error() {
    let (mut r, away) = fresh();
    // The clip applier: two clips on the duct towards the junction (the patient's side), one
    // on the artery near the hepatic artery (its patient's side).
    r.next_instrument(away);
    assert_eq!(r.c.right_tool(), RightTool::ClipApplier);
    let duct = [r.along(0, 0.8), r.along(0, 0.6)];
    for at in duct {
        r.squeeze(at);
    }
    let artery_clip = r.along(3, 0.2);
    r.squeeze(artery_clip);
    // A squeeze far from any vessel places nothing.
    r.squeeze(away);
    let clips = r.named("clip");
    assert_eq!(clips.len(), 3, "{clips:?}");
    let m = &r.c.metrics;
    assert_eq!(m.missed_clips, 1);
    let vessels: Vec<&str> = m.clips.clips.iter().map(|c| c.vessel).collect();
    assert_eq!(vessels, ["cystic_duct", "cystic_duct", "cystic_artery"]);
    for (c, at) in m.clips.clips.iter().zip([duct[0], duct[1], artery_clip]) {
        let d = Vec3::from(c.position).distance(at);
        assert!(d < 0.002, "a clip {d} m from where the jaw closed");
    }
    // Along the duct from the gallbladder, the first clip lies further than the second.
    assert!(m.clips.clips[0].at_m > m.clips.clips[1].at_m);
    // The scissors: the duct cut on the gallbladder's side of both clips (safe), the artery
    // on the gallbladder's side of its one clip (bleeding).
    r.next_instrument(away);
    assert_eq!(r.c.right_tool(), RightTool::Scissors);
    let duct_cut = r.along(0, 0.3);
    r.squeeze(duct_cut);
    let artery_cut = r.along(3, 0.6);
    r.squeeze(artery_cut);
    let cuts = r.named("cut");
    assert_eq!(cuts.len(), 2, "{cuts:?}");
    let m = &r.c.metrics;
    assert_eq!(m.clips.cuts[0].vessel, "cystic_duct");
    assert_eq!(m.clips.cuts[0].clips_patient_side, 2);
    assert_eq!(m.clips.cuts[0].error, None);
    assert_eq!(m.clips.cuts[1].vessel, "cystic_artery");
    assert_eq!(m.clips.cuts[1].clips_patient_side, 1);
    assert_eq!(m.bleedings, 1);
    assert_eq!(m.bile_leaks, 0);
    assert_eq!(m.errors, 1);
    assert_eq!(r.named("bleeding").len(), 1);
    assert!(r.events.iter().any(|e| matches!(&e.kind,
        EventKind::Alarm { message, .. } if message.contains("cystic artery"))));
    // The cut vessels are checked off only after the earlier steps: nothing ticked yet.
    assert!(r.c.metrics.steps_done.is_empty());
    // The report carries the clips in order, with their places, and the cuts.
    let rep = crate::procedures::Procedure::report(&r.c);
    let clips = &rep.metrics["clips"]["clips"];
    assert_eq!(clips.as_array().map(Vec::len), Some(3));
    assert_eq!(clips[2]["vessel"], "cystic_artery");
    assert_eq!(rep.metrics["clips"]["cuts"][1]["error"], "bleeding");
    assert_eq!(rep.errors, 1);
    // A duct cut with no clip on the patient's side leaks bile.
    let leak_at = r.along(0, 0.9);
    r.squeeze(leak_at);
    assert_eq!(r.named("bile_leak").len(), 1);
    assert_eq!(r.c.metrics.errors, 2);
}

#[test]
fn the_live_hook_on_the_liver_is_an_injury_once_per_contact() {
    let mut r = Run {
        c: coarse(),
        step: 0,
        events: Vec::new(),
    };
    // The liver's surface particle nearest the laparoscope; the hook's end (6 mm along the
    // hook from its corner, which is where the hand is) on it.
    let s = &r.c.scene;
    let front = s.anatomy.organs[0]
        .surface
        .iter()
        .copied()
        .filter(|&i| s.solver().particles.w[i as usize] > 0.0)
        .max_by(|&a, &b| {
            s.solver().particles.x[a as usize]
                .z
                .total_cmp(&s.solver().particles.x[b as usize].z)
        })
        .expect("a free liver particle");
    let target = s.solver().particles.x[front as usize];
    let pose = Pose::looking_at(target, target - Vec3::Z);
    let hook = Instrument::l_hook(target, pose.orientation).expect("hook");
    let end = hook.cylinders()[1].p1();
    let on = target - (end - target);
    let off = on + Vec3::Z * 0.02;
    // In slowly with the current off (1 cm/s), pressing the capsule: nothing.
    let approach = |r: &mut Run, trigger: f32| {
        for k in 0..=200 {
            r.go(&frame(off.lerp(on, k as f32 / 200.0), trigger, false));
        }
    };
    approach(&mut r, 0.0);
    assert!(r.named("injury").is_empty());
    // The current on against it: one injury for the whole contact.
    for _ in 0..5 {
        r.go(&frame(on, 1.0, false));
    }
    assert_eq!(r.named("injury").len(), 1);
    assert!(r.c.metrics.liver_burn_steps >= 4, "{:?}", r.c.metrics);
    // Out, and in again with the current on: a second.
    for _ in 0..3 {
        r.go(&frame(off, 1.0, false));
    }
    approach(&mut r, 1.0);
    assert_eq!(r.named("injury").len(), 2);
    assert_eq!(r.c.metrics.injuries, 2);
    assert_eq!(r.c.metrics.errors, 2);
}

#[test]
fn the_primary_button_hands_over_the_instruments_in_turn() {
    let mut r = Run {
        c: coarse(),
        step: 0,
        events: Vec::new(),
    };
    let at = Vec3::new(-0.03, -0.04, 0.08);
    let mut seen = vec![r.c.right_tool()];
    for _ in 0..4 {
        r.next_instrument(at);
        seen.push(r.c.right_tool());
    }
    assert_eq!(
        seen,
        [
            RightTool::Hook,
            RightTool::ClipApplier,
            RightTool::Scissors,
            RightTool::Grasper,
            RightTool::Hook
        ]
    );
    assert_eq!(r.named("instrument_change").len(), 4);
    // The snapshot says which: the registry's swap list names them in the same order.
    r.next_instrument(at);
    let k = r.c.snapshot(r.step).tools[1].instrument;
    assert_eq!(k, 1);
    assert_eq!(
        INFO.held_tool(Hand::Right, k).name,
        RightTool::ClipApplier.name()
    );
    // The snapshot draws every body.
    let snap = r.c.snapshot(r.step);
    let names: Vec<&str> = snap.models.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "liver",
            "gallbladder",
            "fat",
            "vessels",
            "fascia",
            "strands"
        ]
    );
    for m in &snap.models {
        assert!(!m.indices.is_empty(), "{} is drawn", m.name);
        assert!(m.positions.iter().all(|p| p.is_finite()));
    }
}

#[test]
fn the_left_device_drives_the_laparoscope_while_its_button_is_held() {
    let mut r = Run {
        c: coarse(),
        step: 0,
        events: Vec::new(),
    };
    let at = Vec3::new(0.05, -0.05, 0.08);
    let mut f = frame(at, 0.0, false);
    r.go(&f);
    assert!(r.c.snapshot(r.step).scope.is_none());
    let grasper = r.c.tool_tip(0);
    // Button held, the device moved 1 cm: the camera moves with it, the grasper stays.
    f.hands[0].buttons.mark = true;
    r.go(&f);
    f.hands[0].pose.position += Vec3::X * 0.01;
    r.go(&f);
    let view = r.c.snapshot(r.step).scope.expect("the camera moved");
    assert!((view.eye - (INFO.view.eye + Vec3::X * 0.01)).length() < 1e-6);
    assert!(r.c.tool_tip(0).distance(grasper) < 1e-6);
    // Released: the grasper follows the device from where it was left.
    f.hands[0].buttons.mark = false;
    r.go(&f);
    f.hands[0].pose.position += Vec3::Y * 0.01;
    r.go(&f);
    assert!(r.c.tool_tip(0).distance(grasper + Vec3::Y * 0.01) < 1e-5);
}

#[test]
fn one_or_two_threads_play_the_same_bytes() {
    let run = |threads: usize| {
        crate::sim::on_threads(threads, || {
            let mut r = Run {
                c: coarse(),
                step: 0,
                events: Vec::new(),
            };
            // The clip applier, a clip on the duct, the left grasper pressing in.
            r.next_instrument(Vec3::new(-0.03, -0.04, 0.08));
            let at = r.along(0, 0.5);
            r.squeeze(at);
            for k in 0..40 {
                let mut f = frame(at, 0.0, false);
                let p = Vec3::new(0.02, 0.0, 0.02 - 0.0005 * k as f32);
                f.hands[0].pose = Pose::looking_at(p, p - Vec3::Z);
                r.go(&f);
            }
            (r.c.state_hash(), r.c.metrics.clips.clips.len())
        })
    };
    let one = run(1);
    assert_eq!(one.1, 1);
    assert_eq!(one, run(2));
}

#[test]
fn an_organ_read_from_an_obj_file_replaces_its_ellipsoid() {
    let dir = crate::testing::Scratch::new("chole-obj", "surface");
    // A round gallbladder 14 mm in radius where the generated one lies.
    let (centre, radius) = (Vec3::new(0.0, -0.001, 0.0), 0.014);
    let sphere = crate::mesh::icosphere(3);
    let mut obj = String::new();
    for p in &sphere.positions {
        let q = centre + *p * radius;
        obj += &format!("v {} {} {}\n", q.x, q.y, q.z);
    }
    for t in &sphere.triangles {
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(dir.join("gallbladder.obj"), obj).expect("obj written");
    let text = INFO
        .scenario
        .replace("liver_spacing_m = 0.0035", "liver_spacing_m = 0.007")
        .replace("organ_spacing_m = 0.0025", "organ_spacing_m = 0.002")
        .replace("settle_s = 0.5", "settle_s = 0.0")
        + "\n[surfaces]\ngallbladder = \"gallbladder.obj\"\n";
    let file = dir.join("scenario.toml").display().to_string();
    let s = Scenario::parse(&file, &text).expect("parses");
    let c = build_procedure(&file, s.clone()).expect("builds");
    let a = &c.scene.anatomy;
    let gb = &a.organs[1];
    // Its particles fill the sphere: their count is its volume over the cell's, and none
    // lies outside it.
    let h = 0.002f32;
    let expected = sphere.volume() * radius.powi(3) / (h * h * h);
    let n = gb.range.len() as f32;
    assert!(
        (n / expected - 1.0).abs() < 0.1,
        "{n} particles, {expected} expected"
    );
    for i in gb.range.clone() {
        let d = a.particles.x[i as usize].distance(centre);
        assert!(d <= radius + 1e-6, "a particle {d} m from the centre");
    }
    // A file of another kind is refused, naming the key.
    let bad = text.replace("gallbladder.obj", "gallbladder.stl");
    let s = Scenario::parse(&file, &bad).expect("parses");
    let e = build_procedure(&file, s).err().expect("refused");
    assert_eq!(e.key, "surfaces.gallbladder");
    // A missing file names the key and the file.
    let missing = text.replace("gallbladder.obj", "nowhere.obj");
    let s = Scenario::parse(&file, &missing).expect("parses");
    let e = build_procedure(&file, s).err().expect("refused");
    assert_eq!(e.key, "surfaces.gallbladder");
    assert!(e.message.contains("nowhere.obj"), "{e}");
}

/// Pixels of `with` (the snapshot drawn with its blood) that differ from `without` (the same
/// snapshot without it) by more than 24 levels in a channel, red the strongest, within 40
/// pixels of where `at` lands.
fn blood_pixels(snap: &Snapshot, at: Vec3) -> usize {
    use crate::render::camera::{DEFAULT_IPD_M, field_eyes};
    use crate::render::gpu::EYE_FORMAT;
    use crate::render::{EyeTarget, Gpu, Renderer};
    let size = (270, 300);
    let gpu = Gpu::headless(true).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)");
    let eyes = field_eyes(&INFO.view, DEFAULT_IPD_M);
    let draw = |s: &Snapshot| {
        let mut r = Renderer::new(&gpu, EYE_FORMAT).expect("shaders compile");
        let target = EyeTarget::new(&gpu, size);
        r.update(s);
        r.render(target.target(r.multiview()), size, &eyes);
        let [left, _] = target.read(&gpu).expect("read back");
        left
    };
    let dry = Snapshot {
        bleeding: Vec::new(),
        ..snap.clone()
    };
    let (with, without) = (draw(snap), draw(&dry));
    let centre = eyes[0].project(at, size).expect("in front");
    with.chunks_exact(4)
        .zip(without.chunks_exact(4))
        .enumerate()
        .filter(|(k, (p, q))| {
            let (x, y) = ((k % 270) as f32, (k / 270) as f32);
            let near = (x - centre.x).hypot(y - centre.y) < 40.0;
            let differs = (0..3).any(|c| p[c].abs_diff(q[c]) > 24);
            near && differs && p[0] >= p[1] && p[0] >= p[2]
        })
        .count()
}

#[test]
fn a_cut_artery_bleeds_until_a_clip_on_the_patients_side_stops_it() {
    let (mut r, away) = fresh();
    // One clip on the artery's patient side, then a cut on the gallbladder's side of it:
    // short of two clips, it bleeds.
    r.next_instrument(away);
    let first_clip = r.along(3, 0.2);
    r.squeeze(first_clip);
    r.next_instrument(away);
    assert_eq!(r.c.right_tool(), RightTool::Scissors);
    let cut = r.along(3, 0.6);
    r.squeeze(cut);
    assert_eq!(r.c.bleeding().len(), 1);
    let idle = |r: &mut Run, seconds: f64| {
        for _ in 0..(seconds / 0.001).round() as u64 {
            r.go(&frame(away, 0.0, false));
        }
    };
    // Blood shows near the cut within a second, and the pool grows while it bleeds.
    idle(&mut r, 1.0);
    let at_1s = blood_pixels(&r.c.snapshot(r.step), cut);
    idle(&mut r, 1.0);
    let at_2s = blood_pixels(&r.c.snapshot(r.step), cut);
    assert!(at_1s > 30, "{at_1s} blood pixels 1 s after the cut");
    assert!(
        at_2s > at_1s + at_1s / 5,
        "the pool grows: {at_1s} -> {at_2s}"
    );
    // Back to the clip applier: a second clip between the first and the cut stops it.
    for _ in 0..3 {
        r.next_instrument(away);
    }
    assert_eq!(r.c.right_tool(), RightTool::ClipApplier);
    let stop = r.along(3, 0.4);
    r.squeeze(stop);
    assert_eq!(r.named("bleeding_stopped").len(), 1);
    let b = r.c.bleeding()[0];
    assert!(b.stop_s.is_some());
    idle(&mut r, 0.1);
    let clipped = blood_pixels(&r.c.snapshot(r.step), cut);
    idle(&mut r, 2.0);
    let later = blood_pixels(&r.c.snapshot(r.step), cut);
    eprintln!("blood pixels: 1 s {at_1s}, 2 s {at_2s}, clipped {clipped}, 2 s later {later}");
    // Stopped: the pool no longer grows (the tissue under it may still settle a little).
    assert!(
        later <= clipped + clipped / 20,
        "after the clip: {clipped} -> {later} blood pixels"
    );
}

#[test]
fn the_hooks_current_held_at_a_bleeding_cut_coagulates_it() {
    let (mut r, away) = fresh();
    // The artery cut short of its clips (one on the patient's side, as above): it bleeds.
    r.next_instrument(away);
    r.squeeze(r.along(3, 0.2));
    r.next_instrument(away);
    let cut = r.along(3, 0.6);
    r.squeeze(cut);
    let source = r.c.bleeding()[0].position;
    // Scissors -> grasper -> hook.
    r.next_instrument(away);
    r.next_instrument(away);
    assert_eq!(r.c.right_tool(), RightTool::Hook);
    let current = |r: &mut Run, at: Vec3, seconds: f64| {
        for _ in 0..(seconds / 0.001).round() as u64 {
            r.go(&frame(at, 1.0, false));
        }
    };
    // The current on away from the cut does nothing to the bleeding.
    current(&mut r, away, 2.0);
    assert!(r.c.bleeding()[0].stop_s.is_none());
    // The hook's end (its foot's tip, not the hand's point) put on the bleeding source.
    r.go(&frame(source, 0.0, false));
    let end = r.c.snapshot(r.step).tools[1].tip;
    let hand = source - (end - source);
    r.go(&frame(hand, 0.0, false));
    let end = r.c.snapshot(r.step).tools[1].tip;
    let coag = r.c.scenario.tools.coag_time_s as f64;
    assert!(
        end.distance(source) < r.c.scenario.tools.coag_reach_m,
        "{end} vs {source}"
    );
    // Short of the time needed it still bleeds; held on, it stops, by coagulation.
    current(&mut r, hand, coag - 0.3);
    assert!(r.c.bleeding()[0].stop_s.is_none());
    assert!(r.named("bleeding_stopped").is_empty());
    current(&mut r, hand, 0.4);
    let stopped = r.named("bleeding_stopped");
    assert_eq!(stopped.len(), 1);
    assert_eq!(stopped[0].fields["by"], "coagulation");
    assert_eq!(stopped[0].fields["vessel"], "cystic_artery");
    let b = r.c.bleeding()[0];
    let held = b.stop_s.expect("stopped") - b.start_s;
    assert!(held > 2.0 + coag - 0.05, "bled {held} s");
    // It stays stopped: the current there again raises nothing more.
    current(&mut r, hand, 0.5);
    assert_eq!(r.named("bleeding_stopped").len(), 1);
}
