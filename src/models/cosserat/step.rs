//! The rod's backward-Euler step: Newton's method on the incremental potential
//!
//!   Phi(x, R) = sum_i m_i / (2 dt^2) |x_i - x0_i - dt v0_i|^2 + c m_i / (2 dt) |x_i - x0_i|^2
//!             - (m_i g + f_i) . x_i
//!             + sum_e 1 / (2 dt^2) (phi_e - dt w0_e)^T I_e (phi_e - dt w0_e)
//!             + U(x, R) + sum_k gamma_d D0_k / (2 dt) |kappa_k - kappa0_k|^2,
//!
//! with `phi_e = log(R_e R0_e^T)` each element's rotation over the step. Each iteration
//! perturbs the node positions and the frames (`R_e <- exp(delta_e) R_e`) and solves the
//! Gauss-Newton system, block tridiagonal; a step long against the elements is checked
//! against Phi and halved until Phi does not grow.

use super::blocks::{Block, BlockTridiagonal, Vec6};
use super::so3;
use super::{CosseratRod, StepStats};
use glam::{DMat3, DVec3};

/// Steps this long against the shortest element (or rotations this large, radians) are
/// checked against the potential before they are taken.
const CHECKED_STEP: f64 = 0.05;
/// Halvings of a step that raised the potential before it is taken anyway.
const MAX_HALVINGS: u32 = 8;

/// Vectors kept between steps so that a step allocates nothing.
#[derive(Debug, Clone, Default)]
pub(super) struct Scratch {
    x0: Vec<DVec3>,
    v0: Vec<DVec3>,
    r0: Vec<DMat3>,
    w0: Vec<DVec3>,
    kappa0: Vec<DVec3>,
    /// Element inertia in the world frame at the step's start.
    inertia_w: Vec<DMat3>,
    h: BlockTridiagonal,
    rhs: Vec<Vec6>,
    trial_x: Vec<DVec3>,
    trial_r: Vec<DMat3>,
}

/// Element `e`'s strain in its material frame (shear x, y; stretch z).
pub(super) fn strain(x: &[DVec3], frames: &[DMat3], rest_len: &[f64], e: usize) -> DVec3 {
    frames[e].transpose() * (x[e + 1] - x[e]) / rest_len[e] - DVec3::Z
}

/// The curvature between elements `k` and `k + 1` in `k`'s frame.
pub(super) fn curvature(frames: &[DMat3], voronoi: &[f64], k: usize) -> DVec3 {
    so3::log(frames[k].transpose() * frames[k + 1]) / voronoi[k]
}

/// Adds `m` into `block` at (row, col).
fn add3(block: &mut Block, row: usize, col: usize, m: DMat3) {
    for j in 0..3 {
        let c = m.col(j);
        for i in 0..3 {
            block[row + i][col + j] += c[i];
        }
    }
}

fn add_vec(v: &mut Vec6, at: usize, a: DVec3) {
    v[at] += a.x;
    v[at + 1] += a.y;
    v[at + 2] += a.z;
}

/// `J^T diag(w) K` for 3 x 3 `J`, `K`.
fn jt_w_k(j: DMat3, w: DVec3, k: DMat3) -> DMat3 {
    j.transpose() * DMat3::from_diagonal(w) * k
}

