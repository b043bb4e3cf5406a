use super::*;

/// A flat sheet of four layers `gap` apart (layer l at y = -l gap), `rows x cols` nodes
/// `spacing` apart in x (rows) and z (columns), not a ring.
fn sheet(rows: usize, cols: usize, spacing: f32, gap: f32) -> MembraneShape {
    let positions = std::array::from_fn(|l| {
        (0..rows * cols)
            .map(|k| {
                let (i, j) = (k / cols, k % cols);
                Vec3::new(i as f32 * spacing, -(l as f32) * gap, j as f32 * spacing)
            })
            .collect()
    });
    MembraneShape {
        rows,
        cols,
        periodic: false,
        positions,
    }
}

/// A straight tube along x: layer l a ring of radius `radii[l]`.
fn tube(rows: usize, cols: usize, length: f32, radii: [f32; LAYERS]) -> MembraneShape {
    let positions = std::array::from_fn(|l| {
        (0..rows * cols)
            .map(|k| {
                let (i, j) = (k / cols, k % cols);
                let a = std::f32::consts::TAU * j as f32 / cols as f32;
                let x = length * i as f32 / (rows - 1) as f32;
                Vec3::new(x, radii[l] * a.cos(), radii[l] * a.sin())
            })
            .collect()
    });
    MembraneShape {
        rows,
        cols,
        periodic: true,
        positions,
    }
}

fn params(integrator: Integrator) -> MembraneParams {
    let fat = LayerMaterial {
        youngs_modulus_pa: 2e3,
        thickness_m: 2e-3,
        density_kg_per_m3: 950.0,
    };
    MembraneParams {
        layers: [fat; LAYERS],
        link_modulus_pa: [2e3; LAYERS - 1],
        damping_per_s: 5.0,
        spring_damping_ratio: 0.05,
        attach_pa_per_m: 1e6,
        residual_strain: 0.1,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        integrator,
    }
}

/// Forces on every node now (no step).
fn forces_now(m: &Membrane) -> Vec<Vec3> {
    integrate::tests_support::forces(m)
}

#[test]
fn a_stretched_spring_pulls_as_eqs_3_and_4_say() {
    let mut p = params(Integrator::Symplectic);
    p.gravity = Vec3::ZERO;
    p.damping_per_s = 0.0;
    p.spring_damping_ratio = 0.0;
    let mut m = Membrane::new(sheet(3, 3, 0.01, 0.005), p).expect("membrane");
    // Move the middle node of layer 1 (row 1, column 1) 2 mm along +x: its along-springs
    // to rows 0 and 2 change length by +2 and -2 mm, its ring springs and links tilt.
    let node = m.node(1, 1, 1);
    let at = m.state_at(0, node);
    m.state.data[at] += 0.002;
    let f = forces_now(&m)[node];
    // Hand-computed: along springs k = E t w / L0 with w = L0 = 10 mm: k = E t = 4 N/m each;
    // stretched by 2 mm and compressed by 2 mm: -2 * 4 * 0.002 = -0.016 N in x. The two ring
    // springs (to columns 0 and 2) now have length sqrt(10^2 + 2^2) mm: each pulls back by
    // k (L - L0) * 2 / L in x, k = 4 N/m. The links (E A / L0, A = 1e-4 m^2, L0 = 5 mm:
    // 0.04 N/m) likewise, to layers 0 and 2.
    let (l0, dx) = (0.01f32, 0.002f32);
    let len = (l0 * l0 + dx * dx).sqrt();
    let ring = 2.0 * 4.0 * (len - l0) * dx / len;
    let (g0, gl) = (0.005f32, (0.005f32 * 0.005 + dx * dx).sqrt());
    let k_link = 2e3 * 1e-4 / g0;
    let links = 2.0 * k_link * (gl - g0) * dx / gl;
    let want = -(2.0 * 4.0 * dx) - ring - links;
    assert!((f.x - want).abs() < 1e-6, "{} N vs {want} N", f.x);
    assert!(f.y.abs() < 1e-7 && f.z.abs() < 1e-7, "{f}");
}

#[test]
fn a_free_sheet_under_residual_strain_shrinks_by_it() {
    let mut p = params(Integrator::Symplectic);
    p.gravity = Vec3::ZERO;
    p.link_modulus_pa = [0.0; LAYERS - 1];
    // Overdamped: the sheet draws in without overshooting. (Structural springs alone resist
    // neither shear nor bending: a row that overshot would stay folded at zero energy.)
    p.spring_damping_ratio = 0.5;
    p.damping_per_s = 300.0;
    let (rows, cols, spacing) = (21, 11, 0.002);
    let mut m = Membrane::new(sheet(rows, cols, spacing, 0.003), p).expect("membrane");
    m.detach_layer(0);
    m.detach_layer(LAYERS - 1);
    for i in 0..rows {
        for j in 0..cols {
            let node = m.node(1, i, j);
            m.release(node);
        }
    }
    let dt = 0.5 * m.explicit_step_limit();
    for _ in 0..(4.0 / dt) as usize {
        m.step(dt);
    }
    let span = |l: usize| {
        let (a, b) = (m.node(l, 0, cols / 2), m.node(l, rows - 1, cols / 2));
        m.position(b).distance(m.position(a))
    };
    let rest = (rows - 1) as f32 * spacing;
    let across = m
        .position(m.node(1, 10, cols - 1))
        .distance(m.position(m.node(1, 10, 0)));
    let across = 1.0 - across / ((cols - 1) as f32 * spacing);
    assert!((across - 0.1).abs() < 0.015, "shrank across by {across}");
    let shrink = 1.0 - span(1) / rest;
    assert!((shrink - 0.1).abs() < 0.015, "shrank by {shrink}");
    // The layers without residual strain keep their size.
    assert!((span(2) / rest - 1.0).abs() < 1e-4, "{}", span(2));
}

