//! The XPBD constraints (stretch and bending, eqs 11-12) gathered around awake points and
//! projected with the points' masses. Ties are springs of the implicit step, not constraints.
//!
//! A sweep works in blocks of point indices (cut at quantiles of the awake points, which the
//! mesh numbers so that neighbours have nearby indices): the constraints inside one block are
//! projected one after another by one task, the blocks in parallel (they share no point), and
//! the few constraints that cross blocks after them. The blocks depend on the awake points
//! only, never on the threads, so the result is the same bytes on one thread or many.

use super::*;
use rayon::prelude::*;

/// Blocks a sweep is cut into.
pub(super) const BLOCKS: usize = 4;
/// Marks a listed constraint (beside its block) as acting on a point a tool holds.
const HELD: u32 = 1 << 31;

/// What one run of awake points lists: (constraint, block | HELD) and the sleeping points
/// those constraints touch (with repeats).
#[derive(Default)]
struct Listing {
    ids: Vec<(u32, u32)>,
    fringe: Vec<u32>,
}

impl SoftBody {
    /// Lists the live constraints around the awake points, sorted (stably) into blocks of
    /// point indices cut at quantiles of the awake points, those that cross blocks last.
    /// Also lists, while each constraint's points are at hand, the sleeping points the
    /// projection may move (the fringe) and the constraints on points a tool holds.
    ///
    /// A constraint is listed by the lowest-numbered of its awake points, so each once and in
    /// the order of the awake points (sorted): runs of awake points are scanned in parallel
    /// and their lists joined in order, the same bytes on one thread or many.
    pub(super) fn collect_constraints(&mut self) {
        let n = self.x.len() as u32;
        let active = &self.active;
        let mut bounds = [n; BLOCKS + 1];
        bounds[0] = 0;
        for b in 1..BLOCKS {
            let q = active.get(b * active.len() / BLOCKS).copied().unwrap_or(n);
            bounds[b] = q.max(bounds[b - 1]);
        }
        // Block of a point: how many inner bounds are at or below it.
        let block_of = |q: u32| bounds[1..BLOCKS].iter().filter(|&&e| e <= q).count() as u32;
        let any_held = !self.pins.is_empty() || !self.held.is_empty();
        let this = &*self;
        let runs: Vec<Listing> = this
            .active
            .par_chunks(POINTS_PER_TASK)
            .map(|run| {
                let mut l = Listing::default();
                for &i in run {
                    let (s, e) = (
                        this.adj_start[i as usize] as usize,
                        this.adj_start[i as usize + 1] as usize,
                    );
                    for &id in &this.adj[s..e] {
                        let live = match this.kind(id) {
                            Constraint::Stretch(k) => this.stretch_alive[k as usize],
                            Constraint::Bend(k) => this.bend_alive[k as usize],
                            Constraint::Tie(_) => false,
                        };
                        let points = this.constraint_points(id);
                        // Listed by a lower-numbered awake point?
                        if !live || points.iter().any(|&q| q < i && this.awake[q as usize]) {
                            continue;
                        }
                        let (mut lo, mut hi, mut held) = (u32::MAX, 0, false);
                        for &q in &points {
                            lo = lo.min(q);
                            hi = hi.max(q);
                            let qi = q as usize;
                            held |= any_held && (this.pinned[qi] != 0 || this.kinematic[qi]);
                            if !this.awake[qi] && this.alive[qi] {
                                l.fringe.push(q);
                            }
                        }
                        let (a, b) = (block_of(lo), block_of(hi));
                        let block = if a == b { a } else { BLOCKS as u32 };
                        l.ids.push((id, block | if held { HELD } else { 0 }));
                    }
                }
                l
            })
            .collect();
        // Joined in order: each block's constraints counted, then placed (a stable counting
        // sort); the fringe's points each once.
        let mut start = [0u32; BLOCKS + 2];
        for &(_, b) in runs.iter().flat_map(|l| &l.ids) {
            start[(b & !HELD) as usize + 1] += 1;
        }
        for b in 0..=BLOCKS {
            start[b + 1] += start[b];
        }
        let mut fill = start;
        let total = start[BLOCKS + 1] as usize;
        let mut list = std::mem::take(&mut self.constraints_now);
        list.clear();
        list.resize(total, 0);
        self.held_slots.clear();
        for &(id, b) in runs.iter().flat_map(|l| &l.ids) {
            let slot = &mut fill[(b & !HELD) as usize];
            list[*slot as usize] = id;
            if b & HELD != 0 {
                self.held_slots.push((id, *slot));
            }
            *slot += 1;
        }
        self.constraints_now = list;
        let stamp = self.next_stamp();
        let mut fringe = std::mem::take(&mut self.fringe);
        fringe.clear();
        for &q in runs.iter().flat_map(|l| &l.fringe) {
            if self.stamp[q as usize] != stamp {
                self.stamp[q as usize] = stamp;
                fringe.push(q);
            }
        }
        self.fringe = fringe;
        self.block_points = bounds;
        self.block_start = start;
    }

