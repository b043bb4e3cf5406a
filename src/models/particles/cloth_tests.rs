use super::*;

const H: f32 = 0.01;
const N: usize = 10;
/// Fascia-like sheet: 1000 kg/m^3, 0.5 mm thick.
const DENSITY: f32 = 1000.0;
const THICKNESS: f32 = 5e-4;

/// Each particle's share of the sheet's mass, kg.
fn particle_mass() -> f32 {
    let side = (N - 1) as f32 * H;
    DENSITY * THICKNESS * side * side / (N * N) as f32
}

/// An `N x N` sheet `H` apart, particle `j N + i` at `place(i, j)`, with its cells split along
/// the (i, j)-(i + 1, j + 1) diagonal, wound counter-clockwise seen from +z.
fn sheet(place: impl Fn(usize, usize) -> Vec3) -> (Particles, Vec<[u32; 3]>) {
    let mut p = Particles::new();
    for j in 0..N {
        for i in 0..N {
            p.add(place(i, j), particle_mass(), 0);
        }
    }
    let id = |i: usize, j: usize| (j * N + i) as u32;
    let mut tris = Vec::new();
    for j in 0..N - 1 {
        for i in 0..N - 1 {
            tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (p, tris)
}

fn flat(i: usize, j: usize) -> Vec3 {
    Vec3::new(i as f32 * H, j as f32 * H, 0.0)
}

/// A number in [-1, 1] from two integers (a fixed hash: the same every run).
fn jitter(i: usize, k: usize) -> f32 {
    let mut z = (i as u64) << 8 | k as u64;
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 23) as f32 - 1.0
}

fn params(stretch: f32, bend: f32) -> ClothParams {
    ClothParams {
        stretch_stiffness_n_per_m: stretch,
        bend_stiffness_n_m_per_rad: bend,
    }
}

/// Steps the world `steps` times: predict, `iters` sweeps of the cloth, finish.
fn run(p: &mut Particles, c: &mut Cloth, gravity: Vec3, iters: usize, damping: f32, steps: usize) {
    let dt = 1e-3;
    for _ in 0..steps {
        p.predict(dt, gravity);
        c.begin_step();
        for _ in 0..iters {
            c.project(p, dt);
        }
        p.finish(dt, damping);
    }
}

#[test]
fn a_grid_has_an_edge_per_side_and_a_hinge_per_inner_edge() {
    let (p, tris) = sheet(flat);
    let c = Cloth::new(&p, &tris, params(10.0, 1e-5)).expect("cloth");
    // Rows, columns and diagonals; every edge but the border's is shared by two triangles.
    let edges = 2 * N * (N - 1) + (N - 1) * (N - 1);
    assert_eq!(c.edges(), edges);
    assert_eq!(c.hinges(), edges - 4 * (N - 1));
    // A flat sheet rests flat, every edge at its length.
    assert!(c.bend_constraints().iter().all(|b| b.rest_rad == 0.0));
    for s in c.stretch_constraints() {
        let expect = if (s.b - s.a) as usize == N + 1 {
            H * std::f32::consts::SQRT_2
        } else {
            H
        };
        assert!((s.rest_m - expect).abs() < 1e-7, "{s:?}");
    }
    assert!(c.heap_bytes() >= c.edges() * 12 + c.hinges() * 20);
}

/// The sheet rolled on a cylinder of radius `R` about the x axis, rows `DTHETA` apart.
const R: f32 = 0.05;
const DTHETA: f32 = 0.2;

fn rolled(i: usize, j: usize) -> Vec3 {
    let t = j as f32 * DTHETA;
    Vec3::new(i as f32 * H, R * t.sin(), R * (1.0 - t.cos()))
}

#[test]
fn rest_angles_are_the_dihedrals_of_the_present_shape() {
    // On the rolled sheet, each cell is flat (its corners lie on two rulings), so the hinges
    // across the diagonals and the columns are flat, and the hinges along the rows (x) are
    // folded by the angle between neighbouring rows' planes, DTHETA, all the same way.
    let (p, tris) = sheet(rolled);
    let c = Cloth::new(&p, &tris, params(10.0, 1e-5)).expect("cloth");
    let mut folded = Vec::new();
    for b in c.bend_constraints() {
        if b.b.abs_diff(b.a) == 1 {
            folded.push(b.rest_rad);
        } else {
            assert!(b.rest_rad.abs() < 1e-4, "{b:?}");
        }
    }
    assert_eq!(folded.len(), (N - 1) * (N - 2));
    let sign = folded[0].signum();
    for phi in folded {
        assert!((phi - sign * DTHETA).abs() < 1e-4, "{phi} vs {DTHETA}");
    }
}

#[test]
fn a_crumpled_free_sheet_finds_its_rest_shape_by_itself() {
    // The rolled sheet, every particle moved up to 1 mm (10 % of the spacing) each way, free,
    // with no gravity: its springs alone bring every edge and hinge back to rest.
    let (mut p, tris) = sheet(rolled);
    let mut c = Cloth::new(&p, &tris, params(10.0, 1e-5)).expect("cloth");
    for (i, x) in p.x.iter_mut().enumerate() {
        *x += 1e-3 * Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2));
    }
    let (s0, b0) = (c.max_stretch_strain(&p), c.max_bend_error(&p));
    assert!(s0 > 0.05 && b0 > 0.1, "{s0} {b0}");
    run(&mut p, &mut c, Vec3::ZERO, 10, 10.0, 3000);
    let (s1, b1) = (c.max_stretch_strain(&p), c.max_bend_error(&p));
    println!("crumpled sheet: strain {s0} -> {s1}, bend error {b0} -> {b1} rad");
    assert!(p.is_finite());
    assert!(s1 < 1e-4 && b1 < 1e-3, "{s1} {b1}");
    // The same inputs, the same bytes.
    let again = {
        let (mut q, tris) = sheet(rolled);
        let mut c = Cloth::new(&q, &tris, params(10.0, 1e-5)).expect("cloth");
        for (i, x) in q.x.iter_mut().enumerate() {
            *x += 1e-3 * Vec3::new(jitter(i, 0), jitter(i, 1), jitter(i, 2));
        }
        run(&mut q, &mut c, Vec3::ZERO, 10, 10.0, 3000);
        q.state_hash()
    };
    assert_eq!(p.state_hash(), again);
}

