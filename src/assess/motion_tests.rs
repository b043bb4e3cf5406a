use super::*;

const H: f64 = 1.0 / SAMPLE_HZ;

/// Samples of `f` (time in seconds to a position) over `seconds`.
fn sampled(seconds: f64, f: impl Fn(f64) -> Vec3) -> Vec<Vec3> {
    let n = (seconds * SAMPLE_HZ).round() as usize;
    (0..=n).map(|i| f(i as f64 * H)).collect()
}

/// A minimum-jerk movement of `d` metres along x over `t` seconds, from `start` seconds.
fn minimum_jerk(d: f64, t: f64, start: f64) -> impl Fn(f64) -> Vec3 {
    move |time| {
        let s = ((time - start) / t).clamp(0.0, 1.0);
        Vec3::new(
            (d * (10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5))) as f32,
            0.0,
            0.0,
        )
    }
}

#[test]
fn a_straight_line_at_constant_speed() {
    // Still 0.5 s, 0.1 m along x at 0.05 m/s (2 s), still 0.5 s; it acts at the end.
    let x = sampled(3.0, |t| {
        Vec3::new((0.05 * (t - 0.5).clamp(0.0, 2.0)) as f32, 0.02, -0.1)
    });
    let end = *x.last().expect("samples");
    let h = analyse_hand(&x, &[end]);
    assert!((h.path_m - 0.1).abs() < 1e-6, "{}", h.path_m);
    assert_eq!(h.movements, 1);
    // Start to the action (the end) and on to the end: the path itself.
    assert!((h.straight_m - 0.1).abs() < 1e-6);
    // The smoothing is a triangular window over 21 intervals, weights (11 - |k|) / 121, so j
    // intervals before the start the smoothed speed's share of 0.05 m/s is the weights from
    // k = j on: (11 - j)(12 - j) / 242. It passes 0.2 (1 cm/s) at j = 4 (56 / 242), and the
    // movement reaches back while it is at least 0.1 (5 mm/s): to j = 6 (30 / 242; j = 7 is
    // 20 / 242). The same after the end: 100 + 12 intervals of 20 ms.
    assert!((h.moving_s - 2.24).abs() < 1e-9, "{}", h.moving_s);
    assert!((h.moving_path_m - 0.1).abs() < 1e-6);
    let m = combine(
        &[h, HandMotion::default()],
        &[smoothed_speed(&x), vec![0.0; 150]],
        151,
    );
    assert_eq!(m.instruments, 1);
    assert!((m.idle_s - 0.76).abs() < 1e-9, "{}", m.idle_s);
    assert!((m.economy.expect("economy") - 1.0).abs() < 1e-6);
    assert!((m.speed_m_per_s.expect("speed") - 0.1 / 2.24).abs() < 1e-6);
    assert_eq!(m.bimanual, None);
}

#[test]
fn a_half_circle_has_the_economy_of_its_diameter() {
    // Radius 5 cm, 100 intervals at constant angular speed; it acts at the start. Straight:
    // the diameter; path: 100 chords of 2 r sin(pi / 200); economy 1 / (100 sin(pi / 200)).
    let r = 0.05;
    let x = sampled(2.0, |t| {
        let a = std::f64::consts::PI * t / 2.0;
        Vec3::new((r * a.cos()) as f32, (r * a.sin()) as f32, 0.0)
    });
    let h = analyse_hand(&x, &[x[0]]);
    let chord = 2.0 * r * (std::f64::consts::PI / 200.0).sin();
    assert!((h.path_m - 100.0 * chord).abs() < 1e-6, "{}", h.path_m);
    assert!((h.straight_m - 2.0 * r).abs() < 1e-6);
    let m = combine(
        &[h, HandMotion::default()],
        &[smoothed_speed(&x), vec![]],
        101,
    );
    let expected = 1.0 / (100.0 * (std::f64::consts::PI / 200.0).sin());
    assert!((m.economy.expect("economy") - expected).abs() < 1e-6);
    assert!((expected - 2.0 / std::f64::consts::PI).abs() < 1e-4);
}

