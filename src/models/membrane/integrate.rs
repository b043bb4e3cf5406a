//! The membrane's integrators: symplectic Euler (`v += dt F(x, v) / m`, `x += dt v`) and the
//! paper's classical fourth-order Runge-Kutta on `(x, v)`. Both are explicit: stable only
//! below [`super::Membrane::explicit_step_limit`] (see `docs/rectum.md` for what that means at
//! the paper's resolution).
//!
//! Rows go in fixed chunks; every sum is per node, so the bytes do not depend on the number
//! of threads.

use super::forces::{self, ChunkOut, StateRef};
use super::{Integrator, LAYERS, Membrane, State};
use rayon::prelude::*;

/// Rows per parallel task.
const CHUNK_ROWS: usize = 8;

#[derive(Debug, Clone, Default)]
pub(super) struct Scratch {
    f: [Vec<f32>; 3],
    /// Runge-Kutta: a stage's state and the running sums.
    stage: State,
    sum_x: [Vec<f32>; 3],
    sum_v: [Vec<f32>; 3],
}

pub(super) fn step(m: &mut Membrane, dt: f32) {
    let dt = if dt.is_finite() && dt > 0.0 { dt } else { 1e-3 };
    let mut sc = std::mem::take(&mut m.scratch);
    let n = m.len();
    for c in 0..3 {
        sc.f[c].resize(n, 0.0);
    }
    match m.params.integrator {
        Integrator::Symplectic => symplectic(m, &mut sc, dt),
        Integrator::RungeKutta4 => runge_kutta(m, &mut sc, dt),
    }
    m.scratch = sc;
}

/// `a` (one value per node, layer-major) cut into chunks of [`CHUNK_ROWS`] rows: for each
/// chunk, the slice of each layer.
fn chunks_of(a: &mut [f32], rows: usize, cols: usize) -> Vec<[&mut [f32]; LAYERS]> {
    let per = rows * cols;
    let count = rows.div_ceil(CHUNK_ROWS);
    let mut out: Vec<Vec<&mut [f32]>> = (0..count).map(|_| Vec::with_capacity(LAYERS)).collect();
    for layer in a.chunks_mut(per) {
        for (c, piece) in layer.chunks_mut(CHUNK_ROWS * cols).enumerate() {
            out[c].push(piece);
        }
    }
    out.into_iter()
        .map(|v| match <[&mut [f32]; LAYERS]>::try_from(v) {
            Ok(a) => a,
            Err(_) => unreachable!("every layer has the same rows"),
        })
        .collect()
}

fn state_ref(s: &State) -> StateRef<'_> {
    StateRef {
        x: [&s.x[0], &s.x[1], &s.x[2]],
        v: [&s.v[0], &s.v[1], &s.v[2]],
    }
}

/// Forces at `state` for every node into `f`.
fn forces_all(m: &Membrane, state: &StateRef, f: &mut [Vec<f32>; 3]) {
    let (rows, cols) = (m.rows, m.cols);
    let [fx, fy, fz] = f;
    let mut outs: Vec<ChunkOut> = chunks_of(fx, rows, cols)
        .into_iter()
        .zip(chunks_of(fy, rows, cols))
        .zip(chunks_of(fz, rows, cols))
        .map(|((a, b), c)| ChunkOut { f: [a, b, c] })
        .collect();
    outs.par_iter_mut().enumerate().for_each(|(c, out)| {
        let r0 = c * CHUNK_ROWS;
        let r1 = (r0 + CHUNK_ROWS).min(rows);
        forces::chunk(m, state, r0, r1, out);
    });
}

fn symplectic(m: &mut Membrane, sc: &mut Scratch, dt: f32) {
    let state = std::mem::take(&mut m.state);
    forces_all(m, &state_ref(&state), &mut sc.f);
    m.state = state;
    let mass = &m.mass;
    let s = &mut m.state;
    for c in 0..3 {
        let (x, v, f) = (&mut s.x[c], &mut s.v[c], &sc.f[c]);
        x.par_chunks_mut(4096)
            .zip(v.par_chunks_mut(4096))
            .zip(f.par_chunks(4096))
            .zip(mass.par_chunks(4096))
            .for_each(|(((x, v), f), mass)| {
                for k in 0..x.len() {
                    v[k] += dt * f[k] / mass[k];
                    x[k] += dt * v[k];
                }
            });
    }
}

fn runge_kutta(m: &mut Membrane, sc: &mut Scratch, dt: f32) {
    let n = m.len();
    let state = std::mem::take(&mut m.state);
    for c in 0..3 {
        sc.sum_x[c].clear();
        sc.sum_x[c].resize(n, 0.0);
        sc.sum_v[c].clear();
        sc.sum_v[c].resize(n, 0.0);
    }
    let mut stage = std::mem::take(&mut sc.stage);
    stage.x.clone_from(&state.x);
    stage.v.clone_from(&state.v);
    // Stage k: derivative (v, F/m) at the stage's state; weights 1, 2, 2, 1; the next stage
    // starts from the state plus `h_k` times the derivative.
    let weights = [1.0f32, 2.0, 2.0, 1.0];
    let next_h = [0.5 * dt, 0.5 * dt, dt, 0.0];
    for k in 0..4 {
        forces_all(m, &state_ref(&stage), &mut sc.f);
        let mass = &m.mass;
        for c in 0..3 {
            let (w, h) = (weights[k], next_h[k]);
            let sv = &stage.v[c];
            for i in 0..n {
                let a = sc.f[c][i] / mass[i];
                sc.sum_x[c][i] += w * sv[i];
                sc.sum_v[c][i] += w * a;
            }
            if k < 3 {
                // The next stage's state from the start, with this stage's derivative.
                let (x0, v0) = (&state.x[c], &state.v[c]);
                let vs: Vec<f32> = stage.v[c].clone();
                for i in 0..n {
                    let a = sc.f[c][i] / mass[i];
                    stage.x[c][i] = x0[i] + h * vs[i];
                    stage.v[c][i] = v0[i] + h * a;
                }
            }
        }
    }
    let mut state = state;
    for c in 0..3 {
        for i in 0..n {
            state.x[c][i] += dt / 6.0 * sc.sum_x[c][i];
            state.v[c][i] += dt / 6.0 * sc.sum_v[c][i];
        }
    }
    m.state = state;
    sc.stage = stage;
}

#[cfg(test)]
pub(super) mod tests_support {
    use super::*;

    /// The forces on every node at the membrane's state, into `f`.
    pub fn forces(m: &Membrane, f: &mut [Vec<f32>; 3]) {
        forces_all(m, &state_ref(&m.state), f);
    }
}