/// Solves `a u = b` for a symmetric positive definite `a` (`dofs x dofs`, row-major) by
/// Cholesky, in place.
fn cholesky_solve(a: &mut [f64], b: &mut [f64], dofs: usize) {
    for j in 0..dofs {
        let mut s = a[j * dofs + j];
        for m in 0..j {
            s -= a[j * dofs + m] * a[j * dofs + m];
        }
        assert!(s > 0.0, "stiffness matrix not positive definite");
        let ljj = s.sqrt();
        a[j * dofs + j] = ljj;
        for r in j + 1..dofs {
            let mut s = a[r * dofs + j];
            for m in 0..j {
                s -= a[r * dofs + m] * a[j * dofs + m];
            }
            a[r * dofs + j] = s / ljj;
        }
    }
    for r in 0..dofs {
        for m in 0..r {
            b[r] -= a[r * dofs + m] * b[m];
        }
        b[r] /= a[r * dofs + r];
    }
    for r in (0..dofs).rev() {
        for m in r + 1..dofs {
            b[r] -= a[m * dofs + r] * b[m];
        }
        b[r] /= a[r * dofs + r];
    }
}

/// The flat sheet's static equilibrium under its weight with its top row pinned, from the
/// springs' energy `sum k (|x_p - x_q| - l0)^2 / 2` alone (in the sheet's plane, in f64), by
/// Newton's method: returns the bottom row's mean drop after the first iteration (the linear
/// solution, `k d d^T` per edge along its direction `d`) and once converged, m.
fn static_sag(k: f64, g: f64) -> (f64, f64) {
    let h = f64::from(H);
    let mut edges = Vec::new();
    for j in 0..N {
        for i in 0..N {
            let id = j * N + i;
            if i + 1 < N {
                edges.push((id, id + 1));
            }
            if j + 1 < N {
                edges.push((id, id + N));
            }
            if i + 1 < N && j + 1 < N {
                edges.push((id, id + N + 1));
            }
        }
    }
    let rest = |i: usize| [(i % N) as f64 * h, (i / N) as f64 * h];
    // Rows 0..N - 1 move; the top row is pinned.
    let free = N * (N - 1);
    let dofs = 2 * free;
    let mut u = vec![0.0f64; dofs];
    let at = |u: &[f64], i: usize| {
        let r = rest(i);
        if i < free {
            [r[0] + u[2 * i], r[1] + u[2 * i + 1]]
        } else {
            r
        }
    };
    let drop = |u: &[f64]| -(0..N).map(|i| u[2 * i + 1]).sum::<f64>() / N as f64;
    let mut linear = None;
    for _ in 0..50 {
        let mut a = vec![0.0f64; dofs * dofs];
        // The residual: weight less the springs' pull.
        let mut r: Vec<f64> = (0..dofs)
            .map(|d| {
                if d % 2 == 1 {
                    -f64::from(particle_mass()) * g
                } else {
                    0.0
                }
            })
            .collect();
        for &(p, q) in &edges {
            let (xp, xq) = (at(&u, p), at(&u, q));
            let (rp, rq) = (rest(p), rest(q));
            let d = [xq[0] - xp[0], xq[1] - xp[1]];
            let len = d[0].hypot(d[1]);
            let l0 = (rq[0] - rp[0]).hypot(rq[1] - rp[1]);
            let n = [d[0] / len, d[1] / len];
            let t = k * (len - l0);
            let mut tangent = [[0.0; 2]; 2];
            for (x, row) in tangent.iter_mut().enumerate() {
                for (y, e) in row.iter_mut().enumerate() {
                    let eye = if x == y { 1.0 } else { 0.0 };
                    *e = k * (n[x] * n[y] + (1.0 - l0 / len) * (eye - n[x] * n[y]));
                }
            }
            for (m, &i) in [p, q].iter().enumerate() {
                if i >= free {
                    continue;
                }
                // The spring pulls p towards q and q towards p.
                let sign = if m == 0 { 1.0 } else { -1.0 };
                for x in 0..2 {
                    r[2 * i + x] += sign * t * n[x];
                }
                for (l, &j) in [p, q].iter().enumerate() {
                    if j >= free {
                        continue;
                    }
                    let sign = if m == l { 1.0 } else { -1.0 };
                    for x in 0..2 {
                        for y in 0..2 {
                            a[(2 * i + x) * dofs + 2 * j + y] += sign * tangent[x][y];
                        }
                    }
                }
            }
        }
        cholesky_solve(&mut a, &mut r, dofs);
        for (u, du) in u.iter_mut().zip(&r) {
            *u += du;
        }
        linear.get_or_insert(drop(&u));
        if r.iter().all(|du| du.abs() < 1e-13) {
            return (linear.unwrap_or(0.0), drop(&u));
        }
    }
    panic!("Newton's method did not converge");
}

