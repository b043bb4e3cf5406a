//! Shape matching in overlapping clusters (the cholecystectomy paper's eqs 3-4, after Müller
//! et al. 2005), the model of its liver, gallbladder and fat.
//!
//! A cluster is a set of particles `i` with membership weights `a_i` in (0, 1] and rest
//! offsets `q_i = x0_i - c0` from its rest centre of mass. Each projection:
//! 1. the centre of mass now, `c = sum m_i a_i x_i / sum m_i a_i` (eq 3's optimal
//!    translation), and `A = sum m_i a_i (x_i - c) q_i^T`;
//! 2. the rotation `R` of `A`'s polar decomposition (eq 3's optimal rotation), by the
//!    quaternion iteration of Müller et al. 2016 warm-started from the cluster's last one
//!    (robust where `A` is flat or inverted, and the same bytes on every CPU);
//! 3. the goals `g_i = R q_i + c` (eq 4);
//! 4. every particle is pulled towards each of its clusters' goals by a zero-length spring of
//!    stiffness `k = m_i omega_c^2 a_ic / sum_c a_ic` (its mass shared among its clusters by
//!    weight, the paper's average over clusters), solved as an XPBD constraint `C = x_i - g_i` with
//!    compliance `1 / k` (its multiplier kept over the step's iterations), so that the
//!    stiffness depends neither on `dt` nor on the iteration count (Macklin et al. 2016).
//!
//! The cluster's stiffness is its angular frequency `omega = 2 pi f` (a particle of the
//! cluster pulled off its goal and let go swings at `f`); the procedure derives it from the
//! tissue's Young's modulus and density and the cluster's size ([`frequency_for`]).
//! More clusters make a body softer between them (the paper's Fig. 6).
//!
//! Determinism: clusters compute their goals independently (in parallel); then every particle,
//! independently of the others (the goals are fixed meanwhile), takes its clusters' springs
//! one after another in cluster order, so the bytes do not depend on the thread count.

use super::Particles;
use glam::{Mat3, Mat3A, Quat, Vec3, Vec3A};
use rayon::prelude::*;

/// Iterations of the rotation extraction per projection at most: from a cold start (the
/// first projection), and warm-started from the last rotation (a cluster turns little in a
/// millisecond; what is left of a sudden turn is taken up by the next projections).
const COLD_ROTATION_ITERATIONS: usize = 30;
const WARM_ROTATION_ITERATIONS: usize = 4;
/// A turn smaller than this ends the rotation extraction, radians (a few f32 rounding steps).
const ROTATION_TOLERANCE_RAD: f32 = 1e-5;
/// Memberships per parallel task (about).
const RUN: u32 = 4096;
/// Clusters (or particles) below which a projection stays on the calling thread: on a small
/// body, handing the work to a second thread (which then spins beside the first on a shared
/// core) costs more than it saves (the cholecystectomy's CPU preset, 2 cores: 3,300 steps/s
/// on one thread against 2,800 on two). Every cluster and run writes only its own, so the
/// bytes are the same either way.
const PARALLEL_ITEMS: usize = 4096;

/// A run's positions and its springs' multipliers.
type RunSlices<'a> = (&'a mut [Vec3], &'a mut [Vec3A]);

fn worth_threads(items: usize) -> bool {
    items >= PARALLEL_ITEMS && rayon::current_num_threads() > 1
}

/// A cluster as given: its particles, their membership weights in (0, 1], and its frequency,
/// Hz.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterSpec {
    pub members: Vec<u32>,
    pub weights: Vec<f32>,
    pub frequency_hz: f32,
}

/// Why clusters were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeError {
    #[error("cluster {cluster}: {members} members but {weights} weights")]
    Lengths {
        cluster: usize,
        members: usize,
        weights: usize,
    },
    #[error("cluster {cluster}: particle {particle} does not exist ({len} particles)")]
    NoParticle {
        cluster: usize,
        particle: u32,
        len: usize,
    },
    #[error("cluster {cluster}: weight {weight} of particle {particle} is not in (0, 1]")]
    Weight {
        cluster: usize,
        particle: u32,
        weight: f32,
    },
    #[error("cluster {cluster}: frequency {value} Hz is not a positive number")]
    Frequency { cluster: usize, value: f32 },
    #[error("cluster {cluster} has fewer than 2 members")]
    TooSmall { cluster: usize },
}

