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

impl SoftBody {
    /// Lists the live constraints around the awake points, sorted (stably) into blocks of
    /// point indices cut at quantiles of the awake points, those that cross blocks last.
    /// Also lists, while each constraint's points are at hand, the sleeping points the
    /// projection may move (the fringe) and the constraints on points a tool holds.
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
        let block_of = |q: u32| bounds[1..BLOCKS].iter().filter(|&&e| e <= q).count();
        let any_held = !self.pins.is_empty() || !self.held.is_empty();
        let stamp = self.next_stamp();
        // Walk the awake points in index order (the active list is sorted) and list each live
        // constraint once, with its block: a fixed order whatever the order points woke in.
        let mut listed = std::mem::take(&mut self.block_scratch);
        listed.clear();
        let mut dead = std::mem::take(&mut self.dead_seen);
        let mut fringe = std::mem::take(&mut self.fringe);
        fringe.clear();
        let mut start = [0u32; BLOCKS + 2];
        for &i in &self.active {
            let (s, e) = (
                self.adj_start[i as usize] as usize,
                self.adj_start[i as usize + 1] as usize,
            );
            for &id in &self.adj[s..e] {
                // Seen from another of its points already? (The bit is checked first: the
                // constraint's own data is a cache miss away.)
                let (word, bit) = (id as usize / 64, 1u64 << (id % 64));
                if self.listed[word] & bit != 0 {
                    continue;
                }
                self.listed[word] |= bit;
                let live = match self.kind(id) {
                    Constraint::Stretch(k) => self.stretch_alive[k as usize],
                    Constraint::Bend(k) => self.bend_alive[k as usize],
                    Constraint::Tie(_) => false,
                };
                if !live {
                    dead.push(id);
                    continue;
                }
                let points = self.constraint_points(id);
                let (mut lo, mut hi, mut held) = (u32::MAX, 0, false);
                for &q in &points {
                    lo = lo.min(q);
                    hi = hi.max(q);
                    let qi = q as usize;
                    held |= any_held && (self.pinned[qi] != 0 || self.kinematic[qi]);
                    if !self.awake[qi] && self.alive[qi] && self.stamp[qi] != stamp {
                        self.stamp[qi] = stamp;
                        fringe.push(q);
                    }
                }
                let (a, b) = (block_of(lo), block_of(hi));
                let block = if a == b { a } else { BLOCKS };
                start[block + 1] += 1;
                listed.push(id);
                listed.push(block as u32 | if held { HELD } else { 0 });
            }
        }
        for id in listed
            .chunks_exact(2)
            .map(|pair| pair[0])
            .chain(dead.drain(..))
        {
            self.listed[id as usize / 64] = 0;
        }
        self.dead_seen = dead;
        self.fringe = fringe;
        for b in 0..=BLOCKS {
            start[b + 1] += start[b];
        }
        let mut fill = start;
        self.constraints_now.clear();
        self.constraints_now.resize(listed.len() / 2, 0);
        self.held_slots.clear();
        for pair in listed.chunks_exact(2) {
            let slot = &mut fill[(pair[1] & !HELD) as usize];
            self.constraints_now[*slot as usize] = pair[0];
            if pair[1] & HELD != 0 {
                self.held_slots.push((pair[0], *slot));
            }
            *slot += 1;
        }
        self.block_scratch = listed;
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
