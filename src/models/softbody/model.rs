//! The soft body as a tissue model: step, cut, surface, snapshot, checkpoints and digest.

use super::*;
use crate::sim::Fnv;

impl SoftBody {
    /// Heap bytes held by each part of the body (capacity, not length), for the profiler.
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        fn b<T>(v: &Vec<T>) -> usize {
            v.capacity() * std::mem::size_of::<T>()
        }
        let m = &self.mesh;
        let fans: usize = b(&m.fan_start) + b(&m.fan_faces);
        let render: usize = b(&m.render);
        vec![
            ("mesh.neighbors", b(&m.neighbors)),
            ("mesh.faces", b(&m.faces)),
            ("mesh.fans", fans),
            ("mesh.tri_rest", b(&m.tri_rest)),
            ("mesh.rest", b(&m.rest)),
            ("mesh.render", render),
            ("mesh.corners", b(&m.corners)),
            ("x", b(&self.x)),
            ("v", b(&self.v)),
            ("normal", b(&self.normal)),
            ("area+volume_term+inv_mass+leaf_pad", b(&self.area) * 4),
            (
                "flags",
                b(&self.alive) * 4 + b(&self.region) + b(&self.still),
            ),
            ("stretch", b(&self.stretch) + b(&self.stretch_alive)),
            ("bend", b(&self.bend) + b(&self.bend_alive)),
            ("adj", b(&self.adj_start) + b(&self.adj)),
            ("sleep_at", b(&self.sleep_at)),
            ("groups+parts+component+stamp", b(&self.pressure_group) * 4),
            ("bvh", self.bvh.heap_bytes()),
            ("checkpoint", b(&self.checkpoint)),
            (
                "ext_force+pushed+before",
                b(&self.ext_force) + b(&self.pushed) + b(&self.before),
            ),
            (
                "mass+rest_area+slot+pinned",
                b(&self.mass) + b(&self.rest_area) + b(&self.slot) + b(&self.pinned),
            ),
            (
                "links",
                b(&self.shear_k) + b(&self.tie_start) + b(&self.tie_links),
            ),
            (
                "implicit solve",
                b(&self.unknowns) + self.cg.heap_bytes() + b(&self.constraint_lambda),
            ),
            (
                "constraints_now+blocks",
                b(&self.constraints_now) + b(&self.fringe) + b(&self.held_slots),
            ),
            (
                "normals+relink scratch, drawn normals",
                b(&self.normal_scratch) + b(&self.relink) + self.drawn_normals().heap_bytes(),
            ),
            ("lambda", b(&self.lambda)),
            (
                "lists",
                b(&self.active) + b(&self.touched) + b(&self.moved) + b(&self.bvh_pending),
            ),
        ]
    }
}

impl SoftBody {
    /// Sleep bookkeeping: a point slower than the sleep speed (relative to where its goal
    /// carries it) and holding almost no load for SLEEP_TIME_S sleeps. Whether each awake
    /// point is at rest is read-only work, done in parallel; the bookkeeping is in order.
    fn settle(&mut self, dt: f32) {
        use rayon::prelude::*;
        let v_sleep = self.params.sleep_speed_m_per_s;
        let sleep_steps = (SLEEP_TIME_S / dt).ceil().clamp(1.0, f32::from(u16::MAX)) as u16;
        let mut at_rest = std::mem::take(&mut self.at_rest);
        let this = &*self;
        this.active
            .par_iter()
            .with_min_len(POINTS_PER_TASK)
            .map(|&i| {
                let i = i as usize;
                let unloaded = !this.anchored[i]
                    || (this.x[i] - this.mesh.rest[i]).length() * this.total_k(i) < SLEEP_FORCE_N;
                let slow = (this.v[i] - this.goal_velocity(i, dt)).length() < v_sleep;
                !this.kinematic[i] && slow && unloaded
            })
            .collect_into_vec(&mut at_rest);
        let mut kept = 0;
        for k in 0..self.active.len() {
            let i = self.active[k] as usize;
            self.still[i] = if at_rest[k] {
                self.still[i].saturating_add(1)
            } else {
                0
            };
            if (self.still[i] >= sleep_steps && !self.stay_awake) || !self.alive[i] {
                self.awake[i] = false;
                self.v[i] = Vec3::ZERO;
                if self.anchored[i] {
                    self.x[i] = self.mesh.rest[i];
                }
                self.sleep_at[i] = self.x[i];
                self.still[i] = 0;
                continue;
            }
            self.active[kept] = i as u32;
            kept += 1;
        }
        self.active.truncate(kept);
        self.at_rest = at_rest;
    }
}

/// The render triangles, placed from the simplex points (what rays and the renderer see).
impl TriangleSource for SoftBody {
    fn triangle(&self, f: u32) -> [Vec3; 3] {
        self.mesh.corners[f as usize]
            .map(|r| self.mesh.render_position(r as usize, &self.x, &self.normal))
    }
}

