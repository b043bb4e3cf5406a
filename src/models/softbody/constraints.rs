//! The XPBD constraints (stretch, bending, ties) gathered around awake points and projected.

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
                    Constraint::Tie(k) => self.ties[k as usize].alive,
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

    pub(super) fn project(&mut self, dt: f32, out: &mut ModelOutput) {
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
                    Constraint::Tie(k) => {
                        let t = self.ties[k as usize];
                        xpbd::project_stretch(
                            &mut self.x,
                            &self.inv_mass,
                            &Stretch {
                                a: t.a,
                                b: t.b,
                                rest_m: t.rest_m,
                            },
                            p.tie_compliance_m_per_n,
                            dt,
                            l,
                        )
                    }
                };
                self.lambda[li] = l + dl;
            }
        }
        // Ties whose force exceeds the threshold tear.
        for (li, &id) in list.iter().enumerate() {
            if let Constraint::Tie(k) = self.kind(id) {
                let force = self.lambda[li].abs() / (dt * dt);
                if force > p.tie_break_force_n {
                    self.ties[k as usize].alive = false;
                    self.topology_dirty = true;
                    out.events.push(EventKind::TieBroken {
                        model: self.name.clone(),
                        force_n: force,
                    });
                }
            }
        }
        self.constraints_now = list;
    }
}
