//! What tools do to the body: the spring pull a tip feels, presses, rigid tips and grasping jaws.

use super::*;

impl SoftBody {
    /// The spring force (eq 2) pulling point `i` to its goal: its rest position, or for a
    /// piece cut free, its rest position carried by the piece's motion. Zero for a free point
    /// of no piece.
    pub(super) fn spring_pull(&self, i: usize) -> Vec3 {
        let k = self.params.spring_n_per_m;
        if self.anchored[i] {
            forces::spring_force(k, self.x[i], self.mesh.rest[i])
        } else if let Some(part) = self.free_parts.get(self.part_of[i] as usize) {
            let goal = part.rotation * self.mesh.rest[i] + part.translation;
            forces::spring_force(k, self.x[i], goal)
        } else {
            Vec3::ZERO
        }
    }

    pub(super) fn next_stamp(&mut self) -> u32 {
        self.stamp_now = self.stamp_now.wrapping_add(1);
        if self.stamp_now == 0 {
            self.stamp.fill(0);
            self.stamp_now = 1;
        }
        self.stamp_now
    }

    pub(super) fn apply_contacts(&mut self, contacts: &[Contact], out: &mut ModelOutput) {
        let p = self.params;
        let mut seen = [false; 2];
        for c in contacts {
            seen[c.tool.index()] = true;
            match c.kind {
                ContactKind::Press {
                    pressure_pa,
                    area_m2,
                } => {
                    let pressed = pressure_pa * area_m2;
                    let from = forces::offset_point(c.point, c.normal, p.offset_m);
                    // Beyond 2 falloff lengths the force is under a fifth of the peak: ignored.
                    let reach = 2.0 * p.falloff_m;
                    let q = Aabb::new(from - Vec3::splat(reach), from + Vec3::splat(reach));
                    let found: Vec<u32> = self.bvh.faces_in(&q).collect();
                    let mut total = Vec3::ZERO;
                    for f in found {
                        let i = f as usize;
                        if !self.alive[i] || (self.x[i] - from).length() > reach {
                            continue;
                        }
                        self.wake(i);
                        self.refresh_normal(i);
                        let cf = forces::contact_force(
                            self.x[i],
                            self.normal[i],
                            from,
                            pressed,
                            p.falloff_m,
                        );
                        self.force[i] += cf.pressure + cf.offset;
                        total += cf.pressure + cf.offset;
                        self.touched.push(i as u32);
                    }
                    out.reactions.push((c.tool, -total));
                }
                ContactKind::Sphere { radius_m } => {
                    let q = Aabb::new(
                        c.point - Vec3::splat(radius_m * 2.0),
                        c.point + Vec3::splat(radius_m * 2.0),
                    );
                    let found: Vec<u32> = self.bvh.faces_in(&q).collect();
                    for f in found {
                        if (self.x[f as usize] - c.point).length() < radius_m * 1.5 {
                            self.wake(f as usize);
                        }
                    }
                }
                ContactKind::Grasp { rotation, radius_m } => {
                    if let Some(h) = self.held.iter_mut().find(|h| h.tool == c.tool) {
                        h.rotation = rotation;
                        let (rot, pts) = (h.rotation, h.points.clone());
                        // The held tissue pulls the jaws back toward its rest (eq 2's springs;
                        // nothing once the piece is cut free and carried).
                        let mut pull = Vec3::ZERO;
                        for (i, local) in pts {
                            let target = c.point + rot * local;
                            let i = i as usize;
                            self.wake(i);
                            self.x[i] = target;
                            pull += self.spring_pull(i);
                        }
                        out.reactions.push((c.tool, pull));
                        continue;
                    }
                    let q = Aabb::new(
                        c.point - Vec3::splat(radius_m),
                        c.point + Vec3::splat(radius_m),
                    );
                    let mut found: Vec<(f32, u32)> = self
                        .bvh
                        .faces_in(&q)
                        .filter(|&f| self.alive[f as usize])
                        .map(|f| ((self.x[f as usize] - c.point).length(), f))
                        .filter(|&(d, _)| d <= radius_m)
                        .collect();
                    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                    found.truncate(24);
                    if found.is_empty() {
                        continue;
                    }
                    let inv = rotation.inverse();
                    let points: Vec<(u32, Vec3)> = found
                        .iter()
                        .map(|&(_, f)| (f, inv * (self.x[f as usize] - c.point)))
                        .collect();
                    for &(f, _) in &points {
                        self.kinematic[f as usize] = true;
                        self.inv_mass[f as usize] = 0.0;
                        self.wake(f as usize);
                    }
                    out.events.push(EventKind::Grasp {
                        tool: c.tool.name().to_string(),
                        model: self.name.clone(),
                        vertices: points.len() as u32,
                    });
                    self.held.push(Held {
                        tool: c.tool,
                        points,
                        rotation,
                    });
                }
            }
        }
        // Release grasps whose tool sent no grasp this step.
        let mut k = 0;
        while k < self.held.len() {
            let tool = self.held[k].tool;
            let still = contacts
                .iter()
                .any(|c| c.tool == tool && matches!(c.kind, ContactKind::Grasp { .. }));
            if still {
                k += 1;
                continue;
            }
            let h = self.held.remove(k);
            for (i, _) in h.points {
                self.kinematic[i as usize] = false;
                self.inv_mass[i as usize] = if self.alive[i as usize] { 1.0 } else { 0.0 };
                self.wake(i as usize);
            }
            out.events.push(EventKind::Release {
                tool: tool.name().to_string(),
            });
        }
        for h in 0..2 {
            if seen[h] && !self.contacting[h] {
                out.events.push(EventKind::Contact {
                    tool: ToolId::BOTH[h].name().to_string(),
                    model: self.name.clone(),
                });
            }
            self.contacting[h] = seen[h];
        }
    }
}