#[derive(Debug, Clone)]
struct Cluster {
    members: Vec<u32>,
    weights: Vec<f32>,
    /// `m_i a_i / sum_c a_ic`, kg: the particle's mass shared among its clusters as its
    /// springs share it, so each cluster's pulls keep momentum (a pinned particle weighs as
    /// the cluster's heaviest free one times 1000: it anchors the cluster without an infinite
    /// weight).
    mw: Vec<f32>,
    mw_sum: f32,
    /// Rest offsets from the rest centre of mass, m, and the same times `mw`, kg m.
    rest: Vec<Vec3A>,
    mw_rest: Vec<Vec3A>,
    /// The centre of mass at the last projection (the origin the sums are taken about, so
    /// that they stay small wherever the body is), m.
    centre: Vec3,
    /// `omega^2`, 1/s^2.
    omega2: f32,
    /// The last rotation (warm start), and whether there was one.
    q: Quat,
    warm: bool,
}

/// Clusters over a [`Particles`] world.
#[derive(Debug, Clone)]
pub struct ShapeMatching {
    clusters: Vec<Cluster>,
    /// Every cluster's rotation matrix and centre of mass of the last projection: its goals
    /// are `R q + c` (kept per cluster, so that the particles' pass reads its rest offsets in
    /// order rather than gathering goals written cluster by cluster).
    frames: Vec<(Mat3A, Vec3A)>,
    /// For each particle, its entries in cluster order: `offsets[i]..offsets[i + 1]`; entry
    /// `e` is a membership of cluster `entry_cluster[e]` with rest offset `entry_rest[e]`, m.
    offsets: Vec<u32>,
    entry_cluster: Vec<u32>,
    entry_rest: Vec<Vec3A>,
    /// Each entry's spring stiffness over its particle's mass, `k / m`, 1/s^2 (0 for a pinned
    /// particle).
    rate: Vec<f32>,
    /// Each entry's XPBD multiplier over the step times its particle's inverse mass, m.
    mu: Vec<Vec3A>,
    /// For the step `coef_dt` (s): each entry's `beta = m / (k dt^2)` and `1 / (1 + beta)`.
    coef: Vec<[f32; 2]>,
    coef_dt: f32,
    /// Particles in runs of about [`RUN`] memberships (the parallel tasks).
    runs: Vec<(usize, usize)>,
    /// A device holds newer centres and rotations than these (it steps the clusters and
    /// sends only the particles back each substep): a step on the CPU starts every rotation
    /// cold, and a device made from these starts them cold too.
    behind: bool,
}