/// The flat sheet hung by its top row under gravity at `iters` sweeps a step, settled; returns
/// the bottom row's mean drop, m.
fn hanging_sag(k: f32, iters: usize) -> f32 {
    let (mut p, tris) = sheet(flat);
    for i in 0..N {
        p.pin((N - 1) * N + i);
    }
    let mut c = Cloth::new(&p, &tris, params(k, 1e-5)).expect("cloth");
    run(
        &mut p,
        &mut c,
        Vec3::new(0.0, -9.81, 0.0),
        iters,
        20.0,
        2000,
    );
    assert!(p.is_finite());
    (0..N).map(|i| -p.x[i].y).sum::<f32>() / N as f32
}

#[test]
fn a_hanging_sheet_stretches_as_its_springs_say_whatever_the_iterations() {
    let k = 10.0;
    let (s5, s20) = (hanging_sag(k, 5), hanging_sag(k, 20));
    // The same springs' static equilibrium, linear and exact.
    let (linear, exact) = static_sag(k.into(), 9.81);
    // The chain of springs down a column: the row of springs above row j carries the weight
    // of rows 0..=j, (j + 1) N m g. To first order the diagonals carry none of it: each row
    // slides sideways by as much as the row of columns above it stretches, and the diagonals
    // keep their length; so each of the N columns is a chain of springs k.
    let w_row = f64::from(N as f32 * particle_mass()) * 9.81;
    let chain: f64 = (1..N)
        .map(|j| j as f64 * w_row / (N as f64 * k as f64))
        .sum();
    println!(
        "hanging sheet, k = {k} N/m: sag {s5} m at 5 iterations, {s20} m at 20; springs' \
         equilibrium {exact} m (linear {linear} m); chain of springs {chain} m"
    );
    assert!((s5 - s20).abs() <= 0.05 * s20, "{s5} vs {s20}");
    assert!((linear - chain).abs() < 1e-3 * chain, "{linear} vs {chain}");
    let s20 = f64::from(s20);
    assert!((s20 - exact).abs() < 0.005 * exact, "{s20} vs {exact}");
    // The top row of columns stretches 2.7 %: the tilted columns hand some of the weight to
    // the diagonals, a few per cent.
    assert!((s20 - chain).abs() < 0.05 * chain, "{s20} vs {chain}");
}

