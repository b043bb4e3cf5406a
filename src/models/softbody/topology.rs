//! Connectivity after cuts: components, anchored and free pieces (carried rigidly by their
//! fitted motion), and the pressure groups each closed piece keeps.

use super::*;
use rayon::prelude::*;

impl SoftBody {
    /// Recomputes connected parts over live springs and ties; the largest part of the anchor
    /// region keeps its anchor springs, every other part floats free.
    pub(super) fn update_topology(&mut self) {
        let n = self.x.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(p: &mut [u32], mut i: u32) -> u32 {
            while p[i as usize] != i {
                p[i as usize] = p[p[i as usize] as usize];
                i = p[i as usize];
            }
            i
        }
        let union = |p: &mut Vec<u32>, a: u32, b: u32| {
            let (ra, rb) = (find(p, a), find(p, b));
            if ra != rb {
                let (lo, hi) = (ra.min(rb), ra.max(rb));
                p[hi as usize] = lo;
            }
        };
        for (k, s) in self.stretch.iter().enumerate() {
            if self.stretch_alive[k] {
                union(&mut parent, s.a, s.b);
            }
        }
        for t in &self.ties {
            if t.alive {
                union(&mut parent, t.a, t.b);
            }
        }
        let mut count = vec![0u32; n];
        for i in 0..n {
            let r = find(&mut parent, i as u32);
            self.component[i] = r;
            if self.alive[i] && self.region[i] == self.anchor_region {
                count[r as usize] += 1;
            }
        }
        // The part holding most of the anchor region; none if that region has no live point.
        let main = (0..n)
            .max_by_key(|&r| (count[r], std::cmp::Reverse(r)))
            .filter(|&r| count[r] > 0)
            .map_or(u32::MAX, |r| r as u32);
        for i in 0..n {
            let anchored = self.alive[i] && self.component[i] == main;
            if self.anchored[i] && !anchored {
                self.wake(i);
            }
            self.anchored[i] = anchored;
        }
        self.regroup_free_parts();
        self.regroup_pressure();
        self.refresh_links();
        self.topology_dirty = false;
    }

    /// Lists the live parts that float free (not anchored), in order of their first point.
    pub(super) fn regroup_free_parts(&mut self) {
        let n = self.x.len();
        let mut parts: Vec<FreePart> = Vec::new();
        let mut by_component: Vec<(u32, u32)> = Vec::new();
        self.part_of.fill(NO_GROUP);
        for i in 0..n {
            if !self.alive[i] || self.anchored[i] {
                continue;
            }
            let c = self.component[i];
            let k = match by_component.binary_search_by(|e| e.0.cmp(&c)) {
                Ok(k) => by_component[k].1,
                Err(k) => {
                    let id = parts.len() as u32;
                    by_component.insert(k, (c, id));
                    parts.push(FreePart::default());
                    id
                }
            };
            parts[k as usize].points.push(i as u32);
            self.part_of[i] = k;
        }
        for part in &mut parts {
            let rest = &self.mesh.rest;
            let count = part.points.len().max(1) as f32;
            let centre = part.points.iter().map(|&i| rest[i as usize]).sum::<Vec3>() / count;
            part.radius_m = part
                .points
                .iter()
                .map(|&i| (rest[i as usize] - centre).length())
                .fold(0.0, f32::max);
            let (q, t) = self.fit_part(part);
            (part.rotation, part.translation) = (q, t);
            (part.prev_rotation, part.prev_translation) = (q, t);
        }
        self.free_parts = parts;
    }

    /// The best rigid motion of a free piece from rest (Mueller et al.'s 2005 shape matching),
    /// as x = rotation * rest + translation: fitted to the held points when a grasper holds
    /// three or more of them (the instrument carries the piece), else to all its points.
    pub(super) fn fit_part(&self, part: &FreePart) -> (Quat, Vec3) {
        let rest = &self.mesh.rest;
        let held: Vec<u32> = part
            .points
            .iter()
            .copied()
            .filter(|&i| self.kinematic[i as usize])
            .collect();
        let fit: &[u32] = if held.len() >= 3 { &held } else { &part.points };
        let count = fit.len().max(1) as f32;
        let c: Vec3 = fit.iter().map(|&i| self.x[i as usize]).sum::<Vec3>() / count;
        let c0: Vec3 = fit.iter().map(|&i| rest[i as usize]).sum::<Vec3>() / count;
        let mut a = glam::Mat3::ZERO;
        for &i in fit {
            let (p, q) = (self.x[i as usize] - c, rest[i as usize] - c0);
            a += glam::Mat3::from_cols(p * q.x, p * q.y, p * q.z);
        }
        let q = extract_rotation(a, part.rotation);
        (q, c - q * c0)
    }

