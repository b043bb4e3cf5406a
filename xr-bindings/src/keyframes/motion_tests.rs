//! Tests of the format's additions: `interpolation` and `[[tremor]]`.

use super::motion::tremor_weight;
use super::*;

/// Each demo trace the application ships: they must play exactly as before.
const DEMOS: [(&str, &str); 6] = [
    (
        "catheter",
        include_str!("../../../assets/traces/catheter-demo.toml"),
    ),
    (
        "cholecystectomy",
        include_str!("../../../assets/traces/cholecystectomy-demo.toml"),
    ),
    (
        "myotomy",
        include_str!("../../../assets/traces/myotomy-demo.toml"),
    ),
    (
        "nephrectomy",
        include_str!("../../../assets/traces/nephrectomy-demo.toml"),
    ),
    (
        "rectum",
        include_str!("../../../assets/traces/rectum-demo.toml"),
    ),
    (
        "sandbox",
        include_str!("../../../assets/traces/sandbox-demo.toml"),
    ),
];

/// A trace in the old style: several keys, buttons, a mark and head keys.
const OLD_STYLE: &str = "procedure = \"nephrectomy\"
[[head]]
t_s = 0.0
position = [0.0, 0.13, 0.16]
target = [0.0, 0.01, 0.0]
[[head]]
t_s = 3.0
position = [0.02, 0.12, 0.15]
target = [0.0, 0.0, 0.0]
[[left]]
t_s = 0.0
position = [-0.03, 0.06, 0.02]
target = [-0.03, 0.01, 0.0]
[[left]]
t_s = 1.5
position = [-0.02, 0.04, 0.01]
target = [-0.02, 0.0, 0.0]
grip = 1.0
[[right]]
t_s = 0.0
position = [0.03, 0.06, 0.02]
target = [0.03, 0.01, 0.0]
[[right]]
t_s = 1.0
position = [0.01, 0.03, 0.0]
target = [0.0, 0.0, -0.01]
trigger = 0.5
[[right]]
t_s = 1.0
position = [0.012, 0.03, 0.0]
target = [0.0, 0.0, -0.01]
mark = true
[[right]]
t_s = 2.5
position = [-0.01, 0.02, -0.005]
target = [-0.01, -0.03, 0.0]
trigger = 1.0
";

fn file(text: &str) -> KeyframeFile {
    KeyframeFile::parse(text).unwrap_or_else(|e| panic!("{}: {}", e.key, e.message))
}

fn bits(v: Vec3) -> [u32; 3] {
    v.to_array().map(f32::to_bits)
}

/// The same sample, bit for bit (`==` would let 0.0 stand for -0.0).
fn assert_same(a: HandSample, b: HandSample, what: &str) {
    assert_eq!(bits(a.position), bits(b.position), "{what}: position");
    assert_eq!(bits(a.target), bits(b.target), "{what}: target");
    assert_eq!(a.trigger.to_bits(), b.trigger.to_bits(), "{what}: trigger");
    assert_eq!(a.grip.to_bits(), b.grip.to_bits(), "{what}: grip");
    assert_eq!(a.mark, b.mark, "{what}: mark");
}

/// Times from before the start to past the end, including every key's own.
fn times(f: &KeyframeFile) -> Vec<f64> {
    let end = f.duration_s() + 1.0;
    let mut ts: Vec<f64> = (0..=4000)
        .map(|i| -0.5 + end * f64::from(i) / 4000.0)
        .collect();
    ts.extend(f.left.iter().chain(&f.right).map(|k| k.t_s));
    ts.extend(f.head.iter().map(|k| k.t_s));
    ts
}

fn keys_of(f: &KeyframeFile, hand: usize) -> &[HandKey] {
    if hand == 0 { &f.left } else { &f.right }
}

#[test]
fn linear_traces_sample_as_before_with_or_without_saying_so() {
    let said = OLD_STYLE.replace(
        "procedure = \"nephrectomy\"\n",
        "procedure = \"nephrectomy\"\ninterpolation = \"linear\"\n",
    );
    let (plain, said) = (file(OLD_STYLE), file(&said));
    assert_eq!(plain.interpolation, Interpolation::Linear);
    assert_eq!(plain, said, "saying linear changes nothing");
    let mut traces = vec![("old style", plain)];
    traces.extend(DEMOS.iter().map(|(n, text)| (*n, file(text))));
    for (name, f) in &traces {
        assert!(f.tremor.is_empty() && f.interpolation == Interpolation::Linear);
        for t in times(f) {
            for hand in 0..2 {
                let before = sample_hand(keys_of(f, hand), t).expect("keys");
                let now = f.sample_hand_of(hand, t).expect("keys");
                assert_same(now, before, &format!("{name} hand {hand} at {t} s"));
            }
            let (p, q) = f.sample_head_of(t);
            let (p0, q0) = sample_head(&f.head, t);
            assert_eq!(
                (bits(p), bits(q)),
                (bits(p0), bits(q0)),
                "{name} head at {t} s"
            );
        }
        assert!(f.sample_hand_of(2, 0.0).is_none());
    }
}

