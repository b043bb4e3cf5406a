//! The adhesive fascia: the cholecystectomy paper's proposed replacement for the cloth fascia
//! (its section 4.2, after Fig. 7b), strands of distance constraints between the gallbladder
//! and the liver that break at random points and leave sticky halves dangling from the organs.
//!
//! Each pair of particles (one on the gallbladder, `a`, one on the liver, `b`) becomes a
//! strand: `n = segments` distance constraints `C = |x1 - x2| - l0` (eq 5, [`Stretch`])
//! in a chain through `n - 1` new particles placed evenly on the straight line from `a` to `b`,
//! each of mass `strand_mass_kg / (n - 1)`. The strand's rest length `L` is the distance from
//! `a` to `b` when it is built, each segment's `l0 = L / n`.
//!
//! A pseudo-random generator (splitmix64, seeded) marks `breakable_per_strand` of each strand's
//! segments breakable (the paper's "breakable group" scattered at random along each
//! connection). Every segment starts very stiff, `k = stiffness_n_per_m` (a strand of `n`
//! such segments in series is a spring of `k / n`). Then, each step ([`Adhesion::update`]):
//! 1. a strand still whole whose ends are further apart than `break_stretch L` is weakened: its
//!    breakable segments' stiffness drops to `weak_stiffness_n_per_m`, so small that any force
//!    stretches them (the paper's break threshold). A weakened strand stays weakened. With the
//!    ends held apart by a force `F` that the stiff segments alone would carry, the strand is
//!    weakened at `F = k / n (break_stretch - 1) L`;
//! 2. in each whole strand, the segment strained most past `tear_strain` (if any) tears: it is
//!    removed and the event returned. The strains are the strand's equilibrium's, from its
//!    ends' distance `D`: the segments in series share the tension, so segment `i` of
//!    compliance `c_i` stretches `(D - L) c_i / sum c` (nothing when slack). One tear a
//!    strand, and a torn strand's breakable segments stiff again: the two halves stay on their
//!    organs as sticky strands, not let go by a second weak link nor leaving a piece floating
//!    between two tears.
//!
//! A whole strand is solved at its equilibrium ([`Whole`]): one XPBD constraint between its
//! ends, `C = |a - b| - L`, tension only, of compliance `sum c_i` (m/N), its interior particles
//! then placed on the line between the ends, each segment stretched by the shared tension.
//! The interior particles weigh milligrams against the organs' grams, so at the step's length
//! they are always where the tension puts them; as a chain of light particles a substep's
//! solve threw them past their line and the next threw them back. The multiplier is kept over
//! the step's iterations (zeroed by [`Adhesion::begin_step`]); after the iterations,
//! `-lambda / dt^2` is the force the strand carries, newtons (positive in tension), and every
//! segment's multiplier is its strand's. A torn strand's halves hang from their organs as
//! chains: a sweep solves each run of intact segments together (its linearised system is
//! tridiagonal: one pass of the Thomas algorithm).
//!
//! Units are SI: metres, kilograms, seconds, newtons. Determinism: every sweep, check and cut
//! goes through the strands and segments in order, and the generator is seeded, so the same
//! inputs give the same bytes and the same breaks.

use super::chain::{Row, solve_chain};
use super::gpu::{ChainSegment, ChainSet, DeviceChain};
use super::{Particles, colour};

/// Solves of each run of a torn strand's halves per sweep, each linearised where the last left
/// it (Newton steps on the run's own system): where a half is bent, one linearised solve
/// throws its light particles past their line and the next sweep throws them back. (Whole
/// strands are solved at their equilibrium instead, [`Whole`].)
pub const STRAND_NEWTON_STEPS: usize = 3;
use crate::models::xpbd::Stretch;
use glam::Vec3;

/// How the strands are built and break.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdhesionParams {
    /// Distance constraints per strand, 2 to 65536 (a strand has `segments - 1` interior
    /// particles).
    pub segments: u32,
    /// Mass of a strand's interior particles together, kg (split evenly among them).
    pub strand_mass_kg: f32,
    /// Body id of the interior particles.
    pub body: u16,
    /// Each segment's spring constant while intact, N/m (very large: the strands hold).
    pub stiffness_n_per_m: f32,
    /// A breakable segment's spring constant once its strand is weakened, N/m (very small, and
    /// less than `stiffness_n_per_m`).
    pub weak_stiffness_n_per_m: f32,
    /// Breakable segments per strand, at most `segments`.
    pub breakable_per_strand: u32,
    /// The ratio of the ends' distance to the strand's rest length past which the strand is
    /// weakened, more than 1 (1.2: stretched 20 %).
    pub break_stretch: f32,
    /// The strain past which a segment tears, more than 0 (0.5: 50 % longer than its rest
    /// length).
    pub tear_strain: f32,
}