pub(super) fn step(rod: &mut CosseratRod, dt: f64) -> StepStats {
    let dt = if dt.is_finite() && dt > 0.0 { dt } else { 1e-3 };
    let n = rod.elements();
    let mut sc = std::mem::take(&mut rod.scratch);
    sc.x0.clone_from(&rod.x);
    sc.v0.clone_from(&rod.v);
    sc.r0.clone_from(&rod.frames);
    sc.w0.clone_from(&rod.omega);
    sc.kappa0.clear();
    sc.kappa0
        .extend((0..n.saturating_sub(1)).map(|k| rod.curvature(k)));
    sc.inertia_w.clear();
    sc.inertia_w.extend(
        rod.frames
            .iter()
            .zip(&rod.inertia)
            .map(|(r, i)| *r * DMat3::from_diagonal(*i) * r.transpose()),
    );
    // A first guess: carried on at the step's start velocities.
    for i in 0..=n {
        if !rod.fixed_node[i] {
            rod.x[i] = sc.x0[i] + sc.v0[i] * dt;
        }
    }
    for e in 0..n {
        if !rod.fixed_frame[e] {
            rod.frames[e] = so3::orthonormalise(so3::exp(sc.w0[e] * dt) * sc.r0[e]);
        }
    }
    let shortest = rod.rest_len.iter().copied().fold(f64::INFINITY, f64::min);
    let mut stats = StepStats::default();
    for _ in 0..rod.max_iterations.max(1) {
        assemble(rod, &mut sc, dt);
        fix(rod, &mut sc);
        let mut delta = std::mem::take(&mut sc.rhs);
        if sc.h.solve(&mut delta).is_err() {
            // Not positive definite (a degenerate configuration): take a gradient step.
            assemble(rod, &mut sc, dt);
            fix(rod, &mut sc);
            delta.clone_from(&sc.rhs);
            let scale =
                sc.h.diag
                    .iter()
                    .flat_map(|b| (0..6).map(move |i| b[i][i]))
                    .fold(0.0f64, f64::max)
                    .max(1e-12);
            delta.iter_mut().flatten().for_each(|d| *d /= scale);
        }
        let (max_x, max_r) = largest(&delta);
        let mut alpha = 1.0;
        if max_x > CHECKED_STEP * shortest || max_r > CHECKED_STEP {
            let before = potential(rod, &sc, dt);
            for _ in 0..MAX_HALVINGS {
                trial(rod, &mut sc, &delta, alpha);
                let after = potential_of(rod, &sc, dt, &sc.trial_x, &sc.trial_r);
                if after <= before || !after.is_finite() && alpha < 1e-3 {
                    break;
                }
                alpha *= 0.5;
            }
        }
        apply(rod, &delta, alpha);
        sc.rhs = delta;
        stats.iterations += 1;
        stats.last_update_m = alpha * max_x.max(max_r * shortest);
        if stats.last_update_m < rod.tolerance_m {
            break;
        }
    }
    for i in 0..=n {
        rod.v[i] = if rod.fixed_node[i] {
            DVec3::ZERO
        } else {
            (rod.x[i] - sc.x0[i]) / dt
        };
    }
    for e in 0..n {
        rod.frames[e] = so3::orthonormalise(rod.frames[e]);
        rod.omega[e] = if rod.fixed_frame[e] {
            DVec3::ZERO
        } else {
            so3::log(rod.frames[e] * sc.r0[e].transpose()) / dt
        };
    }
    rod.force.iter_mut().for_each(|f| *f = DVec3::ZERO);
    rod.torque.iter_mut().for_each(|t| *t = DVec3::ZERO);
    rod.given_k.iter_mut().for_each(|k| *k = 0.0);
    rod.scratch = sc;
    stats
}

/// The largest position update and rotation update, m and rad.
fn largest(delta: &[Vec6]) -> (f64, f64) {
    delta.iter().fold((0.0f64, 0.0f64), |(px, pr), d| {
        let x = DVec3::new(d[0], d[1], d[2]).length();
        let r = DVec3::new(d[3], d[4], d[5]).length();
        (px.max(x), pr.max(r))
    })
}

fn apply(rod: &mut CosseratRod, delta: &[Vec6], alpha: f64) {
    let n = rod.elements();
    for (b, d) in delta.iter().enumerate() {
        rod.x[b] += DVec3::new(d[0], d[1], d[2]) * alpha;
        if b < n {
            let r = so3::exp(DVec3::new(d[3], d[4], d[5]) * alpha) * rod.frames[b];
            rod.frames[b] = r;
        }
    }
}