/// `OLD_STYLE` made smooth.
fn smooth(text: &str) -> KeyframeFile {
    file(&text.replacen('\n', "\ninterpolation = \"smooth\"\n", 1))
}

#[test]
fn smooth_curves_pass_through_every_key_exactly() {
    let f = smooth(OLD_STYLE);
    assert_eq!(f.interpolation, Interpolation::Smooth);
    for hand in 0..2 {
        let keys = keys_of(&f, hand);
        for (i, k) in keys.iter().enumerate() {
            // Of two keys at one time the later one holds from then on (as with linear).
            if keys.get(i + 1).is_some_and(|n| n.t_s == k.t_s) {
                continue;
            }
            let s = f.sample_hand_of(hand, k.t_s).expect("keys");
            assert_eq!(
                bits(s.position),
                bits(Vec3::from(k.position)),
                "hand {hand} key {i}"
            );
            assert_eq!(
                bits(s.target),
                bits(Vec3::from(k.target)),
                "hand {hand} key {i}"
            );
            // Buttons stay linear, the mark as it was.
            assert_same(
                HandSample {
                    position: s.position,
                    target: s.target,
                    ..sample_hand(keys, k.t_s).expect("keys")
                },
                s,
                "buttons",
            );
        }
        let (first, last) = (keys[0], keys[keys.len() - 1]);
        let before = f.sample_hand_of(hand, -1.0).expect("keys");
        let after = f.sample_hand_of(hand, last.t_s + 1.0).expect("keys");
        assert_eq!(bits(before.position), bits(Vec3::from(first.position)));
        assert_eq!(bits(after.position), bits(Vec3::from(last.position)));
    }
    for k in &f.head {
        let (p, q) = f.sample_head_of(k.t_s);
        assert_eq!(
            (bits(p), bits(q)),
            (bits(k.position.into()), bits(k.target.into()))
        );
    }
    // Off the keys it does differ from the straight line.
    let mid = f.sample_hand_of(1, 1.4).expect("keys").position;
    assert_ne!(mid, sample_hand(&f.right, 1.4).expect("keys").position);
}

/// Right-hand keys along x at the given (time, x); y, z and the target's offset fixed.
fn along_x(keys: &[(f64, f32)], extra: &str) -> KeyframeFile {
    let mut text = format!(
        "procedure = \"nephrectomy\"\ninterpolation = \"smooth\"\n{extra}\n[[left]]\nt_s = 0.0\n\
         position = [0.0, 0.1, 0.1]\ntarget = [0.0, 0.0, 0.0]\n"
    );
    for (t, x) in keys {
        text += &format!(
            "[[right]]\nt_s = {t:?}\nposition = [{x:?}, 0.05, 0.02]\ntarget = [{x:?}, 0.0, 0.0]\n"
        );
    }
    file(&text)
}

fn x_at(f: &KeyframeFile, t: f64) -> f32 {
    f.sample_hand_of(1, t).expect("keys").position.x
}