impl AdhesionParams {
    /// Checks every field; the error names the first one that is wrong.
    pub fn validate(&self) -> Result<(), AdhesionError> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        let (k, weak) = (self.stiffness_n_per_m, self.weak_stiffness_n_per_m);
        let (segments, breakable) = (self.segments, self.breakable_per_strand);
        let checks: [(&'static str, &'static str, bool, String); 7] = [
            (
                "segments",
                "at least 2 and at most 65536",
                (2..=65536).contains(&segments),
                segments.to_string(),
            ),
            (
                "strand_mass_kg",
                "a positive finite number",
                positive(self.strand_mass_kg),
                self.strand_mass_kg.to_string(),
            ),
            (
                "stiffness_n_per_m",
                "a positive finite number",
                positive(k),
                k.to_string(),
            ),
            (
                "weak_stiffness_n_per_m",
                "a positive number less than stiffness_n_per_m",
                positive(weak) && weak < k,
                weak.to_string(),
            ),
            (
                "breakable_per_strand",
                "at most segments",
                breakable <= segments,
                breakable.to_string(),
            ),
            (
                "break_stretch",
                "a finite number more than 1",
                self.break_stretch.is_finite() && self.break_stretch > 1.0,
                self.break_stretch.to_string(),
            ),
            (
                "tear_strain",
                "a positive finite number",
                positive(self.tear_strain),
                self.tear_strain.to_string(),
            ),
        ];
        match checks.into_iter().find(|c| !c.2) {
            None => Ok(()),
            Some((field, rule, _, value)) => Err(AdhesionError::Param { field, rule, value }),
        }
    }
}

/// Why strands were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AdhesionError {
    #[error("{field} must be {rule} (got {value})")]
    Param {
        field: &'static str,
        rule: &'static str,
        value: String,
    },
    #[error("pair {pair}: particle {particle} does not exist ({len} particles)")]
    NoParticle {
        pair: usize,
        particle: u32,
        len: usize,
    },
    #[error("pair {pair} joins particle {particle} to itself")]
    SameParticle { pair: usize, particle: u32 },
    #[error("pair {pair}: particles {a} and {b} are not apart (a strand needs a length)")]
    NoLength { pair: usize, a: u32, b: u32 },
    #[error("{pairs} strands of {segments} segments would number the particles past u32")]
    TooMany { pairs: usize, segments: u32 },
}

/// A segment torn (stretched past the tear strain) or cut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdhesionBreak {
    /// The strand, in the order of the pairs.
    pub strand: u32,
    /// The segment along the strand, 0 at its first particle (the gallbladder's).
    pub segment: u32,
    /// Where: the segment's middle when torn, its point nearest the tool when cut, m.
    pub position: Vec3,
}

#[derive(Debug, Clone)]
struct Strand {
    /// The ends (gallbladder, liver).
    a: u32,
    b: u32,
    /// The first interior particle (the others follow it).
    first: u32,
    /// The rest length end to end, m.
    rest_m: f32,
    /// Whether its breakable segments have gone weak.
    weak: bool,
    /// Segments torn or cut.
    torn: u32,
}

/// A whole strand at its equilibrium: one XPBD constraint between its ends, `C = |a - b| - L`,
/// tension only, of the compliance of its segments in series; then its interior particles on
/// the line from `a` to `b`, each segment stretched by the tension they share (evenly spaced
/// when slack). Its interior particles weigh milligrams against the organs' grams: a segment's
/// own swing is thousands of radians a second, so at the step's length they are always where
/// the tension puts them. Solved as a chain of light particles instead, a substep's
/// linearised solve threw them past their line and the next threw them back (a swing of
/// period two substeps that shook what the strands hold, and tore strands whose ends were
/// 1.1 times their rest length apart, more of them the longer the step:
/// docs/cholecystectomy.md, "The strands at their equilibrium").
struct Whole {
    a: usize,
    b: usize,
    first: usize,
}

