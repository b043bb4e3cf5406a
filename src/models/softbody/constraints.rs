//! The XPBD constraints (stretch and bending, eqs 11-12) gathered around awake points and
//! projected with the points' masses. Ties are springs of the implicit step, not constraints.

use super::*;

impl SoftBody {
    pub(super) fn collect_constraints(&mut self) {
        self.constraints_now.clear();
        // Walk the awake points in index order (the active list is sorted) and list each live
        // constraint once: a fixed order whatever the order points woke in.
        for &i in &self.active {
            let (s, e) = (
                self.adj_start[i as usize] as usize,
                self.adj_start[i as usize + 1] as usize,
            );
            for &id in &self.adj[s..e] {
                let live = match self.kind(id) {
                    Constraint::Stretch(k) => self.stretch_alive[k as usize],
                    Constraint::Bend(k) => self.bend_alive[k as usize],
                    Constraint::Tie(_) => false,
                };
                let (word, bit) = (id as usize / 64, 1u64 << (id % 64));
                if live && self.listed[word] & bit == 0 {
                    self.listed[word] |= bit;
                    self.constraints_now.push(id);
                }
            }
        }
        for &id in &self.constraints_now {
            self.listed[id as usize / 64] = 0;
        }
    }

    pub(super) fn project(&mut self, dt: f32) {
        let p = self.params;
        let list = std::mem::take(&mut self.constraints_now);
        // One Lagrange multiplier per listed constraint, from zero each step.
        self.lambda.clear();
        self.lambda.resize(list.len(), 0.0);
        for _ in 0..p.solver_iterations.max(1) {
            for (li, &id) in list.iter().enumerate() {
                let l = self.lambda[li];
                let dl = match self.kind(id) {
                    Constraint::Stretch(k) => xpbd::project_stretch(
                        &mut self.x,
                        &self.inv_mass,
                        &self.stretch[k as usize],
                        p.stretch_compliance_m_per_n,
                        dt,
                        l,
                    ),
                    Constraint::Bend(k) => xpbd::project_bend(
                        &mut self.x,
                        &self.inv_mass,
                        &self.bend[k as usize],
                        p.bend_compliance_per_n_m,
                        dt,
                        l,
                    ),
                    Constraint::Tie(_) => 0.0,
                };
                self.lambda[li] = l + dl;
            }
        }
        // Keep the multipliers of the constraints on points a tool holds (pinned by a tip or
        // grasped): lambda / dt^2 is the force the constraint exerted on them this step, part
        // of what the tool feels. Sorted by constraint for lookup.
        self.constraint_lambda.clear();
        for (li, &id) in list.iter().enumerate() {
            let held = |q: u32| self.pinned[q as usize] != 0 || self.kinematic[q as usize];
            if matches!(self.kind(id), Constraint::Tie(_)) {
                continue;
            }
            if self.constraint_points(id).into_iter().any(held) {
                self.constraint_lambda.push((id, self.lambda[li]));
            }
        }
        self.constraint_lambda.sort_unstable_by_key(|&(id, _)| id);
        self.last_dt_s = dt;
        // Sleeping points the constraints moved: woken when moved noticeably, else put back.
        let stamp = self.next_stamp();
        for &id in &list {
            for q in self.constraint_points(id) {
                let q = q as usize;
                if !self.awake[q] && self.stamp[q] != stamp && self.alive[q] {
                    self.stamp[q] = stamp;
                    if (self.x[q] - self.sleep_at[q]).length() > WAKE_DISTANCE_M {
                        self.wake(q);
                    } else {
                        self.x[q] = self.sleep_at[q];
                    }
                }
            }
        }
        self.constraints_now = list;
    }
}
