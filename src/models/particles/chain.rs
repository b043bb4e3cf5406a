//! Chains of distance constraints (eq 5) solved a run at a time: the adhesion strands and the
//! vessels (ducts and arteries as chains of particles). A chain's light interior particles
//! between heavy or pinned ends make segment-by-segment Gauss-Seidel hopelessly soft, so each
//! run of intact consecutive segments is solved exactly with the Thomas algorithm
//! ([`solve_chain`]). A vessel also resists bending, by springs from each particle to the one
//! after next (Gauss-Seidel: they are soft).
//!
//! Units: metres, newtons; compliances in m/N (1 / stiffness). Every sweep goes through the
//! chains and segments in order: the same bytes every time.

use super::gpu::{ChainSegment, ChainSet, DeviceChain};
use super::{Particles, colour};
use crate::models::xpbd::{self, Stretch};
use glam::Vec3;

/// One segment's row of a chain's linear system.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Row {
    /// The segment's compliance, m/N (set by the caller).
    pub compliance: f32,
    normal: Vec3,
    diag: f32,
    /// The coupling with the next segment.
    off: f32,
    rhs: f32,
    /// The forward elimination's multipliers.
    c: f32,
    d: f32,
}

/// One projection of a run of consecutive segments (each one's second particle the next one's
/// first) solved together: the XPBD step of the run, `(J W J^T + alpha~) dlambda = -C -
/// alpha~ lambda`, is tridiagonal (neighbouring segments share one particle), and the Thomas
/// algorithm solves it exactly in one pass. A strand's interior particles weigh a few
/// micrograms and its ends are organ particles of grams: segment by segment (plain
/// Gauss-Seidel) the pull on an end would reach the other end only over thousands of sweeps,
/// and a strand meant to hold newtons would tear under a hundredth of one. One segment alone
/// is [`xpbd::project_stretch`].
pub(super) fn solve_chain<S: AsRef<Stretch>>(
    p: &mut Particles,
    segs: &[S],
    lambda: &mut [f32],
    rows: &mut [Row],
    dt: f32,
) {
    if let ([s], [l], [row]) = (segs, &mut *lambda, &*rows) {
        *l += xpbd::project_stretch(&mut p.x, &p.w, s.as_ref(), row.compliance, dt, *l);
        return;
    }
    let (x, w) = (&mut p.x, &p.w);
    let inv_dt2 = 1.0 / (dt * dt);
    for ((row, s), &l) in rows.iter_mut().zip(segs).zip(&*lambda) {
        let (a, b) = (s.as_ref().a as usize, s.as_ref().b as usize);
        let d = x[a] - x[b];
        let len = d.length();
        let alpha = row.compliance * inv_dt2;
        // A segment of no length has no direction: it takes no part this time.
        let (normal, rhs) = if len > f32::EPSILON {
            (d / len, -(len - s.as_ref().rest_m) - alpha * l)
        } else {
            (Vec3::ZERO, 0.0)
        };
        row.normal = normal;
        row.diag = (w[a] + w[b]) * normal.length_squared() + alpha;
        row.rhs = rhs;
    }
    for j in 0..rows.len() {
        rows[j].off = match rows.get(j + 1) {
            Some(next) => -w[segs[j].as_ref().b as usize] * rows[j].normal.dot(next.normal),
            None => 0.0,
        };
    }
    // Forward elimination; the matrix is symmetric, diagonally dominant and positive definite
    // (alpha~ > 0), so no pivot vanishes.
    let (mut c_prev, mut d_prev, mut off_prev) = (0.0f32, 0.0f32, 0.0f32);
    for row in rows.iter_mut() {
        let pivot = row.diag - off_prev * c_prev;
        if pivot.is_nan() || pivot <= 0.0 {
            return;
        }
        row.c = row.off / pivot;
        row.d = (row.rhs - off_prev * d_prev) / pivot;
        (c_prev, d_prev, off_prev) = (row.c, row.d, row.off);
    }
    // Back substitution, applying each segment's change as it comes.
    let mut next = 0.0f32;
    for ((row, s), l) in rows.iter().zip(segs).zip(lambda.iter_mut()).rev() {
        let dl = row.d - row.c * next;
        next = dl;
        *l += dl;
        let (a, b) = (s.as_ref().a as usize, s.as_ref().b as usize);
        x[a] += row.normal * (w[a] * dl);
        x[b] -= row.normal * (w[b] * dl);
    }
}