#[test]
fn smooth_velocity_is_continuous_at_interior_keys() {
    // 0.1 m/s, then 0.2 m/s: the straight lines' velocity jumps by 0.1 m/s at t = 1 s; the
    // curve's is the Catmull-Rom slope, (0.1 + 0.2) / 2 = 0.15 m/s, from both sides.
    let f = along_x(&[(0.0, 0.0), (1.0, 0.1), (2.0, 0.3)], "");
    // Tolerance: a C1 curve's one-sided differences over d differ by about d / 2 times the
    // sum of the accelerations on the two sides; here 0 m/s^2 just before the key and
    // (6 * 0.2 - 4 * 0.15) / 1 = 0.6 m/s^2 just after, so 3e-4 m/s at d = 1 ms. Rounding
    // each f32 sample of about 0.1 m to within half a unit in the last place (3.7e-9 m) adds
    // at most 4 * 3.7e-9 / 1e-3 = 1.5e-5 m/s. 1e-3 m/s covers both and is a hundredth of
    // the jump a kink would make.
    let d = 1e-3;
    let tol = 1e-3;
    let back = f64::from(x_at(&f, 1.0) - x_at(&f, 1.0 - d)) / d;
    let fwd = f64::from(x_at(&f, 1.0 + d) - x_at(&f, 1.0)) / d;
    assert!(
        (back - fwd).abs() < tol,
        "before {back} m/s, after {fwd} m/s"
    );
    assert!(
        (back - 0.15).abs() < tol && (fwd - 0.15).abs() < tol,
        "{back} {fwd}"
    );
    // The lateral axes and the pointing direction do not move.
    let s = f.sample_hand_of(1, 1.0 + d).expect("keys");
    assert_eq!((s.position.y, s.position.z), (0.05, 0.02));
    assert!(
        ((s.target - s.position).normalize() - Vec3::new(0.0, -0.05, -0.02).normalize()).length()
            < 1e-6
    );
    // The test can see a kink: the straight lines fail it.
    let lin = |t: f64| f64::from(sample_hand(&f.right, t).expect("keys").position.x);
    let (lb, lf) = ((lin(1.0) - lin(1.0 - d)) / d, (lin(1.0 + d) - lin(1.0)) / d);
    assert!((lb - lf).abs() > 50.0 * tol, "{lb} {lf}");
    // At rest at the first and last key: one-sided velocities there are d / 2 times the
    // acceleration (0.3 and 0.9 m/s^2), under the tolerance.
    let start = f64::from(x_at(&f, d) - x_at(&f, 0.0)) / d;
    let end = f64::from(x_at(&f, 2.0) - x_at(&f, 2.0 - d)) / d;
    assert!(start.abs() < tol && end.abs() < tol, "{start} {end}");
}

#[test]
fn smooth_curves_do_not_overshoot_holds_reversals_or_ends() {
    // Out, held 1 s (a key repeated), on, back (a reversal), and to rest.
    let f = along_x(
        &[
            (0.0, 0.0),
            (1.0, 0.1),
            (2.0, 0.1),
            (3.0, 0.2),
            (4.0, 0.05),
            (5.0, 0.0),
        ],
        "",
    );
    let ts = (0..=6000).map(|i| -0.5 + f64::from(i) * 1e-3);
    for t in ts {
        let x = x_at(&f, t);
        let (lo, hi) = match t {
            t if t <= 0.0 => (0.0, 0.0),
            t if t <= 1.0 => (0.0, 0.1),
            // Between the two equal keys it stays exactly on them.
            t if t <= 2.0 => (0.1, 0.1),
            t if t <= 3.0 => (0.1, 0.2),
            // The reversal at 0.2 m stops there; the last segment ends at rest on its key.
            t if t <= 4.0 => (0.05, 0.2),
            t if t <= 5.0 => (0.0, 0.05),
            _ => (0.0, 0.0),
        };
        assert!(lo <= x && x <= hi, "x = {x} at {t} s, outside [{lo}, {hi}]");
        if lo == hi {
            assert_eq!(x.to_bits(), lo.to_bits(), "exactly on the key at {t} s");
        }
    }
    // A hold written with a sub-micrometre slip (as a recorded hand gives) is a hold too:
    // with the Catmull-Rom slope there, the 1 s segment would bulge by millimetres.
    let slip = along_x(&[(0.0, 0.0), (1.0, 0.1), (2.0, 0.1000005), (3.0, 0.2)], "");
    for i in 0..=1000 {
        let x = x_at(&slip, 1.0 + f64::from(i) * 1e-3);
        assert!((0.1..=0.1000005).contains(&x), "{x}");
    }
    // Two keys only: both ends at rest, the curve inside them.
    let two = along_x(&[(0.0, 0.0), (2.0, 0.2)], "");
    for i in 0..=200 {
        let x = x_at(&two, f64::from(i) * 0.01);
        assert!((0.0..=0.2).contains(&x), "{x}");
    }
    assert!(
        (x_at(&two, 1.0) - 0.1).abs() < 1e-7,
        "symmetric: half way at half time"
    );
}

/// The trace of `along_x` with this tremor on the right hand.
fn shaking(tremor: &str) -> KeyframeFile {
    let f = along_x(
        &[(0.0, 0.0), (2.0, 0.1), (4.0, 0.1)],
        &format!("[[tremor]]\n{tremor}"),
    );
    // Linear keys, to compare with `sample_hand` directly.
    KeyframeFile {
        interpolation: Interpolation::Linear,
        ..f
    }
}

