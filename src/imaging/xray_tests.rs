use super::*;

/// A scene of one flat-ended cylinder of water-like material (mu = 20 /m, about water's at
/// 60 keV) from `a` to `b`.
fn water_cylinder(a: DVec3, b: DVec3, radius: f64) -> Scene {
    Scene {
        materials: vec![Material {
            name: "water".into(),
            mu_per_m: 20.0,
        }],
        bodies: vec![(Body::Cylinder { a, b, radius }, 0)],
    }
}

/// A water-like phantom: a cylinder of radius 5 cm along z, mu = 20 /m (about water's at
/// 60 keV), 10 cm long; the source 1 m above it on y, the detector 0.5 m below, rows along x.
fn phantom() -> (Scene, CArm) {
    let scene = water_cylinder(
        DVec3::new(0.0, 0.0, -0.05),
        DVec3::new(0.0, 0.0, 0.05),
        0.05,
    );
    let arm = CArm {
        source: DVec3::new(0.0, 1.0, 0.0),
        forward: DVec3::NEG_Y,
        right: DVec3::X,
        distance_m: 1.5,
        width: 64,
        height: 1,
        pixel_m: 0.003,
    };
    (scene, arm)
}

#[test]
fn a_cylinder_phantom_attenuates_as_beer_lambert_says() {
    // The ray to a pixel at x on the detector passes the axis at distance
    // d = 1 * |x| / sqrt(1.5^2 + x^2) (similar triangles from the source 1 m above the axis);
    // its chord through the circle is 2 sqrt(r^2 - d^2), so the transmission is
    // exp(-mu 2 sqrt(r^2 - d^2)).
    let (scene, arm) = phantom();
    let f = expose(&scene, &arm, 1e6, None);
    let mut inside = 0;
    for i in 0..arm.width {
        let x = arm.pixel(i, 0).x;
        let d = x.abs() / (1.5f64 * 1.5 + x * x).sqrt();
        let chord = 2.0 * (0.05f64 * 0.05 - d * d).max(0.0).sqrt();
        let want = (-20.0 * chord).exp();
        let got = f.counts[i] / 1e6;
        assert!(
            (got - want).abs() <= 0.02 * want,
            "pixel {i}: {got} vs {want}"
        );
        if chord > 0.0 {
            inside += 1;
        }
    }
    // The phantom's shadow: 2 r * 1.5 / 1 = 15 cm wide, about 50 of the 64 pixels of 3 mm.
    assert!((45..=55).contains(&inside), "{inside}");
    // Through the middle: the whole diameter, exp(-20 * 0.1) = 0.135.
    let mid = f.counts[31].max(f.counts[32]) / 1e6;
    assert!(
        (mid - (-2.0f64).exp()).abs() < 0.02 * (-2.0f64).exp(),
        "{mid}"
    );
}

#[test]
fn bodies_of_one_material_that_overlap_count_once() {
    // Two capsules along x overlapping by 2 cm, radius 1 cm: a ray along x through their
    // axes crosses 1 + 4 + 4 - 2 + 1 = 8 cm of material (the ends' caps included).
    let m = Material {
        name: "contrast".into(),
        mu_per_m: 10.0,
    };
    let caps = Scene {
        materials: vec![m],
        bodies: vec![
            (
                Body::Capsule {
                    a: DVec3::new(0.0, 0.0, 0.0),
                    b: DVec3::new(0.04, 0.0, 0.0),
                    radius: 0.01,
                },
                0,
            ),
            (
                Body::Capsule {
                    a: DVec3::new(0.02, 0.0, 0.0),
                    b: DVec3::new(0.06, 0.0, 0.0),
                    radius: 0.01,
                },
                0,
            ),
        ],
    };
    let a = caps.attenuation(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0));
    assert!((a - 10.0 * 0.08).abs() < 1e-9, "{a}");
    // Across one of them, 1 mm off its axis: 2 sqrt(1 - 0.01) cm.
    let b = caps.attenuation(DVec3::new(0.01, -1.0, 0.001), DVec3::new(0.01, 1.0, 0.001));
    assert!(
        (b - 10.0 * 2.0 * (0.0001f64 - 0.000001).sqrt()).abs() < 1e-9,
        "{b}"
    );
    assert_eq!(
        union_length(vec![(0.0, 2.0), (1.0, 3.0), (5.0, 6.0)], 0.5, 5.5),
        3.0
    );
}