impl TissueModel for SoftBody {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> &'static str {
        "simplex_soft_body"
    }

    fn sizes(&self) -> ModelSizes {
        ModelSizes {
            vertices: self.x.len(),
            triangles: self.mesh.faces.len(),
            constraints: self.stretch.len() + self.bend.len() + self.ties.len(),
        }
    }

    fn step(&mut self, dt: f32, contacts: &[Contact], out: &mut ModelOutput) {
        if self.topology_dirty {
            self.update_topology();
        }
        self.refresh_moduli();
        // Ties are judged where the step starts, before anything moves them.
        self.break_ties(out);
        let p = self.params;
        self.apply_contacts(contacts, out);
        self.match_free_parts();
        // Tips hold the points they touch where the tip's surface is (eq 9's contact as a
        // position constraint): those points are fixed for the solve.
        self.pin_tips(contacts);
        // Normals and areas of every point whose neighbourhood may move (eq 3 needs them).
        self.active.sort_unstable();
        self.active.dedup();
        let stamp = self.next_stamp();
        self.moved.clear();
        for k in 0..self.active.len() {
            let i = self.active[k] as usize;
            for j in std::iter::once(i as u32).chain(self.mesh.neighbors[i]) {
                if self.stamp[j as usize] != stamp {
                    self.stamp[j as usize] = stamp;
                    self.moved.push(j);
                }
            }
        }
        let moved = std::mem::take(&mut self.moved);
        self.refresh_normals(&moved);
        let volumes = self.region_volumes();
        self.pressure_now = volumes
            .iter()
            .zip(&self.rest_volume)
            .map(|(&v, &v0)| forces::volume_pressure(p.volume_stiffness_pa, v0, v))
            .collect();
        // Mass, damping, foundation, shear layer and ties: one implicit step (eqs 1-8).
        self.before.clear();
        for k in 0..self.active.len() {
            let i = self.active[k] as usize;
            self.before.push(self.x[i]);
            if self.kinematic[i] || !self.alive[i] {
                self.v[i] = Vec3::ZERO;
            }
        }
        self.merge_ext_forces();
        self.solve_implicit(dt);
        self.ext_force.clear();
        // Constraints (Algorithm 2) with the pinned points fixed, then the tips again for
        // points the constraints carried into them.
        for &(i, _) in &self.pins {
            self.inv_mass[i as usize] = 0.0;
        }
        self.collect_constraints();
        let n_active = self.active.len();
        self.project(dt);
        self.push_out_of_tips(contacts);
        for &(i, _) in &self.pins {
            let i = i as usize;
            if !self.kinematic[i] && self.alive[i] && self.mass[i] > 0.0 {
                self.inv_mass[i] = 1.0 / self.mass[i];
            }
        }
        // What each tool feels: everything the tissue does to the points it holds.
        self.tool_reactions(out);
        // Velocities from the positions; points moved by neighbours wake up. A tip's push
        // moves tissue and stops it moving into the tip (an inelastic contact), but adds no
        // speed of its own.
        self.pushed.sort_unstable_by_key(|&(q, _)| q);
        for k in 0..n_active {
            let i = self.active[k] as usize;
            if self.alive[i] && !self.kinematic[i] {
                let push = if self.pushed.is_empty() {
                    Vec3::ZERO
                } else {
                    self.pushed
                        .binary_search_by_key(&(i as u32), |&(q, _)| q)
                        .map_or(Vec3::ZERO, |p| self.pushed[p].1)
                };
                let mut v = (self.x[i] - push - self.before[k]) / dt;
                let n = push.normalize_or_zero();
                v -= n * v.dot(n).min(0.0);
                self.v[i] = v;
            }
        }
        self.pushed.clear();
        for &(i, _) in &self.pins {
            self.pinned[i as usize] = 0;
        }
        self.wake_loaded_neighbours();
        self.settle(dt);
        // Refit the BVH where anything moved.
        let stamp3 = self.next_stamp();
        let mut leaves = std::mem::take(&mut self.touched);
        let pending = std::mem::take(&mut self.bvh_pending);
        for &i in moved.iter().chain(self.active.iter()).chain(pending.iter()) {
            if self.stamp[i as usize] != stamp3 {
                self.stamp[i as usize] = stamp3;
                leaves.push(i);
            }
        }
        for &i in &leaves {
            self.bvh.mark(i);
        }
        leaves.clear();
        self.touched = leaves;
        self.bvh_pending = pending;
        self.bvh_pending.clear();
        let (x, pad, nb, alive) = (&self.x, &self.leaf_pad, &self.mesh.neighbors, &self.alive);
        self.bvh
            .refresh(|f| alive[f].then(|| leaf_aabb(x, pad, nb, f)), BVH_MARGIN_M);
        self.moved = moved;
    }

    fn cut(&mut self, stroke: &CutStroke, out: &mut ModelOutput) {
        let mut severed = 0u32;
        let mut removed = Vec::new();
        for &f in &stroke.faces {
            let i = f as usize;
            if i >= self.alive.len() || !self.alive[i] {
                continue;
            }
            removed.push(f);
            self.relink.push(f);
            self.relink.extend(self.mesh.neighbors[i]);
            self.alive[i] = false;
            self.inv_mass[i] = 0.0;
            self.pinned[i] = 0;
            if let Some(v) = self.volume.get_mut(self.pressure_group[i] as usize) {
                *v -= self.volume_term[i] as f64;
            }
            self.volume_term[i] = 0.0;
            self.bvh.remove_face(f);
            let (s, e) = (self.adj_start[i] as usize, self.adj_start[i + 1] as usize);
            for k in s..e {
                match self.kind(self.adj[k]) {
                    Constraint::Stretch(c) => self.stretch_alive[c as usize] = false,
                    Constraint::Bend(c) => self.bend_alive[c as usize] = false,
                    Constraint::Tie(c) => {
                        if self.ties[c as usize].alive {
                            self.ties[c as usize].alive = false;
                            severed += 1;
                        }
                    }
                }
            }
            for n in self.mesh.neighbors[i] {
                self.wake(n as usize);
            }
        }
        if !removed.is_empty() {
            self.topology_dirty = true;
            // Ray casts read the render triangles, so they change with the cut itself, never
            // with whoever happens to take a snapshot.
            self.rebuild_render_runs(&removed);
        }
        if severed > 0 {
            out.events.push(EventKind::TiesSevered {
                model: self.name.clone(),
                count: severed,
            });
        }
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        SoftBody::memory(self)
    }

    fn awake_fraction(&self) -> f32 {
        self.active.len() as f32 / self.x.len().max(1) as f32
    }

    fn stay_awake(&mut self) {
        self.stay_awake = true;
        for i in 0..self.x.len() {
            self.wake(i);
        }
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        let i = i as usize;
        (i < self.x.len() && self.alive[i]).then(|| self.x[i])
    }

    fn apply_point_forces(&mut self, forces: &[(u32, Vec3)]) {
        for &(i, f) in forces {
            let i = i as usize;
            // A force too small to move a point by a rounding step does not wake it: a resting
            // attachment must not keep its points awake.
            if i >= self.x.len() || !self.alive[i] || !f.is_finite() || f.length() < 1e-9 {
                continue;
            }
            self.wake(i);
            self.ext_force.push((i as u32, f));
        }
    }

    fn collider(&self) -> Collider<'_> {
        Collider::Mesh(MeshSurface {
            triangles: self,
            points: &self.x,
            alive: &self.alive,
            regions: &self.region,
            bvh: &self.bvh,
        })
    }

    /// The surface now, its points' normals (found again only where points moved since the
    /// last snapshot: `drawn.rs`) and the drawn vertices found in parallel (each value
    /// written once: the threads change no bit).
    fn render_mesh(&mut self) -> ModelSnapshot {
        let mut kept = self.drawn_normals();
        drawn::surface(
            &drawn::Drawn {
                name: &self.name,
                mesh: &self.mesh,
                x: &self.x,
                alive: &self.alive,
                regions: &self.region,
                sear_cuts: self.sear_cuts,
            },
            &mut kept,
        )
    }

    /// The snapshot's mesh, its points and their life copied now and the rest built by the
    /// job ([`drawn::surface`], as [`TissueModel::render_mesh`] builds it). The mesh is
    /// shared: a cut while a job holds it copies it first.
    fn render_job(&mut self) -> crate::sim::MeshJob {
        let name = self.name.clone();
        let mesh = Arc::clone(&self.mesh);
        let (x, alive, regions) = (self.x.clone(), self.alive.clone(), self.region.clone());
        let kept = Arc::clone(&self.drawn);
        let sear_cuts = self.sear_cuts;
        crate::sim::MeshJob::later(move || {
            let mut kept = kept
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            drawn::surface(
                &drawn::Drawn {
                    name: &name,
                    mesh: &mesh,
                    x: &x,
                    alive: &alive,
                    regions: &regions,
                    sear_cuts,
                },
                &mut kept,
            )
        })
    }

    /// Keeps the positions only: a restored body is put to sleep where it was, at rest.
    fn checkpoint(&mut self) {
        self.checkpoint.clone_from(&self.x);
    }

    fn restore(&mut self) {
        self.x.clone_from(&self.checkpoint);
        self.v.fill(Vec3::ZERO);
        self.sleep_at.clone_from(&self.x);
        for i in 0..self.x.len() {
            self.refresh_normal(i);
        }
        self.resum_volumes();
        self.active.clear();
        self.awake.fill(false);
    }

    fn state_is_finite(&self) -> bool {
        self.moved
            .iter()
            .chain(self.active.iter())
            .all(|&i| self.x[i as usize].is_finite() && self.v[i as usize].is_finite())
    }

    /// The first point moved to NaN and woken.
    fn inject_nan(&mut self) -> bool {
        if self.x.is_empty() {
            return false;
        }
        self.set_position(0, Vec3::NAN);
        true
    }

    fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        for (x, v) in self.x.iter().zip(&self.v) {
            for c in x.to_array().into_iter().chain(v.to_array()) {
                h.write(c.to_bits());
            }
        }
        for (i, a) in self.alive.iter().enumerate() {
            if !a {
                h.write(i as u32);
            }
        }
        h.0
    }
}