impl Whole {
    /// One solve; every segment's multiplier becomes the strand's.
    fn solve(
        &self,
        p: &mut Particles,
        segs: &[Segment],
        lambda: &mut [f32],
        compliance: impl Fn(&Segment) -> f32,
        dt: f32,
    ) {
        let (a, b) = (self.a, self.b);
        let total: f32 = segs.iter().map(&compliance).sum();
        let rest: f32 = segs.iter().map(|s| s.c.rest_m).sum();
        let x = &mut p.x;
        let wsum = p.w[a] + p.w[b];
        let d = x[a] - x[b];
        let len = d.length();
        if wsum > 0.0 && len > f32::EPSILON {
            let n = d / len;
            let alpha = total / (dt * dt);
            let held = lambda[0];
            // Tension only (the multiplier is negative in tension): a slack strand buckles.
            let dl = ((-(len - rest) - alpha * held) / (wsum + alpha) + held).min(0.0) - held;
            x[a] += n * (p.w[a] * dl);
            x[b] -= n * (p.w[b] * dl);
            lambda.fill(held + dl);
        }
        let (xa, xb) = (x[a], x[b]);
        let len = xa.distance(xb);
        let excess = len - rest;
        let count = segs.len() as f32;
        let mut along = 0.0f32;
        for (j, seg) in segs[..segs.len() - 1].iter().enumerate() {
            along += if excess > 0.0 {
                seg.c.rest_m + excess * compliance(seg) / total
            } else {
                len / count
            };
            let t = if len > f32::EPSILON { along / len } else { 0.0 };
            x[self.first + j] = xa + (xb - xa) * t;
        }
    }
}

#[derive(Debug, Clone)]
struct Segment {
    c: Stretch,
    breakable: bool,
    intact: bool,
}

impl Segment {
    /// Its compliance, m/N: `weak` for a breakable segment of a weakened strand, else `stiff`.
    fn compliance(&self, weakened: bool, stiff: f32, weak: f32) -> f32 {
        if self.breakable && weakened {
            weak
        } else {
            stiff
        }
    }
}

impl AsRef<Stretch> for Segment {
    fn as_ref(&self) -> &Stretch {
        &self.c
    }
}

/// Breakable strands of distance constraints between two organs.
#[derive(Debug, Clone)]
pub struct Adhesion {
    params: AdhesionParams,
    strands: Vec<Strand>,
    /// Strand `s`'s segments are `segments[s n..(s + 1) n]`, `n = params.segments`.
    segments: Vec<Segment>,
    /// XPBD multipliers over the step, N s^2.
    lambda: Vec<f32>,
    /// The last projection's step, s.
    dt: f32,
    /// The number of particles the strands need.
    needs: usize,
    /// A strand's rows of its chain's linear system (work space).
    rows: Vec<Row>,
    /// The strands in projection order: by colour (strands of one colour share no particle,
    /// `colour.rs`), then as given; and each strand's colour.
    order: Vec<u32>,
    colours: Vec<u32>,
}

impl Adhesion {
    /// Strands between `pairs` of particles (gallbladder, liver), their interior particles
    /// added to `p`; `seed` picks the breakable segments. Nothing is added when refused.
    pub fn new(
        p: &mut Particles,
        pairs: &[(u32, u32)],
        params: AdhesionParams,
        seed: u64,
    ) -> Result<Adhesion, AdhesionError> {
        params.validate()?;
        let n = p.len();
        for (pair, &(a, b)) in pairs.iter().enumerate() {
            for particle in [a, b] {
                if particle as usize >= n {
                    return Err(AdhesionError::NoParticle {
                        pair,
                        particle,
                        len: n,
                    });
                }
            }
            if a == b {
                return Err(AdhesionError::SameParticle { pair, particle: a });
            }
            let d = p.x[a as usize].distance(p.x[b as usize]);
            if !(d.is_finite() && d > 0.0) {
                return Err(AdhesionError::NoLength { pair, a, b });
            }
        }
        let segs = params.segments;
        let interior = segs as usize - 1;
        let total = pairs
            .len()
            .checked_mul(interior)
            .and_then(|k| k.checked_add(n));
        if total.is_none_or(|t| t > u32::MAX as usize) {
            return Err(AdhesionError::TooMany {
                pairs: pairs.len(),
                segments: segs,
            });
        }
        let mass = params.strand_mass_kg / interior as f32;
        let mut rng = crate::rng::SplitMix64(seed);
        let mut order: Vec<u32> = Vec::with_capacity(segs as usize);
        let mut strands = Vec::with_capacity(pairs.len());
        let mut segments = Vec::with_capacity(pairs.len() * segs as usize);
        for &(a, b) in pairs {
            let (xa, xb) = (p.x[a as usize], p.x[b as usize]);
            let rest_m = xa.distance(xb);
            let first = p.len() as u32;
            for j in 1..segs {
                p.add(xa.lerp(xb, j as f32 / segs as f32), mass, params.body);
            }
            // The chain a, first, first + 1, ..., b.
            let node = |j: u32| match j {
                0 => a,
                j if j == segs => b,
                j => first + j - 1,
            };
            // A partial Fisher-Yates shuffle: the first `breakable_per_strand` of a random
            // order of the segments.
            order.clear();
            order.extend(0..segs);
            for k in 0..params.breakable_per_strand {
                let pick = k + rng.below(segs - k);
                order.swap(k as usize, pick as usize);
            }
            let from = segments.len();
            for j in 0..segs {
                segments.push(Segment {
                    c: Stretch {
                        a: node(j),
                        b: node(j + 1),
                        rest_m: rest_m / segs as f32,
                    },
                    breakable: false,
                    intact: true,
                });
            }
            for &k in &order[..params.breakable_per_strand as usize] {
                segments[from + k as usize].breakable = true;
            }
            strands.push(Strand {
                a,
                b,
                first,
                rest_m,
                weak: false,
                torn: 0,
            });
        }
        // Strands share only their ends (their interior particles are their own).
        let colours = colour::greedy(&pairs.iter().map(|&(a, b)| [a, b]).collect::<Vec<_>>());
        let order = colour::order(&colours)
            .into_iter()
            .map(|k| k as u32)
            .collect();
        Ok(Adhesion {
            order,
            colours,
            params,
            lambda: vec![0.0; segments.len()],
            strands,
            segments,
            dt: 0.0,
            needs: p.len(),
            rows: vec![Row::default(); segs as usize],
        })
    }

