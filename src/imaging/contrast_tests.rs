use super::*;

/// A trunk of 10 cm, radius 5 mm, carrying 5 mL/s (0.0637 m/s: 1.571 s to cross), splitting
/// into two branches of 5 cm, radius 3.5 mm, 2.5 mL/s each (0.0650 m/s: 0.770 s).
fn tree(dt: f64) -> Contrast {
    let trunk = Vessel {
        parent: None,
        length_m: 0.1,
        radius_m: 0.005,
        flow_m3_per_s: 5e-6,
    };
    let branch = Vessel {
        parent: Some(0),
        length_m: 0.05,
        radius_m: 0.0035,
        flow_m3_per_s: 2.5e-6,
    };
    Contrast::new(vec![trunk, branch, branch], dt).expect("tree")
}

#[test]
fn a_puff_arrives_after_the_transit_time_and_washes_out() {
    // 5 mL/s of contrast into the trunk's start for 1 s: half contrast (5 / (5 + 5)). Halfway
    // along a branch it arrives after 0.1 / v_trunk + 0.025 / v_branch and stays 1 s.
    let v_trunk = 5e-6 / (std::f64::consts::PI * 0.005 * 0.005);
    let v_branch = 2.5e-6 / (std::f64::consts::PI * 0.0035 * 0.0035);
    let arrival = 0.1 / v_trunk + 0.025 / v_branch;
    assert!((arrival - 1.955).abs() < 0.01, "{arrival}");
    for dt in [0.001, 0.002] {
        let mut c = tree(dt);
        let mut seen = Vec::new();
        while c.time_s() < 5.0 {
            let puff = (c.time_s() < 1.0 - 1e-9).then_some((0, 0.0, 5e-6));
            c.step(puff);
            seen.push((
                c.time_s() - dt,
                c.concentration(1, 0.025),
                c.concentration(2, 0.025),
            ));
        }
        for &(t, a, b) in &seen {
            assert_eq!(a, b, "both branches alike at {t}");
            if t < arrival - 0.01 || t > arrival + 1.0 + 0.01 {
                assert!(a.abs() < 1e-9, "dt {dt}: {a} at {t} s");
            } else if t > arrival + 0.01 && t < arrival + 1.0 - 0.01 {
                assert!((a - 0.5).abs() < 1e-9, "dt {dt}: {a} at {t} s");
            }
        }
    }
}

#[test]
fn a_puff_into_one_branch_stays_in_it() {
    let mut c = tree(0.001);
    for _ in 0..500 {
        c.step(Some((1, 0.01, 1e-6)));
    }
    // Downstream of the tip in its branch: 1 / (2.5 + 1); upstream of it, in the trunk and in
    // the other branch: none.
    assert!((c.concentration(1, 0.02) - 1.0 / 3.5).abs() < 1e-9);
    assert_eq!(c.concentration(1, 0.005), 0.0);
    assert_eq!(c.concentration(0, 0.05), 0.0);
    assert_eq!(c.concentration(2, 0.03), 0.0);
}

#[test]
fn a_long_session_keeps_only_what_the_transits_need() {
    let mut c = tree(0.001);
    for k in 0..20_000 {
        c.step((k % 5000 < 1000).then_some((0, 0.0, 5e-6)));
    }
    assert!(c.entered[0].len() <= 2 * c.window, "{}", c.entered[0].len());
    // 20 s in: the fourth puff (15-16 s) is in the branch's middle from 16.955 s to 17.955 s.
    let mut d = tree(0.001);
    for k in 0..17_500 {
        d.step((k % 5000 < 1000).then_some((0, 0.0, 5e-6)));
    }
    assert!((d.concentration(1, 0.025) - 0.5).abs() < 1e-9);
}

#[test]
fn a_tree_that_loses_blood_is_refused_naming_the_vessel() {
    let mut v = tree(0.001).vessels().to_vec();
    v[2].flow_m3_per_s = 1e-6;
    let e = Contrast::new(v.clone(), 0.001).expect_err("flow lost");
    assert_eq!(e.vessel, 0);
    assert!(e.to_string().contains("neither made nor lost"), "{e}");
    v[2].flow_m3_per_s = 2.5e-6;
    v[1].parent = Some(2);
    let e = Contrast::new(v.clone(), 0.001).expect_err("order");
    assert_eq!(e.vessel, 1);
    v[1].parent = Some(0);
    v[1].radius_m = f64::NAN;
    assert!(
        Contrast::new(v, 0.001)
            .expect_err("NaN")
            .to_string()
            .contains("radius_m")
    );
}
