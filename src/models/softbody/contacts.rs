//! What tools do to the body: the spring pull a tip feels, presses, rigid tips and grasping jaws.

use super::*;

impl SoftBody {
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
                    // The tool presses with P A in all (eq 4). It is shared among the points
                    // near the contact by area, weighted by eq 6's falloff from the offset
                    // point, so the total is the tool's whatever the mesh's resolution.
                    let pressed = pressure_pa * area_m2;
                    let from = forces::offset_point(c.point, c.normal, p.offset_m);
                    // Beyond 2 falloff lengths the force is under a fifth of the peak: ignored.
                    let reach = 2.0 * p.falloff_m;
                    let q = Aabb::new(from - Vec3::splat(reach), from + Vec3::splat(reach));
                    let found: Vec<u32> = self.bvh.faces_in(&q).collect();
                    let mut share: Vec<(usize, Vec3, f32)> = Vec::new();
                    for f in found {
                        let i = f as usize;
                        let d = self.x[i] - from;
                        let dist = d.length();
                        if !self.alive[i] || dist > reach {
                            continue;
                        }
                        let dir = if dist > f32::EPSILON {
                            d / dist
                        } else {
                            -c.normal
                        };
                        let w = self.rest_area[i] * forces::falloff(1.0, dist, p.falloff_m);
                        share.push((i, dir, w));
                    }
                    let sum: f32 = share.iter().map(|s| s.2).sum();
                    let mut total = Vec3::ZERO;
                    if sum > 0.0 {
                        for (i, dir, w) in share {
                            self.wake(i);
                            let f = dir * (pressed * w / sum);
                            self.ext_force.push((i as u32, f));
                            total += f;
                        }
                    }
                    out.reactions.push((c.tool, -total));
                }
                ContactKind::Sphere { .. } | ContactKind::Capsule { .. } => {
                    let Some((radius_m, found)) = self.near_tip(c) else {
                        continue;
                    };
                    for f in found {
                        let x = self.x[f as usize];
                        if (x - tip_centre(c, x).0).length() < radius_m * 1.5 {
                            self.wake(f as usize);
                        }
                    }
                }
                ContactKind::Grasp { rotation, radius_m } => {
                    if let Some(h) = self.held.iter_mut().find(|h| h.tool == c.tool) {
                        h.rotation = rotation;
                        let (rot, pts) = (h.rotation, h.points.clone());
                        // The jaws carry the held points; what the tissue does to them is
                        // summed for the tool at the end of the step.
                        for (i, local) in pts {
                            let target = c.point + rot * local;
                            let i = i as usize;
                            self.wake(i);
                            self.x[i] = target;
                        }
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
                let (i, m) = (i as usize, self.mass[i as usize]);
                self.inv_mass[i] = if self.alive[i] && m > 0.0 {
                    1.0 / m
                } else {
                    0.0
                };
                let i = i as u32;
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

/// A point within this fraction of a tip's radius of its surface counts as on it.
const PIN_BAND: f32 = 1e-3;

/// The centre of the part of a rigid tip nearest `x`: a sphere's centre, or the nearest point
/// of a capsule's axis; and whether that is the working end (where the tip tents the surface).
fn tip_centre(c: &Contact, x: Vec3) -> (Vec3, bool) {
    match c.kind {
        ContactKind::Capsule { back, .. } => {
            let axis = c.point - back;
            let len2 = axis.length_squared();
            let t = if len2 > 0.0 {
                ((x - back).dot(axis) / len2).clamp(0.0, 1.0)
            } else {
                1.0
            };
            (back + axis * t, t >= 1.0)
        }
        _ => (c.point, true),
    }
}

/// Where a point at `x` inside a tip goes: from the working end as [`out_of_tip`] says, from
/// a shaft straight out from its axis.
fn out_of(c: &Contact, x: Vec3, radius_m: f32) -> Vec3 {
    let (centre, end) = tip_centre(c, x);
    let d = x - centre;
    if end {
        return out_of_tip(d, -c.normal, radius_m);
    }
    let len = d.length();
    let dir = if len > 1e-9 { d / len } else { -c.normal };
    dir * (radius_m - len)
}

/// Where a point inside a tip goes: a point ahead of the tip's centre goes on ahead of it (to
/// the sphere, along the way the tool points), so the tip tents the surface like a probe;
/// pushed straight out from the centre, the points in front would slide aside and let the
/// tip through between them. A point behind the centre is pushed straight out.
fn out_of_tip(d: Vec3, ahead: Vec3, radius_m: f32) -> Vec3 {
    let len = d.length();
    let along = d.dot(ahead);
    if along >= 0.0 {
        let t = (along * along + radius_m * radius_m - len * len).sqrt() - along;
        ahead * t
    } else {
        let dir = if len > 1e-9 { d / len } else { ahead };
        dir * (radius_m - len)
    }
}

impl SoftBody {
    fn pin(&mut self, i: usize, tool: ToolId) {
        if self.pinned[i] == 0 {
            self.pinned[i] = tool.index() as u8 + 1;
            self.pins.push((i as u32, tool));
        }
        self.wake(i);
    }

    fn push_tip(&mut self, i: usize, corr: Vec3) {
        self.x[i] += corr;
        // Few points are pushed a step (those at the tips): a short list, not an array.
        match self.pushed.iter_mut().find(|(q, _)| *q as usize == i) {
            Some((_, d)) => *d += corr,
            None => self.pushed.push((i as u32, corr)),
        }
    }

    /// A rigid tip's radius and the points within twice it (by the BVH's boxes); none for
    /// another kind of contact.
    fn near_tip(&self, c: &Contact) -> Option<(f32, Vec<u32>)> {
        let (radius_m, back) = match c.kind {
            ContactKind::Sphere { radius_m } => (radius_m, c.point),
            ContactKind::Capsule { back, radius_m } => (radius_m, back),
            _ => return None,
        };
        let reach = Vec3::splat(radius_m * 2.0);
        let q = Aabb::new(c.point.min(back) - reach, c.point.max(back) + reach);
        Some((radius_m, self.bvh.faces_in(&q).collect()))
    }

    /// Pins the points each tip touches for this step: points inside it are moved onto its
    /// surface; points on its surface stay held while the tissue still presses on the tip
    /// (a point the tissue pulls away is let go).
    pub(super) fn pin_tips(&mut self, contacts: &[Contact]) {
        self.pins.clear();
        for c in contacts {
            let Some((radius_m, found)) = self.near_tip(c) else {
                continue;
            };
            for f in found {
                let i = f as usize;
                if !self.alive[i] || self.kinematic[i] {
                    continue;
                }
                let d = self.x[i] - tip_centre(c, self.x[i]).0;
                let len = d.length();
                // On the surface (within the band, either side of it, as rounding leaves a
                // point that was put there), a point stays held only while the tissue presses
                // it on the tip; a tip never pulls tissue.
                let on_surface = (len - radius_m).abs() < radius_m * PIN_BAND;
                if on_surface && self.link_force(i).dot(d) >= 0.0 {
                    continue;
                }
                if len < radius_m {
                    self.push_tip(i, out_of(c, self.x[i], radius_m));
                    self.pin(i, c.tool);
                } else if on_surface {
                    self.pin(i, c.tool);
                }
            }
        }
    }

    /// Moves onto each tip's surface the points the constraints carried into it; they count
    /// as held by the tip this step.
    pub(super) fn push_out_of_tips(&mut self, contacts: &[Contact]) {
        for c in contacts {
            let Some((radius_m, found)) = self.near_tip(c) else {
                continue;
            };
            for f in found {
                let i = f as usize;
                let d = self.x[i] - tip_centre(c, self.x[i]).0;
                if self.alive[i] && !self.kinematic[i] && d.length() < radius_m {
                    self.push_tip(i, out_of(c, self.x[i], radius_m));
                    self.pin(i, c.tool);
                }
            }
        }
    }

    /// Each tool's reaction: the sum of everything the tissue does to the points its tip
    /// holds and its jaws carry (equal and opposite to what the tool does to them).
    pub(super) fn tool_reactions(&mut self, out: &mut ModelOutput) {
        let mut sum = [Vec3::ZERO; 2];
        let mut any = [false; 2];
        for &(i, tool) in &self.pins {
            sum[tool.index()] += self.tissue_force(i as usize);
            any[tool.index()] = true;
        }
        for h in &self.held {
            for &(i, _) in &h.points {
                if self.alive[i as usize] {
                    sum[h.tool.index()] += self.tissue_force(i as usize);
                }
            }
            any[h.tool.index()] = true;
        }
        for t in ToolId::BOTH {
            if any[t.index()] {
                out.reactions.push((t, sum[t.index()]));
            }
        }
    }

    /// Ties whose force over their area exceeds the tie strength tear.
    pub(super) fn break_ties(&mut self, out: &mut ModelOutput) {
        let (k, strength) = (
            self.params.tie_stiffness_pa_per_m,
            self.params.tie_strength_pa,
        );
        for t in 0..self.ties.len() {
            let tie = self.ties[t];
            if !tie.alive {
                continue;
            }
            let (a, b) = (tie.a as usize, tie.b as usize);
            if !(self.awake[a] || self.awake[b]) {
                continue;
            }
            let area = self.rest_area[a];
            let force = k * area * (self.displacement(a) - self.displacement(b)).length();
            if force > strength * area {
                self.ties[t].alive = false;
                self.topology_dirty = true;
                out.events.push(EventKind::TieBroken {
                    model: self.name.clone(),
                    force_n: force,
                });
            }
        }
    }

    /// Wakes the sleeping neighbours of awake points that their links now load by more than
    /// twice the force a point may sleep under.
    /// Wakes the sleeping points that their awake neighbours or the gas pressure load
    /// noticeably. The tests only read, so they run in parallel; the waking is in order.
    pub(super) fn wake_loaded_neighbours(&mut self) {
        use rayon::prelude::*;
        let this = &*self;
        let asleep = |j: usize| !this.awake[j] && this.alive[j];
        let mut wake: Vec<u32> = this
            .active
            .par_chunks(POINTS_PER_TASK)
            .flat_map_iter(|chunk| {
                chunk.iter().flat_map(move |&i| {
                    this.links_of(i as usize).map(|l| l.to).filter(move |&j| {
                        let j = j as usize;
                        asleep(j) && this.link_force(j).length() > 2.0 * SLEEP_FORCE_N
                    })
                })
            })
            .collect();
        // The gas pressure pushes on sleeping points too: wake those it loads noticeably. (A
        // pressure that could not load even a point stretched to four times the largest rest
        // area past that skips the scan of every point.)
        let reach = 4.0 * this.max_rest_area;
        let loud = |p: &f32| p.abs() * reach > 2.0 * SLEEP_FORCE_N;
        if this.pressure_now.iter().any(loud) {
            let loaded = |j: &u32| {
                let j = *j as usize;
                asleep(j)
                    && this
                        .pressure_now
                        .get(this.pressure_group[j] as usize)
                        .is_some_and(|pg| pg.abs() * this.area[j] > 2.0 * SLEEP_FORCE_N)
            };
            let pressed: Vec<u32> = (0..this.x.len() as u32)
                .into_par_iter()
                .with_min_len(POINTS_PER_TASK)
                .filter(loaded)
                .collect();
            wake.extend(pressed);
        }
        for j in wake {
            self.wake(j as usize);
        }
    }
}