    pub fn params(&self) -> &AdhesionParams {
        &self.params
    }

    /// Strands built.
    pub fn strands(&self) -> usize {
        self.strands.len()
    }

    /// Strands with no segment torn or cut.
    pub fn intact_strands(&self) -> usize {
        self.strands.iter().filter(|s| s.torn == 0).count()
    }

    /// Segments built (intact or not).
    pub fn segments(&self) -> usize {
        self.segments.len()
    }

    /// Segments torn or cut.
    pub fn torn_segments(&self) -> usize {
        self.segments.iter().filter(|s| !s.intact).count()
    }

    /// Whether `strand` has been weakened (false when there is no such strand).
    pub fn is_weakened(&self, strand: usize) -> bool {
        self.strands.get(strand).is_some_and(|s| s.weak)
    }

    /// `strand`'s particles end to end: its gallbladder end, the interior ones, its liver end
    /// (empty when there is no such strand).
    pub fn strand_particles(&self, strand: usize) -> Vec<u32> {
        let Some(s) = self.strands.get(strand) else {
            return Vec::new();
        };
        let interior = s.first..s.first + self.params.segments - 1;
        std::iter::once(s.a)
            .chain(interior)
            .chain(std::iter::once(s.b))
            .collect()
    }

    /// `strand`'s segments (along it) marked breakable.
    pub fn breakable_segments(&self, strand: usize) -> impl Iterator<Item = u32> + '_ {
        self.strand_segments(strand)
            .iter()
            .zip(0..)
            .filter(|(s, _)| s.breakable)
            .map(|(_, k)| k)
    }

    /// Whether segment `segment` of `strand` is intact (false when there is no such segment).
    pub fn segment_intact(&self, strand: usize, segment: usize) -> bool {
        self.strand_segments(strand)
            .get(segment)
            .is_some_and(|s| s.intact)
    }

    fn strand_segments(&self, strand: usize) -> &[Segment] {
        let n = self.params.segments as usize;
        self.segments
            .get(strand * n..(strand + 1) * n)
            .unwrap_or(&[])
    }

    /// The largest strain of an intact segment now (0 when none is intact).
    pub fn max_segment_strain(&self, p: &Particles) -> f32 {
        if p.len() < self.needs {
            return 0.0;
        }
        self.segments
            .iter()
            .filter(|s| s.intact)
            .map(|s| (p.x[s.c.a as usize].distance(p.x[s.c.b as usize]) - s.c.rest_m) / s.c.rest_m)
            .fold(0.0, f32::max)
    }

    /// The intact segments' particle pairs, to draw as lines.
    pub fn segments_for_drawing(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.segments
            .iter()
            .filter(|s| s.intact)
            .map(|s| (s.c.a, s.c.b))
    }

    /// The force `strand` carries, N (positive in tension): the mean over its intact segments
    /// of `-lambda / dt^2`, from the multipliers of the step's projections so far (read it
    /// after the iterations, before the next [`Adhesion::begin_step`]). 0 when no segment is
    /// intact or nothing was projected.
    pub fn tension_n(&self, strand: usize) -> f32 {
        let n = self.params.segments as usize;
        let range = strand * n..(strand + 1) * n;
        let (Some(segs), Some(lambda)) = (self.segments.get(range.clone()), self.lambda.get(range))
        else {
            return 0.0;
        };
        let (sum, count) = segs
            .iter()
            .zip(lambda)
            .filter(|(s, _)| s.intact)
            .fold((0.0f32, 0u32), |(sum, count), (_, l)| (sum - l, count + 1));
        if count == 0 || self.dt <= 0.0 {
            return 0.0;
        }
        sum / count as f32 / (self.dt * self.dt)
    }

    /// Starts a step: the multipliers back to zero.
    pub fn begin_step(&mut self) {
        self.lambda.fill(0.0);
    }

    /// One sweep of a step of `dt` seconds: Gauss-Seidel from strand to strand in projection
    /// order (by colour), each whole strand at its equilibrium ([`Whole`]), each torn one's runs
    /// of intact segments solved together (see [`solve_chain`]). Does nothing when `dt` is not
    /// a positive number or `p` lacks the strands' particles.
    pub fn project(&mut self, p: &mut Particles, dt: f32) {
        if !(dt.is_finite() && dt > 0.0) || p.len() < self.needs {
            return;
        }
        self.dt = dt;
        let n = self.params.segments as usize;
        let stiff = 1.0 / self.params.stiffness_n_per_m;
        let weak = 1.0 / self.params.weak_stiffness_n_per_m;
        for &k in &self.order {
            let (k, strand) = (k as usize, &self.strands[k as usize]);
            let segs = &self.segments[k * n..(k + 1) * n];
            let lambda = &mut self.lambda[k * n..(k + 1) * n];
            if strand.torn == 0 {
                let compliance = |s: &Segment| s.compliance(strand.weak, stiff, weak);
                let whole = Whole {
                    a: strand.a as usize,
                    b: strand.b as usize,
                    first: strand.first as usize,
                };
                whole.solve(p, segs, lambda, compliance, dt);
                continue;
            }
            // A torn strand's halves hang from their organs as chains of particles, their
            // segments stiff again.
            let mut from = 0;
            while from < n {
                if !segs[from].intact {
                    from += 1;
                    continue;
                }
                let mut to = from + 1;
                while to < n && segs[to].intact {
                    to += 1;
                }
                let rows = &mut self.rows[..to - from];
                for row in rows.iter_mut() {
                    row.compliance = stiff;
                }
                for _ in 0..STRAND_NEWTON_STEPS {
                    solve_chain(p, &segs[from..to], &mut lambda[from..to], rows, dt);
                }
                from = to;
            }
        }
    }

    /// Strands weakened and segments torn or cut so far (a change to either changes what a
    /// sweep projects).
    pub fn broken_counts(&self) -> (usize, usize) {
        let weak = self.strands.iter().filter(|s| s.weak).count();
        let torn = self.segments.iter().filter(|s| !s.intact).count();
        (weak, torn)
    }

    /// The strands as a device takes them, in projection order (`gpu.rs`).
    pub(super) fn device_set(&self) -> ChainSet {
        let n = self.params.segments as usize;
        let mut set = ChainSet::default();
        for &k in &self.order {
            let (k, strand) = (k as usize, &self.strands[k as usize]);
            let first = set.segs.len() as u32;
            for s in &self.segments[k * n..(k + 1) * n] {
                set.segs.push(ChainSegment {
                    c: s.c,
                    intact: s.intact,
                    breakable: s.breakable,
                });
            }
            let bends = set.bends.len() as u32;
            set.chains.push(DeviceChain {
                segs: first..set.segs.len() as u32,
                bends: bends..bends,
                compliance: 1.0 / self.params.stiffness_n_per_m,
                weak_compliance: 1.0 / self.params.weak_stiffness_n_per_m,
                weakened: strand.weak && strand.torn == 0,
                whole: strand.torn == 0,
                solves: STRAND_NEWTON_STEPS as u32,
                bend_compliance: 0.0,
                colour: self.colours[k],
            });
        }
        set
    }

    /// The step's checks, after the iterations: weakens the whole strands stretched past the
    /// break threshold, then tears each strand's segment stretched most past the tear strain;
    /// returns the tears.
    pub fn update(&mut self, p: &Particles) -> Vec<AdhesionBreak> {
        let mut out = Vec::new();
        if p.len() < self.needs {
            return out;
        }
        let x = &p.x;
        for s in &mut self.strands {
            if s.torn == 0
                && !s.weak
                && x[s.a as usize].distance(x[s.b as usize]) > self.params.break_stretch * s.rest_m
            {
                s.weak = true;
            }
        }
        // Each whole strand's most strained segment past the tear strain, if any, tears. The
        // strains are the strand's equilibrium's, from its ends' distance: its interior
        // particles weigh milligrams against the organs' grams (a segment's own swing is
        // thousands of radians a second), so the strand is a spring of its segments in series,
        // each stretched by the tension they share. Read from the interior particles'
        // positions instead, a strand swinging sideways between two substeps had segments
        // past the tear strain with its ends 1.1 times their rest length apart, and how many
        // tore depended on the step's length (docs/cholecystectomy.md, "The strands at
        // their equilibrium").
        let n = self.params.segments as usize;
        let stiff = 1.0 / self.params.stiffness_n_per_m;
        let weak = 1.0 / self.params.weak_stiffness_n_per_m;
        for (k, s) in self.strands.iter_mut().enumerate() {
            if s.torn > 0 {
                continue;
            }
            let segs = &self.segments[k * n..(k + 1) * n];
            // The rest length as the solve takes it (`Whole::solve`): its segments' together.
            let rest: f32 = segs.iter().map(|seg| seg.c.rest_m).sum();
            let excess = x[s.a as usize].distance(x[s.b as usize]) - rest;
            if excess.is_nan() || excess <= 0.0 {
                continue;
            }
            let compliance = |seg: &Segment| seg.compliance(s.weak, stiff, weak);
            let total: f32 = segs.iter().map(compliance).sum();
            let mut worst: Option<(usize, f32)> = None;
            for (j, seg) in segs.iter().enumerate() {
                let strain = excess * compliance(seg) / total / seg.c.rest_m;
                if strain > self.params.tear_strain && worst.is_none_or(|(_, w)| strain > w) {
                    worst = Some((j, strain));
                }
            }
            if let Some((j, _)) = worst {
                let seg = &mut self.segments[k * n + j];
                seg.intact = false;
                self.lambda[k * n + j] = 0.0;
                s.torn += 1;
                out.push(AdhesionBreak {
                    strand: k as u32,
                    segment: j as u32,
                    position: x[seg.c.a as usize].lerp(x[seg.c.b as usize], 0.5),
                });
            }
        }
        out
    }

    /// Cuts every intact segment passing within `radius_m` of `centre` (m): the hook's or the
    /// scissors' cut. Returns the cuts, each at the segment's point nearest `centre`.
    pub fn cut_near(&mut self, centre: Vec3, radius_m: f32, p: &Particles) -> Vec<AdhesionBreak> {
        let mut out = Vec::new();
        if radius_m.is_nan() || radius_m < 0.0 || p.len() < self.needs {
            return out;
        }
        let n = self.params.segments as usize;
        for (k, (s, l)) in self.segments.iter_mut().zip(&mut self.lambda).enumerate() {
            if !s.intact {
                continue;
            }
            let nearest = nearest_on_segment(p.x[s.c.a as usize], p.x[s.c.b as usize], centre);
            if nearest.distance_squared(centre) <= radius_m * radius_m {
                s.intact = false;
                *l = 0.0;
                self.strands[k / n].torn += 1;
                out.push(AdhesionBreak {
                    strand: (k / n) as u32,
                    segment: (k % n) as u32,
                    position: nearest,
                });
            }
        }
        out
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        self.strands.capacity() * std::mem::size_of::<Strand>()
            + self.segments.capacity() * std::mem::size_of::<Segment>()
            + self.lambda.capacity() * 4
            + self.rows.capacity() * std::mem::size_of::<Row>()
    }
}

/// The point of the segment from `a` to `b` nearest `q`.
fn nearest_on_segment(a: Vec3, b: Vec3, q: Vec3) -> Vec3 {
    let ab = b - a;
    let len2 = ab.length_squared();
    if len2 <= 0.0 {
        return a;
    }
    a + ab * ((q - a).dot(ab) / len2).clamp(0.0, 1.0)
}

#[cfg(test)]
#[path = "adhesion_tests.rs"]
mod tests;
