//! The haptic channel: every step publishes each instrument's force, contact point, normal and
//! a stiffness estimate; a reader on another thread gets whole frames without stopping the
//! session. Pressed into the kidney, the grasper's frame carries exactly the tissue's reaction,
//! a normal pointing back out, and a stiffness that is positive while it presses deeper.

use glam::Vec3;
use vesalius::procedures::nephrectomy::Scenario;
use vesalius::registry::builtin;
use vesalius::session::Live;
use vesalius::sim::{Hand, Pacing};
use vesalius::trace::KeyTrace;

fn coarse() -> String {
    builtin("nephrectomy")
        .expect("builtin")
        .replace("level = 5", "level = 3")
        .replace("vessel_rings = 64", "vessel_rings = 12")
}

fn key(hand: &str, t_s: f64, position: Vec3, target: Vec3) -> String {
    format!(
        "[[{hand}]]\nt_s = {t_s}\nposition = [{}, {}, {}]\ntarget = [{}, {}, {}]\n\n",
        position.x, position.y, position.z, target.x, target.y, target.z
    )
}

#[test]
fn a_press_is_felt_with_its_force_point_normal_and_stiffness() {
    let text = coarse();
    let scenario = Scenario::parse("coarse", &text).expect("scenario");
    let tip_r = scenario.grasper.tip_radius_m;
    // The kidney's surface point furthest along d (its normal there is d), at rest.
    let d = Vec3::new(0.45, -0.85, 0.3).normalize();
    let rest = vesalius::procedures::Nephrectomy::new(scenario).expect("anatomy");
    let p = rest
        .kidney()
        .positions()
        .iter()
        .copied()
        .max_by(|a, b| a.dot(d).total_cmp(&b.dot(d)))
        .expect("points");
    // From 20 mm above down to 3 mm past first contact by 1.5 s, held to 2 s, out by 2.5 s.
    let at = |h: f32| p + d * h;
    let mut trace = String::from("procedure = \"nephrectomy\"\n\n");
    for (t, h) in [
        (0.0, 0.02),
        (1.5, tip_r - 0.003),
        (2.0, tip_r - 0.003),
        (2.5, 0.02),
    ] {
        trace += &key("left", t, at(h), at(h) - d * 0.05);
    }
    let away = Vec3::new(0.12, 0.05, 0.15);
    trace += &key("right", 0.0, away, away + Vec3::Y);
    let keys = KeyTrace::parse("press", &trace).expect("trace");

    let mut live = Live::new(&text, "coarse", Pacing::AsFastAsPossible).expect("session");
    let slot = live.haptics();
    let (mut touched, mut stiff) = (0, 0);
    let mut stiffness_sum = 0.0f32;
    let done = std::sync::atomic::AtomicBool::new(false);
    let reader_saw = std::thread::scope(|s| {
        // A reader polling all the while, as a 1 kHz device loop would.
        let reader = s.spawn(|| {
            let mut last = 0;
            while !done.load(std::sync::atomic::Ordering::Relaxed) {
                last = last.max(slot.latest().step);
            }
            last
        });
        while live.time_s() < 2.6 {
            let frame = keys.sample(live.time_s());
            live.step(frame).expect("steps");
            let felt = live.haptics().latest();
            let g = felt.tools[Hand::Left.index()];
            assert_eq!(felt.step + 1, live.step_count());
            assert_eq!(g.force_n, live.reactions()[0], "the reaction itself");
            assert_eq!(g.in_contact, g.force_n.length() > 0.0);
            if g.in_contact {
                touched += 1;
                assert!((g.normal.length() - 1.0).abs() < 1e-4);
                assert!(g.normal.dot(d) > 0.5, "points back out: {}", g.normal);
                assert!(g.point.distance(frame.hands[0].pose.position) < 1e-6);
                let pressing = (0.6..1.5).contains(&live.time_s());
                if pressing && g.stiffness_n_per_m > 0.0 {
                    stiff += 1;
                    stiffness_sum += g.stiffness_n_per_m;
                }
            } else {
                assert_eq!(g.stiffness_n_per_m, 0.0);
            }
            let laser = felt.tools[Hand::Right.index()];
            assert!(!laser.in_contact && laser.force_n == Vec3::ZERO);
        }
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        reader.join().unwrap_or(0)
    });
    assert!(touched > 100, "{touched} steps in contact");
    assert!(stiff > 50, "{stiff} pressing steps with a stiffness");
    // The reaction grows about 0.04 N per mm at first and 0.2 N per mm at 3 mm (the model's
    // own figures): the felt stiffness lies in that span, not at 0 nor at the clamp.
    let mean = stiffness_sum / stiff as f32;
    println!("mean felt stiffness {mean:.1} N/m over {stiff} pressing steps, {touched} in contact");
    assert!((20.0..400.0).contains(&mean), "mean stiffness {mean} N/m");
    assert!(reader_saw > 0);
    let end = live.haptics().latest().tools[0];
    assert!(!end.in_contact, "withdrawn: {end:?}");
}