#[test]
fn cutting_removes_only_the_constraints_at_the_cut() {
    let (mut p, tris) = sheet(flat);
    let mut c = Cloth::new(&p, &tris, params(10.0, 1e-5)).expect("cloth");
    let (edges, hinges) = (c.edges(), c.hinges());
    let before_s = c.stretch_constraints().to_vec();
    let before_b = c.bend_constraints().to_vec();
    // Far from the sheet: nothing.
    assert_eq!(c.cut_near(Vec3::new(1.0, 1.0, 1.0), 0.005, &p), 0);
    // At an inner particle: its 6 edges, and the 12 hinges it is part of (the 6 across its
    // edges and the 6 across the far sides of its 6 triangles).
    let centre = flat(4, 5);
    let removed = c.cut_near(centre, 0.5 * H, &p);
    assert_eq!(removed, 18);
    assert_eq!((edges - c.edges(), hinges - c.hinges()), (6, 12));
    let near = |i: u32| p.x[i as usize].distance(centre) <= 0.5 * H;
    // What is left is exactly what touched nothing near the cut, in the same order.
    let kept_s: Vec<_> = before_s
        .iter()
        .filter(|s| !near(s.a) && !near(s.b))
        .map(|s| (s.a, s.b))
        .collect();
    let left_s: Vec<_> = c.stretch_constraints().iter().map(|s| (s.a, s.b)).collect();
    assert_eq!(left_s, kept_s);
    let kept_b: Vec<_> = before_b
        .iter()
        .filter(|b| ![b.a, b.b, b.c, b.d].into_iter().any(near))
        .map(|b| [b.a, b.b, b.c, b.d])
        .collect();
    let left_b: Vec<_> = c
        .bend_constraints()
        .iter()
        .map(|b| [b.a, b.b, b.c, b.d])
        .collect();
    assert_eq!(left_b, kept_b);
    // Hung by its top row and cut across row 4, the rows below fall freely while the rest
    // keeps hanging.
    for i in 0..N {
        p.pin((N - 1) * N + i);
    }
    let mut c = Cloth::new(&p, &tris, params(10.0, 1e-5)).expect("cloth");
    run(&mut p, &mut c, Vec3::new(0.0, -9.81, 0.0), 10, 20.0, 1000);
    let hanging = p.x.clone();
    let mut cut = 0;
    for i in 0..N {
        cut += c.cut_near(p.x[4 * N + i], 0.3 * H, &p);
    }
    assert!(cut > 0);
    let steps = 100;
    run(&mut p, &mut c, Vec3::new(0.0, -9.81, 0.0), 10, 0.0, steps);
    // 0.1 s of free fall from rest: g t^2 / 2 (the explicit steps add g dt t / 2).
    let t = steps as f32 * 1e-3;
    let fall = 0.5 * 9.81 * t * t;
    for j in 0..4 {
        for i in 0..N {
            let k = j * N + i;
            let dropped = hanging[k].y - p.x[k].y;
            assert!(
                (dropped - fall).abs() < 0.05 * fall,
                "{k}: {dropped} vs {fall}"
            );
        }
    }
    for k in 5 * N..N * N {
        assert!(hanging[k].distance(p.x[k]) < 0.1 * fall, "{k}");
    }
}

#[test]
fn bad_meshes_and_stiffnesses_are_refused_with_what_is_wrong() {
    let (p, _) = sheet(flat);
    let ok = params(10.0, 1e-5);
    let e = Cloth::new(&p, &[[0, 1, 11], [0, 100, 11]], ok).expect_err("missing");
    assert!(
        e.to_string()
            .starts_with("triangle 1: corner 1 is particle 100"),
        "{e}"
    );
    let e = Cloth::new(&p, &[[0, 1, 11], [3, 4, 3]], ok).expect_err("repeated");
    assert!(
        e.to_string()
            .contains("triangle 1: particle 3 is both corner 0 and corner 2"),
        "{e}"
    );
    let e = Cloth::new(&p, &[[0, 1, 2]], ok).expect_err("in a line");
    assert!(e.to_string().contains("triangle 0"), "{e}");
    let e = Cloth::new(&p, &[[0, 1, 11]], params(0.0, 1e-5)).expect_err("stretch");
    assert!(e.to_string().contains("stretch_stiffness_n_per_m"), "{e}");
    let e = Cloth::new(&p, &[[0, 1, 11]], params(1.0, f32::NAN)).expect_err("bend");
    assert!(e.to_string().contains("bend_stiffness_n_m_per_rad"), "{e}");
}