/// One chain of [`Chains`]: its segments and bending springs in the shared arrays.
#[derive(Debug, Clone)]
struct Span {
    segs: std::ops::Range<usize>,
    bends: std::ops::Range<usize>,
    compliance: f32,
    bend_compliance: f32,
}

/// Chains of particles (vessels) with their stretch and bending springs.
#[derive(Debug, Clone, Default)]
pub struct Chains {
    spans: Vec<Span>,
    segs: Vec<Stretch>,
    intact: Vec<bool>,
    lambda: Vec<f32>,
    bends: Vec<Stretch>,
    bend_intact: Vec<bool>,
    bend_lambda: Vec<f32>,
    rows: Vec<Row>,
    dt: f32,
    /// The chains in projection order: by colour (chains of one colour share no particle,
    /// `colour.rs`), then as added.
    order: Vec<u32>,
    colours: Vec<u32>,
}

impl Chains {
    pub fn new() -> Chains {
        Chains::default()
    }

    /// Adds the chain through `particles` (in order; rest lengths from their present
    /// positions), stretch stiffness `stretch_n_per_m` per segment and bending stiffness
    /// `bend_n_per_m` per skip-one spring (0: none). Returns its index.
    pub fn add(
        &mut self,
        p: &Particles,
        particles: &[u32],
        stretch_n_per_m: f32,
        bend_n_per_m: f32,
    ) -> usize {
        let s0 = self.segs.len();
        for w in particles.windows(2) {
            self.segs.push(Stretch {
                a: w[0],
                b: w[1],
                rest_m: p.x[w[0] as usize].distance(p.x[w[1] as usize]),
            });
        }
        let b0 = self.bends.len();
        if bend_n_per_m > 0.0 {
            for w in particles.windows(3) {
                self.bends.push(Stretch {
                    a: w[0],
                    b: w[2],
                    rest_m: p.x[w[0] as usize].distance(p.x[w[2] as usize]),
                });
            }
        }
        let (s1, b1) = (self.segs.len(), self.bends.len());
        self.intact.resize(s1, true);
        self.lambda.resize(s1, 0.0);
        self.bend_intact.resize(b1, true);
        self.bend_lambda.resize(b1, 0.0);
        let compliance = |k: f32| if k > 0.0 { 1.0 / k } else { f32::INFINITY };
        self.spans.push(Span {
            segs: s0..s1,
            bends: b0..b1,
            compliance: compliance(stretch_n_per_m),
            bend_compliance: compliance(bend_n_per_m),
        });
        self.rows
            .resize(self.rows.len().max(s1 - s0), Row::default());
        let particles: Vec<Vec<u32>> = self
            .spans
            .iter()
            .map(|s| {
                let segs = &self.segs[s.segs.clone()];
                segs.iter().flat_map(|g| [g.a, g.b]).collect()
            })
            .collect();
        self.colours = colour::greedy(&particles);
        self.order = colour::order(&self.colours)
            .into_iter()
            .map(|k| k as u32)
            .collect();
        self.spans.len() - 1
    }

    pub fn chains(&self) -> usize {
        self.spans.len()
    }

    /// Segments of chain `c` (its `k`-th joins its particles `k` and `k + 1`).
    pub fn segments(&self, c: usize) -> usize {
        self.spans.get(c).map_or(0, |s| s.segs.len())
    }

    pub fn is_intact(&self, c: usize, k: usize) -> bool {
        self.spans
            .get(c)
            .and_then(|s| s.segs.clone().nth(k))
            .is_some_and(|i| self.intact[i])
    }

    /// Cuts segment `k` of chain `c` (and the bending springs across it); false if there is
    /// no such intact segment.
    pub fn cut(&mut self, c: usize, k: usize) -> bool {
        let Some(span) = self.spans.get(c) else {
            return false;
        };
        let Some(i) = span.segs.clone().nth(k) else {
            return false;
        };
        if !self.intact[i] {
            return false;
        }
        self.intact[i] = false;
        // Bending spring j spans segments j and j + 1.
        for j in [k.wrapping_sub(1), k] {
            if let Some(b) = span.bends.clone().nth(j) {
                self.bend_intact[b] = false;
            }
        }
        true
    }

