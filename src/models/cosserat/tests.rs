use super::reference::{Cantilever, heavy_params, reference_for, settled_cantilever};
use super::*;

#[test]
fn a_stiff_cantilever_sags_as_the_linear_beam_says() {
    let params = RodParams {
        youngs_modulus_pa: 1e7,
        ..heavy_params()
    };
    let (length, n) = (0.2, 40);
    let (rod, _) = settled_cantilever(params, n, length, 2e-3, 1e-6, 20.0);
    let drop = -rod.positions()[n].y;
    let r = reference_for(&params, length);
    let linear = r.load_n_per_m * length.powi(4) / (8.0 * r.bend_n_m2);
    eprintln!(
        "stiff cantilever: tip drop {drop:.7} m, q L^4 / 8 EI {linear:.7} m, Reissner {:.7} m",
        r.tip_drop()
    );
    assert!(
        (drop / linear - 1.0).abs() < 0.05,
        "tip drop {drop} m vs q L^4 / 8 EI = {linear} m"
    );
    // Shear and the slight stiffening of the deflected shape: the Reissner beam, closer.
    let exact = r.tip_drop();
    assert!((drop / exact - 1.0).abs() < 0.005, "{drop} vs {exact}");
}

#[test]
fn the_heavy_cantilever_hangs_as_the_elastica_says() {
    let params = heavy_params();
    let (length, n) = (0.2, 200);
    let wall = std::time::Instant::now();
    let (rod, t) = settled_cantilever(params, n, length, 5e-3, 1e-6, 30.0);
    let wall = wall.elapsed().as_secs_f64();
    let drop = -rod.positions()[n].y;
    let reference = reference_for(&params, length).tip_drop();
    let inextensible = Cantilever {
        axial_n: f64::INFINITY,
        shear_n: f64::INFINITY,
        ..reference_for(&params, length)
    }
    .tip_drop();
    eprintln!(
        "heavy cantilever: tip drop {drop:.6} m, Reissner {reference:.6} m, inextensible elastica \
         {inextensible:.6} m; at rest after {t:.2} s simulated in {wall:.2} s"
    );
    assert!(
        (drop / reference - 1.0).abs() < 0.02,
        "tip drop {drop} m vs the elastica's {reference} m (settled after {t} s)"
    );
}

#[test]
fn a_torque_twists_the_rod_by_t_l_over_g_j() {
    let params = RodParams {
        gravity: DVec3::ZERO,
        ..heavy_params()
    };
    let (length, n) = (0.2, 100);
    let mut rod = CosseratRod::straight(n, length, DVec3::ZERO, DVec3::X, params);
    rod.fix_node(0, true);
    let clamp = rod.frames()[0];
    let torque = 1e-4;
    for _ in 0..400 {
        rod.add_torque(n - 1, DVec3::X * torque);
        rod.step(5e-3);
    }
    let twist = so3::log(rod.frames()[n - 1] * clamp.transpose());
    let (_, _, j) = params.section();
    let reference = torque * length / (params.shear_modulus_pa() * j);
    assert!(
        (twist.x / reference - 1.0).abs() < 0.05,
        "twist {} rad vs T L / G J = {reference} rad",
        twist.x
    );
    assert!(twist.y.abs() + twist.z.abs() < 1e-6 * reference, "{twist}");
}

#[test]
fn without_load_the_energy_never_grows() {
    let params = RodParams {
        gravity: DVec3::ZERO,
        damping_per_s: 0.0,
        curvature_damping_n_m2_s: 0.0,
        ..heavy_params()
    };
    let mut rod = CosseratRod::straight(30, 0.2, DVec3::ZERO, DVec3::X, params);
    // A kick: the free rod's middle pushed sideways and twisted.
    for i in 10..20 {
        rod.v[i] = DVec3::new(0.0, 0.3, 0.1);
    }
    rod.omega[15] = DVec3::X * 5.0;
    let total = |r: &CosseratRod| r.kinetic_energy() + r.elastic_energy();
    let start = total(&rod);
    let mut last = start;
    for _ in 0..500 {
        rod.step(2e-3);
        let e = total(&rod);
        assert!(e <= last * (1.0 + 1e-9) + 1e-15, "{e} after {last}");
        last = e;
    }
    assert!(last < start && last > 0.0, "{last} of {start}");
}

#[test]
fn a_rod_at_rest_stays_exactly_put() {
    let mut rod = CosseratRod::straight(20, 0.1, DVec3::ONE, DVec3::Y, heavy_params());
    rod.params.gravity = DVec3::ZERO;
    let before = rod.positions().to_vec();
    let stats = rod.step(1e-3);
    assert_eq!(stats.iterations, 1);
    assert_eq!(rod.positions(), &before[..]);
    assert!(rod.is_finite());
}

#[test]
fn refining_the_rod_converges_to_the_beam_at_second_order() {
    let params = RodParams {
        youngs_modulus_pa: 1e6,
        ..heavy_params()
    };
    let reference = reference_for(&params, 0.2).tip_drop();
    let error = |n: usize| {
        let (rod, _) = settled_cantilever(params, n, 0.2, 2e-3, 1e-7, 60.0);
        (-rod.positions()[n].y / reference - 1.0).abs()
    };
    let (coarse, fine) = (error(10), error(40));
    // Four times the elements, a sixteenth of the error (allowing for what settling leaves).
    assert!(fine < coarse / 8.0, "{coarse} then {fine}");
}