fn trial(rod: &CosseratRod, sc: &mut Scratch, delta: &[Vec6], alpha: f64) {
    sc.trial_x.clone_from(&rod.x);
    sc.trial_r.clone_from(&rod.frames);
    let n = rod.elements();
    for (b, d) in delta.iter().enumerate() {
        sc.trial_x[b] += DVec3::new(d[0], d[1], d[2]) * alpha;
        if b < n {
            sc.trial_r[b] = so3::exp(DVec3::new(d[3], d[4], d[5]) * alpha) * rod.frames[b];
        }
    }
}

fn potential(rod: &CosseratRod, sc: &Scratch, dt: f64) -> f64 {
    potential_of(rod, sc, dt, &rod.x, &rod.frames)
}

/// Phi at positions `x` and frames `r` (the module's formula).
fn potential_of(rod: &CosseratRod, sc: &Scratch, dt: f64, x: &[DVec3], r: &[DMat3]) -> f64 {
    let p = &rod.params;
    let c = p.damping_per_s;
    let mut phi = 0.0;
    for i in 0..x.len() {
        let m = rod.mass[i];
        let dx = x[i] - sc.x0[i];
        phi += m / (2.0 * dt * dt) * (dx - sc.v0[i] * dt).length_squared()
            + c * m / (2.0 * dt) * dx.length_squared()
            - (p.gravity * m + rod.force[i]).dot(x[i])
            + 0.5 * rod.given_k[i] * dx.length_squared();
    }
    for e in 0..r.len() {
        let rotation = so3::log(r[e] * sc.r0[e].transpose());
        let turn = rotation - sc.w0[e] * dt;
        phi += 0.5 * turn.dot(sc.inertia_w[e] * turn) / (dt * dt) - rod.torque[e].dot(rotation);
        let d = strain(x, r, &rod.rest_len, e) - rod.rest_strain[e];
        phi += 0.5 * rod.rest_len[e] * (d * d).dot(rod.stretch_k);
    }
    let gamma = p.curvature_damping_n_m2_s;
    for k in 0..rod.voronoi.len() {
        let kappa = curvature(r, &rod.voronoi, k);
        let d = kappa - rod.rest_curvature[k];
        phi += 0.5 * rod.voronoi[k] * (d * d).dot(rod.bend_k);
        phi += gamma * rod.voronoi[k] / (2.0 * dt) * (kappa - sc.kappa0[k]).length_squared();
    }
    for c in &rod.clamps {
        let d0 = 0.5 * rod.rest_len[c.element];
        let kappa = c.joint(r[c.element]).0 / d0;
        phi += 0.5 * d0 * (kappa * kappa).dot(rod.bend_k);
    }
    phi
}