#[test]
fn a_tremor_in_place_travels_four_amplitudes_a_cycle_and_is_no_movement() {
    // 2 mm at 5 Hz for 4 s: the samples fall on the extremes (every 0.1 s), so each cycle
    // travels exactly 4 amplitudes: 4 * 0.002 * 5 * 4 = 0.16 m. Each pass of the 11-sample
    // average leaves |sin(11 pi 5 / 50) / (11 sin(pi 5 / 50))| = 0.091 of it, the two 0.008
    // (a speed under 1 mm/s).
    let x = sampled(4.0, |t| {
        Vec3::new(
            (0.002 * (2.0 * std::f64::consts::PI * 5.0 * t).cos()) as f32,
            0.0,
            0.0,
        )
    });
    let h = analyse_hand(&x, &[]);
    assert!((h.path_m - 0.16).abs() < 1e-5, "{}", h.path_m);
    assert_eq!(h.movements, 0);
    let speed = smoothed_speed(&x);
    let m = combine(&[h, HandMotion::default()], &[speed, vec![]], 201);
    assert_eq!(m.instruments, 0, "a tremor alone is not work");
    assert!((m.path_m - 0.16).abs() < 1e-5);
    assert!((m.idle_s - 4.0).abs() < 1e-9);
    assert_eq!(m.speed_m_per_s, None);
    assert_eq!(m.economy, None, "it never acted");
}

#[test]
fn a_minimum_jerk_movement_has_its_analytic_dimensionless_jerk() {
    // x = D (10 s^3 - 15 s^4 + 6 s^5), s = t / T: the jerk is D / T^3 (60 - 360 s + 360 s^2),
    // whose square integrates to 720 D^2 / T^5; the peak speed is 1.875 D / T. So
    // T^3 / v_peak^2 * integral = 720 / 1.875^2 = 204.8 and the LDLJ is -ln 204.8 = -5.322,
    // whatever D and T. The third differences at 50 Hz blur the jump of the jerk at both
    // ends: within 0.05 for T = 2 s.
    let exact = -(720.0f64 / (1.875 * 1.875)).ln();
    for (d, t) in [(0.1, 2.0), (0.05, 2.0)] {
        let x = sampled(t + 1.0, minimum_jerk(d, t, 0.5));
        let (l, duration) = ldlj(&x, 0, x.len() - 1).expect("it moved");
        assert!((duration - t).abs() < 1e-9, "{duration}");
        assert!((l - exact).abs() < 0.05, "{l} vs {exact}");
        let h = analyse_hand(&x, &[]);
        assert_eq!(h.movements, 1);
        assert!(
            (h.ldlj[0].0 - l).abs() < 1e-12,
            "the movement covers the motion"
        );
    }
}

#[test]
fn a_tremor_on_a_movement_makes_it_less_smooth_not_more_movements() {
    let smooth = minimum_jerk(0.1, 2.0, 0.5);
    let clean = sampled(3.0, &smooth);
    let shaky = sampled(3.0, |t| {
        smooth(t)
            + Vec3::new(
                0.0,
                (0.002 * (2.0 * std::f64::consts::PI * 5.0 * t).cos()) as f32,
                0.0,
            )
    });
    let (a, b) = (analyse_hand(&clean, &[]), analyse_hand(&shaky, &[]));
    assert_eq!((a.movements, b.movements), (1, 1));
    // Still for 1 s it travels 4 * 0.002 * 5 = 0.04 m; moving, more.
    assert!(b.path_m > a.path_m + 0.05, "{} vs {}", b.path_m, a.path_m);
    assert!(
        b.ldlj[0].0 < a.ldlj[0].0 - 3.0,
        "{:?} vs {:?}",
        b.ldlj,
        a.ldlj
    );
}