    /// The segment of chain `c` nearest `q` and how far, m.
    pub fn nearest_segment(&self, p: &Particles, c: usize, q: Vec3) -> Option<(usize, f32)> {
        let span = self.spans.get(c)?;
        span.segs
            .clone()
            .enumerate()
            .map(|(k, i)| {
                let s = &self.segs[i];
                let (a, b) = (p.x[s.a as usize], p.x[s.b as usize]);
                let ab = b - a;
                let t = ((q - a).dot(ab) / ab.length_squared().max(1e-20)).clamp(0.0, 1.0);
                (k, q.distance(a + ab * t))
            })
            .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)))
    }

    /// The particles segment `k` of chain `c` joins.
    pub fn segment_ends(&self, c: usize, k: usize) -> Option<(u32, u32)> {
        let i = self.spans.get(c)?.segs.clone().nth(k)?;
        Some((self.segs[i].a, self.segs[i].b))
    }

    /// Rest length of segment `k` of chain `c`, m (0 if there is none).
    pub fn rest_length(&self, c: usize, k: usize) -> f32 {
        self.spans
            .get(c)
            .and_then(|s| s.segs.clone().nth(k))
            .map_or(0.0, |i| self.segs[i].rest_m)
    }

    /// Rest length of chain `c` before its segment `k`, m (the arc length of its start).
    pub fn rest_length_before(&self, c: usize, k: usize) -> f32 {
        self.spans.get(c).map_or(0.0, |s| {
            self.segs[s.segs.start..s.segs.end.min(s.segs.start + k)]
                .iter()
                .map(|g| g.rest_m)
                .sum()
        })
    }

    /// The tension segment `k` of chain `c` carried over the last step, N (positive pulls).
    pub fn tension_n(&self, c: usize, k: usize) -> f32 {
        let Some(i) = self.spans.get(c).and_then(|s| s.segs.clone().nth(k)) else {
            return 0.0;
        };
        if self.dt > 0.0 {
            -self.lambda[i] / (self.dt * self.dt)
        } else {
            0.0
        }
    }

    pub fn begin_step(&mut self) {
        self.lambda.fill(0.0);
        self.bend_lambda.fill(0.0);
    }

    /// One sweep: chain by chain in projection order (by colour), each one's runs of intact
    /// segments solved exactly, then its bending springs one by one.
    pub fn project(&mut self, p: &mut Particles, dt: f32) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        self.dt = dt;
        for &k in &self.order {
            let span = &self.spans[k as usize];
            let (s0, s1) = (span.segs.start, span.segs.end);
            let mut from = s0;
            while from < s1 {
                if !self.intact[from] {
                    from += 1;
                    continue;
                }
                let mut to = from + 1;
                while to < s1 && self.intact[to] {
                    to += 1;
                }
                let rows = &mut self.rows[..to - from];
                rows.iter_mut().for_each(|r| r.compliance = span.compliance);
                solve_chain(
                    p,
                    &self.segs[from..to],
                    &mut self.lambda[from..to],
                    rows,
                    dt,
                );
                from = to;
            }
            for b in span.bends.clone() {
                if self.bend_intact[b] {
                    self.bend_lambda[b] += xpbd::project_stretch(
                        &mut p.x,
                        &p.w,
                        &self.bends[b],
                        span.bend_compliance,
                        dt,
                        self.bend_lambda[b],
                    );
                }
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        (self.segs.len() + self.bends.len()) * (12 + 1 + 4) + self.rows.len() * 40
    }

    /// Segments and bending springs still intact (a cut changes them).
    pub fn intact_counts(&self) -> (usize, usize) {
        let count = |v: &[bool]| v.iter().filter(|&&b| b).count();
        (count(&self.intact), count(&self.bend_intact))
    }

    /// The chains as a device takes them, in projection order (`gpu.rs`).
    pub(super) fn device_set(&self) -> ChainSet {
        let mut set = ChainSet::default();
        for &k in &self.order {
            let span = &self.spans[k as usize];
            let first = set.segs.len() as u32;
            for i in span.segs.clone() {
                set.segs.push(ChainSegment {
                    c: self.segs[i],
                    intact: self.intact[i],
                    breakable: false,
                });
            }
            let bend_first = set.bends.len() as u32;
            for b in span.bends.clone() {
                set.bends.push((self.bends[b], self.bend_intact[b]));
            }
            set.chains.push(DeviceChain {
                segs: first..set.segs.len() as u32,
                bends: bend_first..set.bends.len() as u32,
                compliance: span.compliance,
                weak_compliance: span.compliance,
                weakened: false,
                whole: false,
                solves: 1,
                bend_compliance: span.bend_compliance,
                colour: self.colours[k as usize],
            });
        }
        set
    }
}

#[cfg(test)]
#[path = "chain_tests.rs"]
mod tests;