/// Fills `sc.h` with the Gauss-Newton Hessian of Phi and `sc.rhs` with minus its gradient.
fn assemble(rod: &CosseratRod, sc: &mut Scratch, dt: f64) {
    let n = rod.elements();
    let p = &rod.params;
    sc.h.reset(n + 1);
    sc.rhs.clear();
    sc.rhs.resize(n + 1, [0.0; 6]);
    let (h, g) = (&mut sc.h, &mut sc.rhs);
    let c = p.damping_per_s;
    // Gradient accumulated with its sign; negated at the end.
    for i in 0..=n {
        let m = rod.mass[i];
        let dx = rod.x[i] - sc.x0[i];
        let k = rod.given_k[i];
        let grad = (dx - sc.v0[i] * dt) * (m / (dt * dt)) + dx * (c * m / dt + k)
            - p.gravity * m
            - rod.force[i];
        add_vec(&mut g[i], 0, grad);
        add3(
            &mut h.diag[i],
            0,
            0,
            DMat3::IDENTITY * (m / (dt * dt) + c * m / dt + k),
        );
    }
    for e in 0..n {
        let r = rod.frames[e];
        // Inertia of the element's turn over the step.
        let phi = so3::log(r * sc.r0[e].transpose());
        let jinv = so3::jl_inv(phi);
        let iw = sc.inertia_w[e] / (dt * dt);
        add_vec(
            &mut g[e],
            3,
            jinv.transpose() * (iw * (phi - sc.w0[e] * dt) - rod.torque[e]),
        );
        add3(&mut h.diag[e], 3, 3, jinv.transpose() * iw * jinv);
        // Shear and stretch: gamma = R^T t / l0 - e3.
        let l0 = rod.rest_len[e];
        let t = rod.x[e + 1] - rod.x[e];
        let rt = r.transpose() / l0;
        let ja = -rt;
        let jb = rt;
        let jc = rt * so3::skew(t);
        let d = strain(&rod.x, &rod.frames, &rod.rest_len, e) - rod.rest_strain[e];
        let gs = d * rod.stretch_k * l0;
        add_vec(&mut g[e], 0, ja.transpose() * gs);
        add_vec(&mut g[e], 3, jc.transpose() * gs);
        add_vec(&mut g[e + 1], 0, jb.transpose() * gs);
        let w = rod.stretch_k * l0;
        add3(&mut h.diag[e], 0, 0, jt_w_k(ja, w, ja));
        add3(&mut h.diag[e], 0, 3, jt_w_k(ja, w, jc));
        add3(&mut h.diag[e], 3, 0, jt_w_k(jc, w, ja));
        add3(&mut h.diag[e], 3, 3, jt_w_k(jc, w, jc));
        add3(&mut h.diag[e + 1], 0, 0, jt_w_k(jb, w, jb));
        add3(&mut h.upper[e], 0, 0, jt_w_k(ja, w, jb));
        add3(&mut h.upper[e], 3, 0, jt_w_k(jc, w, jb));
    }
    let gamma = p.curvature_damping_n_m2_s;
    for k in 0..rod.voronoi.len() {
        let d0 = rod.voronoi[k];
        let rk = rod.frames[k];
        let phi = so3::log(rk.transpose() * rod.frames[k + 1]);
        let kappa = phi / d0;
        let jb = so3::jl_inv(phi) * rk.transpose() / d0;
        let ja = -jb;
        let gk = (kappa - rod.rest_curvature[k]) * rod.bend_k * d0
            + (kappa - sc.kappa0[k]) * (gamma * d0 / dt);
        add_vec(&mut g[k], 3, ja.transpose() * gk);
        add_vec(&mut g[k + 1], 3, jb.transpose() * gk);
        let w = rod.bend_k * d0 + DVec3::splat(gamma * d0 / dt);
        add3(&mut h.diag[k], 3, 3, jt_w_k(ja, w, ja));
        add3(&mut h.diag[k + 1], 3, 3, jt_w_k(jb, w, jb));
        add3(&mut h.upper[k], 3, 3, jt_w_k(ja, w, jb));
    }
    for c in &rod.clamps {
        let e = c.element;
        let d0 = 0.5 * rod.rest_len[e];
        let (phi, j) = c.joint(rod.frames[e]);
        let j = j / d0;
        let gk = phi / d0 * rod.bend_k * d0;
        add_vec(&mut g[e], 3, j.transpose() * gk);
        add3(&mut h.diag[e], 3, 3, jt_w_k(j, rod.bend_k * d0, j));
    }
    for v in g.iter_mut() {
        v.iter_mut().for_each(|x| *x = -*x);
    }
}

/// Fixed degrees of freedom (clamped nodes and frames, and the last block's rotation slot,
/// which stands for no element) become identity rows with no update.
fn fix(rod: &CosseratRod, sc: &mut Scratch) {
    let n = rod.elements();
    let fixed = |b: usize, i: usize| -> bool {
        if i < 3 {
            rod.fixed_node[b]
        } else {
            b >= n || rod.fixed_frame[b]
        }
    };
    for b in 0..=n {
        for i in 0..6 {
            if !fixed(b, i) {
                continue;
            }
            for j in 0..6 {
                sc.h.diag[b][i][j] = 0.0;
                sc.h.diag[b][j][i] = 0.0;
            }
            sc.h.diag[b][i][i] = 1.0;
            if b < n {
                sc.h.upper[b][i] = [0.0; 6];
            }
            if b > 0 {
                for row in sc.h.upper[b - 1].iter_mut() {
                    row[i] = 0.0;
                }
            }
            sc.rhs[b][i] = 0.0;
        }
    }
}
