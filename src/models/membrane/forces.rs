//! The membrane's forces (eqs 3-4) over a chunk of rows, all four layers: springs around,
//! along and between layers, point damping, gravity, the attachments and the external
//! forces. The state is only read, so chunks run in parallel; each writes its own rows.

use super::{LAYERS, Membrane};

/// Where a chunk writes: for each component, one slice per layer covering the chunk's rows.
pub(super) struct ChunkOut<'a> {
    pub f: [[&'a mut [f32]; LAYERS]; 3],
}

/// A state to evaluate forces at (positions and velocities, structure of arrays).
pub(super) struct StateRef<'a> {
    pub x: [&'a [f32]; 3],
    pub v: [&'a [f32]; 3],
}

/// One spring from `a` to `b` (d = x_b - x_a): the force on `a` (the opposite on `b`).
#[inline(always)]
fn spring(d: [f32; 3], dv: [f32; 3], k: f32, rest: f32, c: f32) -> [f32; 3] {
    let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    let len = len2.sqrt();
    let inv = if len > 0.0 { 1.0 / len } else { 0.0 };
    let along = dv[0] * d[0] + dv[1] * d[1] + dv[2] * d[2];
    let s = (k * (len - rest) + c * along * inv) * inv;
    [d[0] * s, d[1] * s, d[2] * s]
}

/// Forces on rows `r0..r1` of every layer at `state` into `out` (overwritten).
pub(super) fn chunk(m: &Membrane, state: &StateRef, r0: usize, r1: usize, out: &mut ChunkOut) {
    let (rows, cols) = (m.rows, m.cols);
    let per = rows * cols;
    let p = &m.params;
    let (x, v) = (&state.x, &state.v);
    // The along-spring force carried from row i to row i + 1, per layer and column.
    let mut carry = vec![[0.0f32; 3]; LAYERS * cols];
    let mut ring = vec![[0.0f32; 3]; cols];
    for i in r0..r1 {
        let local = (i - r0) * cols;
        for l in 0..LAYERS {
            let base = (l * rows + i) * cols;
            let carried = &mut carry[l * cols..(l + 1) * cols];
            if i == r0 && i > 0 {
                // The spring from the row before (the chunk before computes it too).
                for (j, slot) in carried.iter_mut().enumerate() {
                    let a = base - cols + j;
                    let fa = pair(
                        x,
                        v,
                        a,
                        a + cols,
                        m.k_along[a],
                        m.rest_along[a],
                        m.c_along[a],
                    );
                    *slot = [-fa[0], -fa[1], -fa[2]];
                }
            } else if i == r0 {
                carried.iter_mut().for_each(|s| *s = [0.0; 3]);
            }
            // Around: ring[j] is the spring from column j to the next.
            for (j, slot) in ring.iter_mut().enumerate() {
                let node = base + j;
                let jn = if j + 1 < cols { j + 1 } else { 0 };
                let k = m.k_around[node];
                *slot = if k > 0.0 {
                    pair(
                        x,
                        v,
                        node,
                        base + jn,
                        k,
                        m.rest_around[node],
                        m.c_around[node],
                    )
                } else {
                    [0.0; 3]
                };
            }
            for j in 0..cols {
                let before = if j > 0 {
                    ring[j - 1]
                } else if m.periodic {
                    ring[cols - 1]
                } else {
                    [0.0; 3]
                };
                let node = base + j;
                // Along: the spring to the next row, carried to it.
                let ahead = if i + 1 < rows && m.k_along[node] > 0.0 {
                    pair(
                        x,
                        v,
                        node,
                        node + cols,
                        m.k_along[node],
                        m.rest_along[node],
                        m.c_along[node],
                    )
                } else {
                    [0.0; 3]
                };
                let behind = carried[j];
                carried[j] = [-ahead[0], -ahead[1], -ahead[2]];
                for c in 0..3 {
                    out.f[c][l][local + j] = ring[j][c] - before[c] + ahead[c] + behind[c];
                }
            }
        }
        // Links between layers, at this row.
        for l in 0..LAYERS - 1 {
            for j in 0..cols {
                let t = i * cols + j;
                let link = l * per + t;
                let k = m.k_link[link];
                if k <= 0.0 {
                    continue;
                }
                let fs = pair(x, v, link, link + per, k, m.rest_link[link], m.c_link[link]);
                for c in 0..3 {
                    out.f[c][l][local + j] += fs[c];
                    out.f[c][l + 1][local + j] -= fs[c];
                }
            }
        }
        // Per node: point damping, gravity, attachments.
        for l in 0..LAYERS {
            let slot = match l {
                0 => Some(0),
                x if x == LAYERS - 1 => Some(1),
                _ => None,
            };
            for j in 0..cols {
                let node = (l * rows + i) * cols + j;
                let mass = m.mass[node];
                let ka = m.k_attach[node];
                for c in 0..3 {
                    let mut add = mass * (p.gravity[c] - p.damping_per_s * v[c][node]);
                    if let (Some(s), true) = (slot, ka > 0.0) {
                        add -= ka * (x[c][node] - m.target[c][s * per + i * cols + j]);
                    }
                    out.f[c][l][local + j] += add;
                }
            }
        }
    }
    // External forces on these rows.
    for &(node, fe) in &m.external {
        let (l, i, j) = m.coords(node as usize);
        if (r0..r1).contains(&i) {
            let local = (i - r0) * cols + j;
            for c in 0..3 {
                out.f[c][l][local] += fe[c];
            }
        }
    }
}

/// The spring from node `a` to node `b` at the state: its force on `a` (the opposite on `b`).
#[inline(always)]
fn pair(
    x: &[&[f32]; 3],
    v: &[&[f32]; 3],
    a: usize,
    b: usize,
    k: f32,
    rest: f32,
    c: f32,
) -> [f32; 3] {
    let d = [x[0][b] - x[0][a], x[1][b] - x[1][a], x[2][b] - x[2][a]];
    let dv = [v[0][b] - v[0][a], v[1][b] - v[1][a], v[2][b] - v[2][a]];
    spring(d, dv, k, rest, c)
}