impl ShapeMatching {
    /// Clusters at the particles' present positions as their rest shape.
    pub fn new(p: &Particles, specs: Vec<ClusterSpec>) -> Result<ShapeMatching, ShapeError> {
        let n = p.len();
        let mut clusters = Vec::with_capacity(specs.len());
        // Each particle's total membership (checked below before it is used).
        let mut total_a = vec![0.0f32; n];
        for s in &specs {
            for (&i, &a) in s.members.iter().zip(&s.weights) {
                if let Some(t) = total_a.get_mut(i as usize) {
                    *t += a;
                }
            }
        }
        for (k, s) in specs.into_iter().enumerate() {
            if s.members.len() != s.weights.len() {
                return Err(ShapeError::Lengths {
                    cluster: k,
                    members: s.members.len(),
                    weights: s.weights.len(),
                });
            }
            if s.members.len() < 2 {
                return Err(ShapeError::TooSmall { cluster: k });
            }
            if !(s.frequency_hz.is_finite() && s.frequency_hz > 0.0) {
                return Err(ShapeError::Frequency {
                    cluster: k,
                    value: s.frequency_hz,
                });
            }
            for (&i, &a) in s.members.iter().zip(&s.weights) {
                if i as usize >= n {
                    return Err(ShapeError::NoParticle {
                        cluster: k,
                        particle: i,
                        len: n,
                    });
                }
                if !(a > 0.0 && a <= 1.0) {
                    return Err(ShapeError::Weight {
                        cluster: k,
                        particle: i,
                        weight: a,
                    });
                }
            }
            let heaviest = s
                .members
                .iter()
                .filter(|&&i| p.w[i as usize] > 0.0)
                .map(|&i| p.mass(i as usize))
                .fold(0.0f32, f32::max);
            let anchor = if heaviest > 0.0 {
                1000.0 * heaviest
            } else {
                1.0
            };
            let mw: Vec<f32> = s
                .members
                .iter()
                .zip(&s.weights)
                .map(|(&i, &a)| {
                    let m = if p.w[i as usize] > 0.0 {
                        p.mass(i as usize)
                    } else {
                        anchor
                    };
                    m * a / total_a[i as usize]
                })
                .collect();
            let mw_sum: f32 = mw.iter().sum();
            let c0 = weighted_centre(&p.x, &s.members, &mw, mw_sum);
            let rest: Vec<Vec3A> = s
                .members
                .iter()
                .map(|&i| Vec3A::from(p.x[i as usize] - c0))
                .collect();
            let mw_rest = rest.iter().zip(&mw).map(|(q, m)| *q * *m).collect();
            clusters.push(Cluster {
                members: s.members,
                weights: s.weights,
                mw,
                mw_sum,
                rest,
                mw_rest,
                centre: c0,
                omega2: (std::f32::consts::TAU * s.frequency_hz).powi(2),
                q: Quat::IDENTITY,
                warm: false,
            });
        }
        // Each particle's entries, in cluster order.
        let mut count = vec![0u32; n + 1];
        for c in &clusters {
            for &i in &c.members {
                count[i as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let offsets = count.clone();
        let mut fill = count;
        let mut entries = vec![(0u32, 0u32); offsets[n] as usize];
        for (k, c) in clusters.iter().enumerate() {
            for (slot, &i) in c.members.iter().enumerate() {
                let at = &mut fill[i as usize];
                entries[*at as usize] = (k as u32, slot as u32);
                *at += 1;
            }
        }
        // A particle's springs share its mass by membership weight (the paper's average over
        // its clusters): with every cluster at `omega`, they sum to `m omega^2`.
        let mut rate = vec![0.0f32; entries.len()];
        for i in 0..n {
            let (from, to) = (offsets[i] as usize, offsets[i + 1] as usize);
            if p.w[i] <= 0.0 || from == to {
                continue;
            }
            let weight = |&(k, slot): &(u32, u32)| clusters[k as usize].weights[slot as usize];
            let total: f32 = entries[from..to].iter().map(weight).sum();
            for e in from..to {
                let c = &clusters[entries[e].0 as usize];
                rate[e] = weight(&entries[e]) / total * c.omega2;
            }
        }
        let mu = vec![Vec3A::ZERO; entries.len()];
        let mut runs: Vec<(usize, usize)> = Vec::new();
        let mut start = 0;
        while start < n {
            let mut end = start + 1;
            while end < n && (offsets[end] - offsets[start]) < RUN {
                end += 1;
            }
            runs.push((start, end));
            start = end;
        }
        let entry_rest = entries
            .iter()
            .map(|&(k, slot)| clusters[k as usize].rest[slot as usize])
            .collect();
        Ok(ShapeMatching {
            frames: vec![(Mat3A::IDENTITY, Vec3A::ZERO); clusters.len()],
            clusters,
            offsets,
            entry_cluster: entries.iter().map(|&(k, _)| k).collect(),
            entry_rest,
            coef: vec![[0.0; 2]; rate.len()],
            rate,
            mu,
            coef_dt: 0.0,
            runs,
            behind: false,
        })
    }

    pub fn clusters(&self) -> usize {
        self.clusters.len()
    }

    /// Memberships over all clusters.
    pub fn memberships(&self) -> usize {
        self.entry_cluster.len()
    }

    /// Particles that belong to at least one cluster.
    pub fn particles_in_clusters(&self) -> usize {
        self.offsets.windows(2).filter(|w| w[1] > w[0]).count()
    }

    /// Cluster `k`'s rotation after the last projection.
    pub fn rotation(&self, k: usize) -> Quat {
        self.clusters[k].q
    }

    /// Cluster `k`'s goal for its member `slot` after the last projection, m.
    pub fn goal(&self, k: usize, slot: usize) -> Vec3 {
        let (r, c) = self.frames[k];
        (r * self.clusters[k].rest[slot] + c).into()
    }

    /// Computes every cluster's rotation and centre, its goals' frame, from the present
    /// positions (steps 1-3).
    pub fn match_goals(&mut self, x: &[Vec3]) {
        let one = |(c, frame): (&mut Cluster, &mut (Mat3A, Vec3A))| *frame = c.match_goals(x);
        if worth_threads(self.clusters.len()) {
            self.clusters
                .par_iter_mut()
                .zip(&mut self.frames)
                .with_min_len(16)
                .for_each(one);
        } else {
            self.clusters.iter_mut().zip(&mut self.frames).for_each(one);
        }
    }

    /// Starts a step: the springs' multipliers back to zero.
    pub fn begin_step(&mut self) {
        self.mu.fill(Vec3A::ZERO);
        if self.behind {
            self.clusters.iter_mut().for_each(|c| c.warm = false);
            self.behind = false;
        }
    }

    /// A device stepped the clusters on from these (see [`ShapeMatching::is_behind`]).
    pub(super) fn fall_behind(&mut self) {
        self.behind = true;
    }

    /// Whether a device holds newer centres and rotations than these.
    pub(super) fn is_behind(&self) -> bool {
        self.behind
    }

    /// One iteration of a step of `dt_s`: goals, then every free particle through its
    /// clusters' springs (step 4).
    pub fn project(&mut self, p: &mut Particles, dt_s: f32) {
        self.match_goals(&p.x);
        if self.coef_dt != dt_s {
            self.coef_dt = dt_s;
            for (c, &r) in self.coef.iter_mut().zip(&self.rate) {
                *c = coefficients(r, dt_s);
            }
        }
        let mut xs: Vec<&mut [Vec3]> = Vec::with_capacity(self.runs.len());
        let mut ms: Vec<&mut [Vec3A]> = Vec::with_capacity(self.runs.len());
        let (mut xr, mut mr) = (&mut p.x[..], &mut self.mu[..]);
        for &(a, b) in &self.runs {
            let (x_here, x_rest) = std::mem::take(&mut xr).split_at_mut(b - a);
            let m = (self.offsets[b] - self.offsets[a]) as usize;
            let (m_here, m_rest) = std::mem::take(&mut mr).split_at_mut(m);
            xs.push(x_here);
            ms.push(m_here);
            xr = x_rest;
            mr = m_rest;
        }
        let (frames, offsets, entry_cluster, entry_rest, coef, w) = (
            &self.frames,
            &self.offsets,
            &self.entry_cluster,
            &self.entry_rest,
            &self.coef,
            &p.w,
        );
        // XPBD for `C = x - g` with compliance `1 / k`, `k = m r`: in `mu = w lambda` the
        // update is `d_mu = (g - x - beta mu) / (1 + beta)`, `beta = 1 / (r dt^2)`, and
        // `x += d_mu` (the particle's mass drops out).
        let one = |((xs, ms), &(a, _)): (RunSlices, &(usize, usize))| {
            let base = offsets[a] as usize;
            for (k, x) in xs.iter_mut().enumerate() {
                let i = a + k;
                if w[i] <= 0.0 {
                    continue;
                }
                // Three lanes at once (the same operations, in the same order, as on
                // each coordinate alone).
                let mut xa = Vec3A::from(*x);
                for e in offsets[i] as usize..offsets[i + 1] as usize {
                    let [beta, inv] = coef[e];
                    if inv <= 0.0 {
                        continue;
                    }
                    let (r, c) = &frames[entry_cluster[e] as usize];
                    let g = *r * entry_rest[e] + *c;
                    let m = &mut ms[e - base];
                    let d = (g - xa - beta * *m) * inv;
                    *m += d;
                    xa += d;
                }
                *x = xa.into();
            }
        };
        if worth_threads(w.len()) {
            xs.into_par_iter().zip(ms).zip(&self.runs).for_each(one);
        } else {
            xs.into_iter().zip(ms).zip(&self.runs).for_each(one);
        }
    }

    /// Cluster `k`'s deviation from its goals, m (root mean square over its members, at the
    /// goals of the last projection).
    pub fn deviation(&self, x: &[Vec3], k: usize) -> f32 {
        let c = &self.clusters[k];
        let (r, centre) = self.frames[k];
        let s: f32 = c
            .members
            .iter()
            .zip(&c.rest)
            .map(|(&i, q)| (Vec3A::from(x[i as usize]) - (r * *q + centre)).length_squared())
            .sum();
        (s / c.members.len() as f32).sqrt()
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        let per: usize = self
            .clusters
            .iter()
            .map(|c| c.members.len() * (4 + 4 + 4 + 12 + 12))
            .sum();
        per + self.frames.len() * 64
            + self.offsets.len() * 4
            + self.entry_cluster.len() * (4 + 16 + 4 + 16 + 8)
    }
}

/// An entry's `[beta, 1 / (1 + beta)]` for a substep of `dt_s` from its rate `k / m`
/// (`beta` infinite and the factor 0 for a pinned particle's).
pub(super) fn coefficients(rate: f32, dt_s: f32) -> [f32; 2] {
    let beta = if rate > 0.0 {
        1.0 / (rate * dt_s * dt_s)
    } else {
        f32::INFINITY
    };
    [beta, 1.0 / (1.0 + beta)]
}

/// The clusters and entries flattened for a device (`gpu.rs`, `shaders/particles.wgsl`).
pub(super) struct ShapeArrays {
    /// Per cluster: first member, end, the bits of its mass sum, 0.
    pub info: Vec<[u32; 4]>,
    /// Per cluster: `[centre, warm]`, `[quaternion]`.
    pub state: Vec<[f32; 4]>,
    pub member_index: Vec<u32>,
    /// Per member: `[m a q, m a]`.
    pub member_mw: Vec<[f32; 4]>,
    /// Each particle's entries `offsets[i]..offsets[i + 1]`.
    pub offsets: Vec<u32>,
    /// Per entry: `[rest offset, bits of the cluster]`.
    pub entries: Vec<[f32; 4]>,
    /// Per entry: `k / m`, 1/s^2, and the multiplier.
    pub rate: Vec<f32>,
    pub mu: Vec<[f32; 4]>,
}

impl ShapeMatching {
    /// Everything a device needs to project these clusters.
    pub(super) fn arrays(&self) -> ShapeArrays {
        let mut a = ShapeArrays {
            info: Vec::with_capacity(self.clusters.len()),
            state: Vec::new(),
            member_index: Vec::new(),
            member_mw: Vec::new(),
            offsets: self.offsets.clone(),
            entries: self
                .entry_rest
                .iter()
                .zip(&self.entry_cluster)
                .map(|(q, &k)| [q.x, q.y, q.z, f32::from_bits(k)])
                .collect(),
            rate: self.rate.clone(),
            mu: self.mu.iter().map(|m| [m.x, m.y, m.z, 0.0]).collect(),
        };
        for c in &self.clusters {
            let first = a.member_index.len() as u32;
            a.member_index.extend(&c.members);
            a.member_mw.extend(
                c.mw_rest
                    .iter()
                    .zip(&c.mw)
                    .map(|(q, &m)| [q.x, q.y, q.z, m]),
            );
            a.info
                .push([first, a.member_index.len() as u32, c.mw_sum.to_bits(), 0]);
        }
        a.state = self.state_rows();
        a
    }

    /// The clusters' centres with their warm starts and their rotations, two rows a cluster
    /// (what a device holds of them between substeps).
    pub(super) fn state_rows(&self) -> Vec<[f32; 4]> {
        let mut state = Vec::with_capacity(2 * self.clusters.len());
        for c in &self.clusters {
            let warm = if c.warm && !self.behind { 1.0 } else { 0.0 };
            state.push([c.centre.x, c.centre.y, c.centre.z, warm]);
            state.push(c.q.to_array());
        }
        state
    }

    /// Takes the clusters' centres, rotations and warm starts (`[centre, warm]`,
    /// `[quaternion]` per cluster), the frames of their goals and the multipliers from a
    /// device, so the CPU goes on where it left off.
    pub(super) fn take_device_state(
        &mut self,
        state: &[[f32; 4]],
        frames: &[[f32; 4]],
        mu: &[[f32; 4]],
    ) {
        for (k, c) in self.clusters.iter_mut().enumerate() {
            let (Some(s), Some(q)) = (state.get(2 * k), state.get(2 * k + 1)) else {
                break;
            };
            c.centre = Vec3::new(s[0], s[1], s[2]);
            c.warm = s[3] > 0.0;
            c.q = Quat::from_array(*q);
        }
        for (k, f) in self.frames.iter_mut().enumerate() {
            let Some(cols) = frames.get(4 * k..4 * k + 4) else {
                break;
            };
            let v = |j: usize| Vec3A::new(cols[j][0], cols[j][1], cols[j][2]);
            *f = (Mat3A::from_cols(v(0), v(1), v(2)), v(3));
        }
        for (m, d) in self.mu.iter_mut().zip(mu) {
            *m = Vec3A::new(d[0], d[1], d[2]);
        }
        self.behind = false;
    }
}

impl Cluster {
    /// Steps 1-3 in one pass over the members: about the last centre `o`, `sum m (x - o)`
    /// gives the centre and `sum (x - o) (m q)^T` is `A` (the rest offsets' weighted sum is
    /// zero, so the origin drops out of `A`).
    fn match_goals(&mut self, x: &[Vec3]) -> (Mat3A, Vec3A) {
        if !self.warm {
            // The body may be anywhere now: the sums about where it is.
            self.centre = weighted_centre(x, &self.members, &self.mw, self.mw_sum);
        }
        let o = Vec3A::from(self.centre);
        let (mut sum, mut ax, mut ay, mut az) =
            (Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO);
        for ((&i, &m), mq) in self.members.iter().zip(&self.mw).zip(&self.mw_rest) {
            let d = Vec3A::from(x[i as usize]) - o;
            sum += d * m;
            ax += d * mq.x;
            ay += d * mq.y;
            az += d * mq.z;
        }
        let c = o + sum / self.mw_sum;
        let a = Mat3::from_cols(ax.into(), ay.into(), az.into());
        let most = if self.warm {
            WARM_ROTATION_ITERATIONS
        } else {
            COLD_ROTATION_ITERATIONS
        };
        self.q = rotation_of(&a, self.q, most);
        self.warm = true;
        self.centre = c.into();
        (Mat3A::from_quat(self.q), c)
    }
}

fn weighted_centre(x: &[Vec3], members: &[u32], mw: &[f32], sum: f32) -> Vec3 {
    let mut c = Vec3::ZERO;
    for (&i, &m) in members.iter().zip(mw) {
        c += x[i as usize] * m;
    }
    c / sum
}

/// The rotation of `a`'s polar decomposition, from `q` (Müller, Bender, Chentanez and Macklin
/// 2016, "A robust method to extract the rotational part of deformations"): turn `q` by
/// `omega = sum_k r_k x a_k / |sum_k r_k . a_k|` until it no longer turns (at most
/// `iterations` times).
pub fn rotation_of(a: &Mat3, q: Quat, iterations: usize) -> Quat {
    let mut q = if q.is_finite() { q } else { Quat::IDENTITY };
    if !a.is_finite() {
        return q;
    }
    let cols = [a.x_axis, a.y_axis, a.z_axis];
    for _ in 0..iterations {
        let r = Mat3::from_quat(q);
        let rc = [r.x_axis, r.y_axis, r.z_axis];
        let mut num = Vec3::ZERO;
        let mut den = 0.0f32;
        for k in 0..3 {
            num += rc[k].cross(cols[k]);
            den += rc[k].dot(cols[k]);
        }
        let omega = num / (den.abs() + 1e-9 * (1.0 + num.length()));
        let angle = omega.length();
        // Below a few f32 rounding steps of a unit vector the turn is noise: done.
        if angle.is_nan() || angle <= ROTATION_TOLERANCE_RAD {
            break;
        }
        // The turn by `omega` as the normalised quaternion `(omega / 2, 1)`: the exponential
        // map to second order without its sine and cosine (a large turn, from a cold start,
        // is under-taken and finished by the next iterations).
        let turn = Quat::from_xyzw(0.5 * omega.x, 0.5 * omega.y, 0.5 * omega.z, 1.0).normalize();
        q = (turn * q).normalize();
    }
    q
}

/// The factor between a tissue's Young's modulus and its clusters' stiffness:
/// `omega^2 = MODULUS_FACTOR E / (rho r^2)` for clusters of radius `r` (2.5 lattice steps,
/// every 3 steps). Calibrated against the continuum: a column hanging under its own weight
/// stretches by `rho g H^2 / (2 E)`; with 10, columns of 20 and 30 lattice steps do so within
/// 3 % (the test `a_hanging_column_sags_as_the_continuum_does`). Shape matching's stiffness
/// depends on the body's size (taller columns come out softer: 12 % at 40 steps), so a body
/// far outside that range needs its own calibration.
pub const MODULUS_FACTOR: f32 = 10.0;

/// A cluster's frequency (Hz) for a tissue of Young's modulus `modulus_pa` and density
/// `density_kg_per_m3`, clusters of radius `radius_m` ([`MODULUS_FACTOR`]).
pub fn frequency_for(modulus_pa: f32, density_kg_per_m3: f32, radius_m: f32) -> f32 {
    (MODULUS_FACTOR * modulus_pa / (density_kg_per_m3 * radius_m * radius_m)).sqrt()
        / std::f32::consts::TAU
}

/// Clusters for a body whose particles lie on a lattice: centres every `stride` lattice
/// steps (of `spacing_m`) over the particles' box, each taking the particles within
/// `radius_m` with weight `(1 - (d / radius)^2)^2` (at least `min_weight`), and every
/// particle left out by them its nearest centre's cluster. Clusters with fewer than 4 members
/// are dropped (their particles join the nearest other cluster).
pub fn lattice_clusters(
    x: &[Vec3],
    members: &[u32],
    spacing_m: f32,
    stride: usize,
    radius_m: f32,
    frequency_hz: f32,
) -> Vec<ClusterSpec> {
    let min_weight = 0.05f32;
    if members.is_empty() {
        return Vec::new();
    }
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for &i in members {
        lo = lo.min(x[i as usize]);
        hi = hi.max(x[i as usize]);
    }
    let step = spacing_m * stride.max(1) as f32;
    let cells = ((hi - lo) / step).ceil().max(Vec3::ZERO).as_uvec3() + 1;
    let mut centres = Vec::new();
    for a in 0..cells.x {
        for b in 0..cells.y {
            for c in 0..cells.z {
                centres.push(lo + Vec3::new(a as f32, b as f32, c as f32) * step);
            }
        }
    }
    let mut specs: Vec<ClusterSpec> = centres
        .iter()
        .map(|_| ClusterSpec {
            members: Vec::new(),
            weights: Vec::new(),
            frequency_hz,
        })
        .collect();
    let mut covered = vec![false; members.len()];
    for (s, c) in specs.iter_mut().zip(&centres) {
        for (k, &i) in members.iter().enumerate() {
            let d2 = (x[i as usize] - *c).length_squared() / (radius_m * radius_m);
            if d2 < 1.0 {
                let wgt = ((1.0 - d2) * (1.0 - d2)).max(min_weight);
                s.members.push(i);
                s.weights.push(wgt);
                covered[k] = true;
            }
        }
    }
    let nearest = |p: Vec3, specs: &[ClusterSpec]| {
        centres
            .iter()
            .enumerate()
            .filter(|(k, _)| specs[*k].members.len() >= 4)
            .min_by(|a, b| {
                (p - *a.1)
                    .length_squared()
                    .total_cmp(&(p - *b.1).length_squared())
            })
            .map(|(k, _)| k)
    };
    for (k, &i) in members.iter().enumerate() {
        if !covered[k]
            && let Some(c) = nearest(x[i as usize], &specs)
        {
            specs[c].members.push(i);
            specs[c].weights.push(min_weight);
        }
    }
    // Small clusters' particles go to the nearest kept one (if not already in one).
    let small: Vec<usize> = (0..specs.len())
        .filter(|&k| !specs[k].members.is_empty() && specs[k].members.len() < 4)
        .collect();
    for k in small {
        let gone = std::mem::take(&mut specs[k].members);
        specs[k].weights.clear();
        for i in gone {
            let elsewhere = specs.iter().any(|s| s.members.contains(&i));
            if !elsewhere && let Some(c) = nearest(x[i as usize], &specs) {
                specs[c].members.push(i);
                specs[c].weights.push(min_weight);
            }
        }
    }
    specs.retain(|s| s.members.len() >= 4);
    specs
}