    /// Moves each free piece's spring goals with the piece's fitted motion, so a cut-out
    /// specimen keeps its shape and follows the grasper instead of stretching out of its
    /// jaws. Sleeping points of the piece ride along rigidly (they stay asleep; only points
    /// disturbed relative to the piece wake), which keeps a carried specimen cheap.
    pub(super) fn match_free_parts(&mut self) {
        for part in &mut self.free_parts {
            part.prev_rotation = part.rotation;
            part.prev_translation = part.translation;
        }
        for k in 0..self.free_parts.len() {
            let part = &self.free_parts[k];
            let busy = part
                .points
                .iter()
                .any(|&i| self.awake[i as usize] || self.kinematic[i as usize]);
            if !busy {
                continue;
            }
            let (q, t) = self.fit_part(part);
            let (q0, t0) = (part.rotation, part.translation);
            let radius = part.radius_m;
            let change = (t - t0).length() + q.angle_between(q0) * radius;
            if change <= 1e-9 {
                continue;
            }
            let delta = q * q0.inverse();
            // Leaves are padded by the BVH margin: refresh the piece's leaves only when it has
            // moved half of that since they were last fitted.
            let drift = self.free_parts[k].bvh_drift_m + change;
            let refit = drift > 0.5 * BVH_MARGIN_M;
            self.free_parts[k].bvh_drift_m = if refit { 0.0 } else { drift };
            let points = std::mem::take(&mut self.free_parts[k].points);
            for &i in &points {
                let i = i as usize;
                if !self.awake[i] {
                    // Rigidly carried: position, normal and volume term move with the piece.
                    let carried = delta * (self.x[i] - t0) + t;
                    self.x[i] = carried;
                    self.sleep_at[i] = carried;
                    self.normal[i] = delta * self.normal[i];
                    let term = if self.alive[i] {
                        carried.dot(self.normal[i]) * self.area[i] / 3.0
                    } else {
                        0.0
                    };
                    if let Some(v) = self.volume.get_mut(self.pressure_group[i] as usize) {
                        *v += (term - self.volume_term[i]) as f64;
                    }
                    self.volume_term[i] = term;
                }
                if refit {
                    self.bvh_pending.push(i as u32);
                }
            }
            let part = &mut self.free_parts[k];
            part.points = points;
            part.rotation = q;
            part.translation = t;
        }
    }

    /// Sorts the points into pressure groups: one per connected part (the regions of one
    /// surface share its gas: a region alone is an open patch whose "volume" depends on the
    /// origin). A closed part encloses a volume whatever its pose; an open part (cut) only
    /// while it is anchored in place, so a cut-free open piece gets no internal pressure (its
    /// "volume" would change as it moves, pumping energy into it). Rest volumes are taken over
    /// what is left, at rest, so the pressure starts from zero.
    pub(super) fn regroup_pressure(&mut self) {
        let n = self.x.len();
        // Groups are numbered in the order their parts first appear; a part is named by its
        // component (a point index).
        let mut group_of_part = vec![NO_GROUP; n];
        let mut closed: Vec<bool> = Vec::new();
        let mut anchored: Vec<bool> = Vec::new();
        let mut group = vec![NO_GROUP; n];
        for i in 0..n {
            if !self.alive[i] {
                continue;
            }
            let part = &mut group_of_part[self.component[i] as usize];
            if *part == NO_GROUP {
                *part = closed.len() as u32;
                closed.push(true);
                anchored.push(false);
            }
            let g = *part;
            group[i] = g;
            let g = g as usize;
            anchored[g] |= self.anchored[i];
            closed[g] &= self.mesh.neighbors[i]
                .iter()
                .all(|&q| self.alive[q as usize]);
        }
        for g in &mut group {
            if *g != NO_GROUP && !(closed[*g as usize] || anchored[*g as usize]) {
                *g = NO_GROUP;
            }
        }
        // Each point's term of its group's rest volume (in parallel), summed in point order.
        let (mesh, alive) = (&self.mesh, &self.alive);
        let terms: Vec<f32> = (0..n)
            .into_par_iter()
            .with_min_len(POINTS_PER_TASK)
            .map(|i| {
                if group[i] == NO_GROUP {
                    return 0.0;
                }
                let (nn, a) = mesh.normal_area(&mesh.rest, alive, i);
                mesh.rest[i].dot(nn) * a / 3.0
            })
            .collect();
        let mut rest_volume = vec![0.0f32; closed.len()];
        for (g, t) in group.iter().zip(terms) {
            if *g != NO_GROUP {
                rest_volume[*g as usize] += t;
            }
        }
        self.pressure_group = group;
        self.rest_volume = rest_volume;
        // Volume terms are current; the sums start again over the new groups.
        self.volume.clear();
    }
}