const TREMOR: &str = "hand = \"right\"\namplitude_m = [0.001, 0.002, 0.0005]\nhz = 8.5\n\
                      phase = 0.3\nfrom_s = 1.0\nto_s = 3.0\n";

#[test]
fn tremor_adds_its_sine_inside_its_interval_and_nothing_outside() {
    let f = shaking(TREMOR);
    let amp = Vec3::new(0.001, 0.002, 0.0005);
    let offset = |t: f64| {
        let s = f.sample_hand_of(1, t).expect("keys");
        let base = sample_hand(&f.right, t).expect("keys");
        // The instrument shakes without turning (up to the f32 rounding of the sums).
        let (dir, was) = (s.target - s.position, base.target - base.position);
        assert!((dir - was).length() < 1e-7, "{dir} vs {was}");
        assert_eq!(
            (s.trigger, s.grip, s.mark),
            (base.trigger, base.grip, base.mark)
        );
        (s, base)
    };
    // Inside, past the fades: exactly amplitude * sin(2 pi hz t + phase).
    for t in [1.25, 1.7, 2.0, 2.345, 2.75] {
        let wave = (std::f64::consts::TAU * 8.5 * t + 0.3).sin();
        let want = (amp.as_dvec3() * wave).as_vec3();
        let (s, base) = offset(t);
        assert_eq!(bits(s.position), bits(base.position + want), "at {t} s");
        assert_eq!(bits(s.target), bits(base.target + want), "at {t} s");
    }
    // Outside (and on its ends, where the fades reach 0): nothing, bit for bit.
    for t in [0.0, 0.5, 0.999, 1.0, 3.0, 3.001, 3.5, 10.0] {
        let (s, base) = offset(t);
        assert_same(s, base, &format!("at {t} s"));
    }
    // The other hand never shakes.
    for t in [1.5, 2.0] {
        assert_same(
            f.sample_hand_of(0, t).expect("keys"),
            sample_hand(&f.left, t).expect("keys"),
            "left",
        );
    }
}

#[test]
fn tremor_fades_in_and_out_over_its_ends() {
    let f = shaking(TREMOR);
    let tr = f.tremor[0];
    let amp = Vec3::new(0.001, 0.002, 0.0005).as_dvec3();
    // Half way through each fade, half the shake.
    for t in [1.1, 2.9] {
        assert!((tremor_weight(&tr, t) - 0.5).abs() < 1e-12);
        let wave = (std::f64::consts::TAU * 8.5 * t + 0.3).sin();
        let (s, base) = (
            f.sample_hand_of(1, t).expect("keys").position,
            sample_hand(&f.right, t).expect("keys").position,
        );
        let want = amp * wave * 0.5;
        // Within f32 rounding of positions near 0.1 m (a unit in the last place: 7.5e-9 m).
        assert!((s - base).as_dvec3().distance(want) < 1e-8, "at {t} s");
    }
    assert!(
        (tremor_weight(&tr, 1.05) - (1.0 - (std::f64::consts::PI / 4.0).cos()) / 2.0).abs() < 1e-12
    );
    // No jump: within 1 ms of either end the shake is under a thousandth of its amplitude.
    for t in [1.001, 2.999] {
        let d = f.sample_hand_of(1, t).expect("keys").position
            - sample_hand(&f.right, t).expect("keys").position;
        assert!(
            d.abs().cmple(Vec3::new(0.001, 0.002, 0.0005) * 1e-3).all(),
            "{d} at {t} s"
        );
    }
    // Full strength between the fades, none outside the interval.
    assert_eq!(
        (
            tremor_weight(&tr, 1.25),
            tremor_weight(&tr, 2.0),
            tremor_weight(&tr, 2.75)
        ),
        (1.0, 1.0, 1.0)
    );
    assert_eq!(
        (tremor_weight(&tr, 0.9), tremor_weight(&tr, 3.1)),
        (0.0, 0.0)
    );
}