#[test]
fn the_equilibrium_does_not_depend_on_the_integrator_or_the_step() {
    let shape = || tube(12, 16, 0.03, [0.01, 0.012, 0.013, 0.016]);
    let limit = Membrane::new(shape(), params(Integrator::Symplectic))
        .expect("membrane")
        .explicit_step_limit();
    let settle = |integrator, dt: f32| {
        let mut m = Membrane::new(shape(), params(integrator)).expect("membrane");
        for _ in 0..(3.0 / dt) as usize {
            m.step(dt);
        }
        m
    };
    let a = settle(Integrator::Symplectic, 0.5 * limit);
    let b = settle(Integrator::Symplectic, 0.1 * limit);
    let c = settle(Integrator::RungeKutta4, 0.9 * limit);
    let probe = a.node(2, 6, 4);
    let rest = shape().positions[2][6 * 16 + 4].y;
    let sag = |m: &Membrane| m.position(probe).y - rest;
    let (a, b, c) = (sag(&a), sag(&b), sag(&c));
    assert!(a < -1e-6, "the tissue sags under gravity: {a}");
    assert!(
        (a - b).abs() < 0.01 * a.abs(),
        "{a} at half the limit vs {b} at a tenth"
    );
    assert!(
        (a - c).abs() < 0.01 * a.abs(),
        "symplectic {a} vs Runge-Kutta {c}"
    );
}

#[test]
fn the_explicit_limit_separates_stable_steps_from_unstable_ones() {
    let mut p = params(Integrator::Symplectic);
    p.gravity = Vec3::ZERO;
    let kicked = |dt: f32| {
        let mut m =
            Membrane::new(tube(16, 24, 0.04, [0.01, 0.011, 0.012, 0.015]), p).expect("membrane");
        for j in 0..24 {
            let node = m.node(1, 8, j);
            let at = m.state_at(4, node);
            m.state.data[at] = 0.5;
        }
        let start = m.kinetic_energy();
        for _ in 0..2000 {
            m.step(dt);
        }
        (
            m.is_finite() && m.kinetic_energy() < start,
            m.kinetic_energy() / start,
        )
    };
    let limit = Membrane::new(tube(16, 24, 0.04, [0.01, 0.011, 0.012, 0.015]), p)
        .expect("membrane")
        .explicit_step_limit();
    assert!(
        kicked(0.9 * limit).0,
        "at 0.9 x the limit: {:?}",
        kicked(0.9 * limit)
    );
    assert!(
        !kicked(3.0 * limit).0,
        "at 3 x the limit: {:?}",
        kicked(3.0 * limit)
    );
}

#[test]
fn cutting_removes_only_the_plane_links_inside_the_sphere() {
    let mut m = Membrane::new(sheet(10, 10, 0.002, 0.003), params(Integrator::Symplectic))
        .expect("membrane");
    let springs = m.springs();
    let c = m.node(1, 5, 5);
    let center = (m.position(c) + m.position(c + 100)) * 0.5;
    // 2.5 mm: the link at (5, 5) and its four neighbours 2 mm away.
    let cut = m.cut_plane(center, 0.0025);
    assert_eq!(cut, 5);
    assert_eq!(m.springs(), springs - 5);
    for i in 0..10 {
        for j in 0..10 {
            let near = (i as i32 - 5).abs() + (j as i32 - 5).abs() <= 1;
            assert_eq!(m.link_alive(1, i, j), !near, "({i}, {j})");
            assert!(m.link_alive(0, i, j) && m.link_alive(2, i, j));
        }
    }
    // Cutting again there finds nothing.
    assert_eq!(m.cut_plane(center, 0.0025), 0);
}

#[test]
fn one_or_two_threads_give_the_same_bytes() {
    let run = |threads| {
        crate::sim::on_threads(threads, || {
            let mut m = Membrane::new(
                tube(40, 32, 0.05, [0.01, 0.012, 0.013, 0.016]),
                params(Integrator::Symplectic),
            )
            .expect("membrane");
            m.cut_plane(m.position(m.node(1, 20, 3)), 0.004);
            let dt = 0.5 * m.explicit_step_limit();
            for _ in 0..50 {
                m.step(dt);
            }
            m.state_hash()
        })
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn bad_shapes_and_parameters_are_refused_with_a_reason() {
    let p = params(Integrator::Symplectic);
    assert!(matches!(
        Membrane::new(sheet(1, 5, 0.01, 0.01), p),
        Err(MembraneError::TooSmall { .. })
    ));
    let mut s = sheet(3, 3, 0.01, 0.01);
    s.positions[2].pop();
    assert!(matches!(
        Membrane::new(s, p),
        Err(MembraneError::WrongCount { layer: 2, .. })
    ));
    let mut bad = p;
    bad.layers[0].thickness_m = f32::NAN;
    assert!(matches!(
        Membrane::new(sheet(3, 3, 0.01, 0.01), bad),
        Err(MembraneError::BadParameter { .. })
    ));
}