#[test]
fn hesitant_stop_and_go_counts_each_movement_and_its_pauses() {
    // The same 0.1 m in three minimum-jerk pieces with 0.5 s pauses between them.
    let piece = |t: f64| {
        let f = [
            minimum_jerk(0.04, 0.8, 0.3),
            minimum_jerk(0.03, 0.8, 1.6),
            minimum_jerk(0.03, 0.8, 2.9),
        ];
        f.iter().map(|g| g(t)).sum::<Vec3>()
    };
    let x = sampled(4.0, piece);
    let h = analyse_hand(&x, &[]);
    assert_eq!(h.movements, 3);
    assert!((h.path_m - 0.1).abs() < 1e-6);
    let m = combine(
        &[h, HandMotion::default()],
        &[smoothed_speed(&x), vec![]],
        201,
    );
    // Still for 1.6 s (0.3 + 0.5 + 0.5 + 0.3); the smoothing widens each movement by at most
    // 0.2 s a side, and the slow starts and ends below 5 mm/s (under half of each piece) are
    // idle too.
    assert!(m.idle_s > 1.6 - 1.2 && m.idle_s < 1.6 + 1.2, "{}", m.idle_s);
}

#[test]
fn hands_moving_together_correlate_and_taking_turns_does_not() {
    let go = minimum_jerk(0.1, 1.0, 0.2);
    let late = minimum_jerk(0.1, 1.0, 1.6);
    let a = sampled(3.0, &go);
    let b = sampled(3.0, |t| go(t) + Vec3::Y * 0.05);
    let c = sampled(3.0, &late);
    let (sa, sb, sc) = (smoothed_speed(&a), smoothed_speed(&b), smoothed_speed(&c));
    assert!((correlation(&sa, &sb).expect("r") - 1.0).abs() < 1e-9);
    assert!(correlation(&sa, &sc).expect("r") < 0.0);
    let both = combine(
        &[analyse_hand(&a, &[]), analyse_hand(&b, &[])],
        &[sa.clone(), sb],
        151,
    );
    assert!((both.bimanual.expect("both work") - 1.0).abs() < 1e-9);
    assert_eq!(both.instruments, 2);
    assert!((both.path_m - 0.2).abs() < 1e-6);
    assert!((both.left_path_m - 0.1).abs() < 1e-6);
}

#[test]
fn the_recorder_samples_simulated_time_not_steps() {
    // The same motion stepped at 1 ms and at 2 ms gives the same measures.
    let f = minimum_jerk(0.08, 1.0, 0.3);
    let run = |dt: f64| {
        let mut r = MotionRecorder::new();
        let steps = (2.0 / dt).round() as usize;
        for k in 1..=steps {
            let t = k as f64 * dt;
            r.record(t, [f(t), Vec3::ZERO], [t > 1.5, false]);
        }
        r.analyse()
    };
    let (a, b) = (run(0.001), run(0.002));
    assert_eq!(a, b);
    assert!((a.duration_s - 2.0).abs() < 1e-9);
    assert!((a.path_m - 0.08).abs() < 1e-6);
    assert_eq!(a.movements, 1);
    // It acted once, at the end of its movement: no detour.
    assert!((a.economy.expect("it acted") - 1.0).abs() < 1e-6);
    let names: Vec<String> = a.measures().into_iter().map(|(k, _)| k).collect();
    assert!(names.contains(&"motion.ldlj".to_string()), "{names:?}");
}

#[test]
fn a_non_finite_tip_does_not_leak() {
    let mut r = MotionRecorder::new();
    for k in 1..=100 {
        let t = f64::from(k) * 0.01;
        let tip = if k == 50 {
            Vec3::NAN
        } else {
            Vec3::X * t as f32 * 0.05
        };
        r.record(t, [tip, tip], [false, false]);
    }
    let m = r.analyse();
    assert!(m.path_m.is_finite() && m.ldlj.is_none_or(f64::is_finite));
}