#[test]
fn the_noise_grows_as_the_dose_falls() {
    // A flat field behind 5 cm of the phantom's material (transmission exp(-1)): the
    // measured line integral -ln(N / N0) has variance 1 / (N0 exp(-1)) to first order (a
    // Poisson count's relative variance is 1 / N); a quarter of the dose, four times it.
    let scene = water_cylinder(
        DVec3::new(0.0, 0.025, 0.0),
        DVec3::new(0.0, -0.025, 0.0),
        1.0,
    );
    let arm = CArm {
        source: DVec3::new(0.0, 1.0, 0.0),
        forward: DVec3::NEG_Y,
        right: DVec3::X,
        distance_m: 1.0e3,
        width: 100,
        height: 100,
        pixel_m: 1e-4,
    };
    let variance = |photons: f64| {
        let f = expose(&scene, &arm, photons, Some(7));
        let n = f.line_integrals.len() as f64;
        let mean = f.line_integrals.iter().sum::<f64>() / n;
        let var = f
            .line_integrals
            .iter()
            .map(|x| (x - mean).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        (mean, var)
    };
    for photons in [4000.0, 1000.0] {
        let (mean, var) = variance(photons);
        let want = 1.0 / (photons * (-1.0f64).exp());
        assert!((mean - 1.0).abs() < 0.01, "{photons}: mean {mean}");
        assert!(
            (var - want).abs() < 0.1 * want,
            "{photons}: {var} vs {want}"
        );
    }
    // The same seed, the same frame.
    assert_eq!(
        expose(&scene, &arm, 1000.0, Some(3)),
        expose(&scene, &arm, 1000.0, Some(3))
    );
}

/// The tiles' lists of bodies leave out only bodies a ray cannot meet: a scene of 90 bodies
/// of three kinds and two materials, scattered round the beam (some near the source, one
/// holding it), gives every pixel the attenuation the ray through every body gives, to the
/// bit, and the lists are shorter than the scene.
#[test]
fn the_tiles_lists_of_bodies_change_no_pixel() {
    let mut g = crate::rng::SplitMix64(11);
    let mut at = || DVec3::new(g.unit() - 0.5, 0.8 * g.unit() - 0.4, g.unit() - 0.5) * 0.4;
    let mut bodies = Vec::new();
    for k in 0..90 {
        let (a, b) = (at(), at());
        let body = match k % 3 {
            0 => Body::Sphere {
                centre: a,
                radius: 0.01 + 0.02 * (k as f64 / 90.0),
            },
            1 => Body::Capsule {
                a,
                b: a + 0.2 * (b - a),
                radius: 0.005,
            },
            _ => Body::Cylinder {
                a,
                b: a + 0.3 * (b - a),
                radius: 0.008,
            },
        };
        bodies.push((body, k % 2));
    }
    // One body holding the source, one beside it.
    bodies.push((
        Body::Sphere {
            centre: DVec3::new(0.0, 1.0, 0.0),
            radius: 0.05,
        },
        0,
    ));
    bodies.push((
        Body::Sphere {
            centre: DVec3::new(0.03, 0.97, 0.0),
            radius: 0.01,
        },
        1,
    ));
    let scene = Scene {
        materials: vec![
            Material {
                name: "tissue".into(),
                mu_per_m: 20.0,
            },
            Material {
                name: "bone".into(),
                mu_per_m: 50.0,
            },
        ],
        bodies,
    };
    let arm = CArm {
        source: DVec3::new(0.0, 1.0, 0.0),
        forward: DVec3::NEG_Y,
        right: DVec3::X,
        distance_m: 1.5,
        width: 80,
        height: 72,
        pixel_m: 0.006,
    };
    let f = expose(&scene, &arm, 1e5, None);
    let mut shadowed = 0;
    for j in 0..arm.height {
        for i in 0..arm.width {
            let direct = scene.attenuation(arm.source, arm.pixel(i, j));
            let got = f.line_integrals[j * arm.width + i];
            let want = -((1e5 * (-direct).exp()).max(1e-300) / 1e5).ln();
            assert_eq!(got.to_bits(), want.to_bits(), "pixel {i}, {j}");
            shadowed += usize::from(direct > 0.05 * 20.0);
        }
    }
    assert!(shadowed > 500, "the bodies show: {shadowed}");
    let lists = scene.tiles(&arm);
    let longest = lists.iter().map(Vec::len).max().unwrap_or(0);
    assert!(longest < scene.bodies.len(), "{longest}");
    assert!(
        lists.iter().all(|l| l.contains(&90)),
        "the source's own body in every list"
    );
}