#[test]
fn tremor_defaults_to_the_whole_trace_and_entries_add_up() {
    let f = shaking(
        "hand = \"right\"\namplitude_m = [0.001, 0.0, 0.0]\nhz = 5.0\n\
         [[tremor]]\nhand = \"right\"\namplitude_m = [0.0, 0.0, 0.001]\nhz = 7.0\nphase = 1.0\n\
         [[tremor]]\nhand = \"left\"\namplitude_m = [0.0, 0.001, 0.0]\nhz = 6.0\n",
    );
    assert_eq!(f.tremor[0].from_s, 0.0);
    assert_eq!(f.tremor[0].phase, 0.0);
    assert_eq!(f.tremor[0].to_s, Some(4.0), "the trace's last key");
    let t = 1.3;
    let d = f.sample_hand_of(1, t).expect("keys").position
        - sample_hand(&f.right, t).expect("keys").position;
    let want = [
        0.001 * (std::f64::consts::TAU * 5.0 * t).sin(),
        0.0,
        0.001 * (std::f64::consts::TAU * 7.0 * t + 1.0).sin(),
    ];
    for (got, want) in d.to_array().into_iter().zip(want) {
        assert!((f64::from(got) - want).abs() < 1e-8, "{d} vs {want:?}");
    }
    let left = f.sample_hand_of(0, t).expect("keys").position - Vec3::new(0.0, 0.1, 0.1);
    assert!((f64::from(left.y) - 0.001 * (std::f64::consts::TAU * 6.0 * t).sin()).abs() < 1e-8);
    // Smooth motion and tremor together: the tremor rides on the curve.
    let smooth = KeyframeFile {
        interpolation: Interpolation::Smooth,
        ..f.clone()
    };
    let quiet = KeyframeFile {
        tremor: Vec::new(),
        ..smooth.clone()
    };
    let d2 = smooth.sample_hand_of(1, t).expect("keys").position
        - quiet.sample_hand_of(1, t).expect("keys").position;
    assert!((d2 - d).length() < 1e-7, "{d2} vs {d}");
}

#[test]
fn bad_additions_name_the_key() {
    let err = |tremor: &str| {
        let text = format!("{OLD_STYLE}[[tremor]]\n{tremor}");
        KeyframeFile::parse(&text).expect_err("refused")
    };
    let base = "hand = \"right\"\namplitude_m = [0.001, 0.001, 0.001]\nhz = 9.0\n";
    assert!(KeyframeFile::parse(&format!("{OLD_STYLE}[[tremor]]\n{base}")).is_ok());
    let cases = [
        (
            base.replace("[0.001, 0.001", "[-0.001, 0.001"),
            "tremor[0].amplitude_m",
            "-0.001",
        ),
        (
            base.replace("[0.001, 0.001", "[0.05, 0.001"),
            "tremor[0].amplitude_m",
            "0.02",
        ),
        (base.replace("hz = 9.0", "hz = 0"), "tremor[0].hz", "got 0"),
        (base.replace("hz = 9.0", "hz = 31.0"), "tremor[0].hz", "30"),
        (
            base.replace("\"right\"", "\"middle\""),
            "tremor[0].hand",
            "middle",
        ),
        (
            base.replace("hand = \"right\"\n", ""),
            "tremor[0].hand",
            "missing",
        ),
        (
            base.replace("hand = \"right\"", "hand = 1"),
            "tremor[0].hand",
            "got 1",
        ),
        (
            format!("{base}from_s = 2.0\nto_s = 1.5\n"),
            "tremor[0].to_s",
            "before from_s",
        ),
        (
            format!("{base}from_s = 5.0\n"),
            "tremor[0].from_s",
            "last key at 3 s",
        ),
        (format!("{base}from_s = -1.0\n"), "tremor[0].from_s", "-1"),
        (format!("{base}phase = nan\n"), "tremor[0].phase", "NaN"),
    ];
    for (tremor, key, says) in cases {
        let e = err(&tremor);
        assert_eq!(e.key, key, "{tremor}: {}", e.message);
        assert!(e.message.contains(says), "{key}: {}", e.message);
    }
    // The second entry is named as such.
    let e = err(&format!(
        "{base}[[tremor]]\n{}",
        base.replace("hz = 9.0", "hz = -2.0")
    ));
    assert_eq!(e.key, "tremor[1].hz");
    let e = KeyframeFile::parse(&OLD_STYLE.replacen('\n', "\ninterpolation = \"cubic\"\n", 1))
        .expect_err("refused");
    assert_eq!(e.key, "interpolation");
    assert!(
        e.message.contains("\"smooth\"") && e.message.contains("cubic"),
        "{}",
        e.message
    );
    // Other mistakes stay toml's, which names the field.
    let e = err(&format!("{base}hertz = 3.0\n"));
    assert_eq!(e.key, "toml");
    assert!(e.message.contains("hertz"), "{}", e.message);
}