    /// Projects constraint `id` on the points `x` (the body's points from `offset` on) with
    /// inverse masses `w` (likewise); returns the multiplier's increment.
    fn project_one(
        &self,
        id: u32,
        x: &mut [Vec3],
        w: &[f32],
        offset: u32,
        dt: f32,
        lambda: f32,
    ) -> f32 {
        let p = &self.params;
        match self.kind(id) {
            Constraint::Stretch(k) => {
                let mut c = self.stretch[k as usize];
                c.a -= offset;
                c.b -= offset;
                xpbd::project_stretch(x, w, &c, p.stretch_compliance_m_per_n, dt, lambda)
            }
            Constraint::Bend(k) => {
                let mut c = self.bend[k as usize];
                for q in [&mut c.a, &mut c.b, &mut c.c, &mut c.d] {
                    *q -= offset;
                }
                xpbd::project_bend(x, w, &c, p.bend_compliance_per_n_m, dt, lambda)
            }
            Constraint::Tie(_) => 0.0,
        }
    }

    pub(super) fn project(&mut self, dt: f32) {
        let p = self.params;
        let list = std::mem::take(&mut self.constraints_now);
        // One Lagrange multiplier per listed constraint, from zero each step.
        self.lambda.clear();
        self.lambda.resize(list.len(), 0.0);
        let mut x = std::mem::take(&mut self.x);
        let mut lambda = std::mem::take(&mut self.lambda);
        let (bounds, start) = (self.block_points, self.block_start);
        for _ in 0..p.solver_iterations.max(1) {
            let this = &*self;
            let blocks = split_at_offsets(&mut x, &bounds[1..BLOCKS]);
            let mut lambdas = split_at_offsets(&mut lambda, &start[1..=BLOCKS]);
            let crossing = lambdas.pop().unwrap_or_default();
            blocks
                .into_par_iter()
                .zip(lambdas)
                .enumerate()
                .for_each(|(b, (xb, lb))| {
                    let (lo, hi) = (bounds[b], bounds[b + 1]);
                    let w = &this.inv_mass[lo as usize..hi as usize];
                    let ids = &list[start[b] as usize..start[b + 1] as usize];
                    for (l, &id) in lb.iter_mut().zip(ids) {
                        *l += this.project_one(id, xb, w, lo, dt, *l);
                    }
                });
            let ids = &list[start[BLOCKS] as usize..];
            for (l, &id) in crossing.iter_mut().zip(ids) {
                *l += this.project_one(id, &mut x, &this.inv_mass, 0, dt, *l);
            }
        }
        self.x = x;
        self.lambda = lambda;
        // Keep the multipliers of the constraints on points a tool holds (pinned by a tip or
        // grasped): lambda / dt^2 is the force the constraint exerted on them this step, part
        // of what the tool feels. Sorted by constraint for lookup.
        self.constraint_lambda.clear();
        for &(id, slot) in &self.held_slots {
            self.constraint_lambda
                .push((id, self.lambda[slot as usize]));
        }
        // Sleeping points the constraints moved are woken when moved noticeably, else put
        // back.
        let fringe = std::mem::take(&mut self.fringe);
        for &q in &fringe {
            let q = q as usize;
            if (self.x[q] - self.sleep_at[q]).length() > WAKE_DISTANCE_M {
                self.wake(q);
            } else {
                self.x[q] = self.sleep_at[q];
            }
        }
        self.fringe = fringe;
        self.constraint_lambda.sort_unstable_by_key(|&(id, _)| id);
        self.last_dt_s = dt;
        self.constraints_now = list;
    }
}
