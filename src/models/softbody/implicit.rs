//! The implicit part of a step. Each point carries a real mass (its area's share of its part's
//! enclosed mass) and is held to its goal (its rest position, or for a piece cut free, its
//! rest position carried by the piece) by an elastic foundation: a Winkler spring per unit
//! area (eq 2's spring, weighted by area) and a Pasternak shear layer that couples
//! neighbouring points' displacements (Kerr, "Elastic and viscoelastic foundation models",
//! 1964). Ties between regions are linear springs on the two ends' displacements. Mass,
//! damping, foundation, shear layer and ties are integrated together by backward Euler,
//!
//!   (M (1 + c dt) + dt^2 K) v' = M v + dt (f - K u),
//!
//! solved by a Jacobi-preconditioned conjugate gradient over the awake points to a relative
//! tolerance or a floor on the force left unbalanced (not a fixed count), so the result depends neither on dt's stability limit nor on
//! an iteration setting, and a static load reaches the exact equilibrium K u = f. Every
//! stiffness is per unit area or per unit length of shared edge, so totals do not change with
//! the mesh's resolution.

use super::*;
use cg::RowsMut;
use rayon::prelude::*;

/// The fewest rows of the implicit step one parallel task assembles.
const ROWS_PER_TASK: usize = 1024;

/// CG stops once every component's residual is below this fraction of its right-hand side
const CG_TOLERANCE: f32 = 1e-4;
/// ... or once the force left unbalanced averages (RMS over the unknowns) below this, N: the
/// weight of 0.1 mg, a ten-thousandth of the smallest force the instruments render (0.01 N). A
/// relative goal alone chases rounding when the right-hand side is small (a body at rest).
const CG_FORCE_FLOOR_N: f32 = 1e-6;
/// ... or after this many iterations.
const CG_MAX_ITERATIONS: usize = 500;
/// Enclosed volume over area (m) for a part that encloses none (an open sheet): its mass is
/// that of a layer this thick.
const OPEN_THICKNESS_M: f32 = 0.002;

/// A spring between two points' displacements: a shear-layer link or a tie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Link {
    pub to: u32,
    /// N/m.
    pub k: f32,
}

impl SoftBody {
    /// Each point's rest area (its face's) and mass: its area's share of the mass of the
    /// volume its connected part of the surface encloses at rest (density x volume x area /
    /// part area). Masses are the uncut body's: cutting removes points, not density.
    pub(super) fn compute_masses(&mut self) {
        let n = self.x.len();
        self.rest_area = (0..n).map(|f| self.rest_face_area(f)).collect();
        self.max_rest_area = self.rest_area.iter().fold(0.0f32, |a, &b| a.max(b));
        // Connected parts of the surface at rest (flood fill over the simplex neighbours),
        // each with the volume it encloses (divergence theorem) and its area.
        let mut part = vec![NO_GROUP; n];
        let mut volume: Vec<f64> = Vec::new();
        let mut area: Vec<f64> = Vec::new();
        let mut stack = Vec::new();
        let rest = &self.mesh.rest;
        let all = vec![true; n];
        for seed in 0..n {
            if part[seed] != NO_GROUP {
                continue;
            }
            let id = volume.len() as u32;
            let (mut v, mut a) = (0.0f64, 0.0f64);
            part[seed] = id;
            stack.push(seed);
            while let Some(i) = stack.pop() {
                let (nn, ai) = self.mesh.normal_area(rest, &all, i);
                v += (rest[i].dot(nn) * ai / 3.0) as f64;
                a += self.rest_area[i] as f64;
                for &j in &self.mesh.neighbors[i] {
                    if part[j as usize] == NO_GROUP {
                        part[j as usize] = id;
                        stack.push(j as usize);
                    }
                }
            }
            volume.push(v);
            area.push(a);
        }
        let rho = self.params.density_kg_per_m3;
        self.mass = (0..n)
            .map(|i| {
                let g = part[i] as usize;
                let thickness = if volume[g] > 0.0 && area[g] > 0.0 {
                    (volume[g] / area[g]) as f32
                } else {
                    OPEN_THICKNESS_M
                };
                rho * thickness * self.rest_area[i]
            })
            .collect();
        for i in 0..n {
            self.inv_mass[i] = if self.alive[i] && !self.kinematic[i] && self.mass[i] > 0.0 {
                1.0 / self.mass[i]
            } else {
                0.0
            };
        }
    }

    /// Rebuilds masses and links when the density or a modulus they depend on was changed.
    pub(super) fn refresh_moduli(&mut self) {
        let p = &self.params;
        let now = [
            p.density_kg_per_m3,
            p.shear_layer_n_per_m,
            p.tie_stiffness_pa_per_m,
        ];
        if now != self.link_params {
            self.compute_masses();
            self.rebuild_links();
        }
    }

    /// Total mass of the body's live points, kg.
    pub fn total_mass_kg(&self) -> f64 {
        (0..self.x.len())
            .filter(|&i| self.alive[i])
            .map(|i| self.mass[i] as f64)
            .sum()
    }

    /// The shear-layer links between live neighbours and the live ties, per point (CSR).
    pub(super) fn rebuild_links(&mut self) {
        let n = self.x.len();
        let mut shear = std::mem::take(&mut self.shear_k);
        shear.clear();
        shear.extend((0..n).map(|i| self.shear_row(i)));
        self.shear_k = shear;
        self.rebuild_tie_links();
        self.link_params = [
            self.params.density_kg_per_m3,
            self.params.shear_layer_n_per_m,
            self.params.tie_stiffness_pa_per_m,
        ];
        self.relink.clear();
    }

    /// After cuts: the shear links of the points around the removed faces only (the others
    /// are unchanged), and the ties.
    pub(super) fn refresh_links(&mut self) {
        let mut relink = std::mem::take(&mut self.relink);
        relink.sort_unstable();
        relink.dedup();
        for &i in &relink {
            self.shear_k[i as usize] = self.shear_row(i as usize);
        }
        relink.clear();
        self.relink = relink;
        self.rebuild_tie_links();
    }

    /// Point `i`'s shear-layer stiffness to each neighbour slot (zero where there is no
    /// link). A link across the edge shared by faces i and j has the shear modulus times the
    /// edge's length over the distance between the two points (the finite-volume flux across
    /// it).
    fn shear_row(&self, i: usize) -> [f32; 3] {
        let g = self.params.shear_layer_n_per_m;
        let mut ks = [0.0f32; 3];
        if !self.alive[i] {
            return ks;
        }
        let fi = self.mesh.faces[i];
        for (slot, &j) in self.mesh.neighbors[i].iter().enumerate() {
            let j = j as usize;
            if !self.alive[j] || j == i {
                continue;
            }
            // The edge faces i and j share.
            let fj = self.mesh.faces[j];
            let mut shared = fi.iter().filter(|v| fj.contains(v));
            let (Some(&a), Some(&b)) = (shared.next(), shared.next()) else {
                continue;
            };
            let edge = self.mesh.tri_rest[a as usize] - self.mesh.tri_rest[b as usize];
            let d = (self.mesh.rest[i] - self.mesh.rest[j]).length();
            if d > 1e-9 {
                ks[slot] = g * edge.length() / d;
            }
        }
        ks
    }

    /// Each live tie end's partners (CSR).
    fn rebuild_tie_links(&mut self) {
        let n = self.x.len();
        let tie_k = self.params.tie_stiffness_pa_per_m;
        let mut tie_start = std::mem::take(&mut self.tie_start);
        tie_start.clear();
        tie_start.resize(n + 1, 0);
        let live_tie = |t: &Tie| {
            let (a, b) = (t.a as usize, t.b as usize);
            t.alive && self.alive[a] && self.alive[b] && a != b
        };
        for t in self.ties.iter().filter(|t| live_tie(t)) {
            tie_start[t.a as usize + 1] += 1;
            tie_start[t.b as usize + 1] += 1;
        }
        for i in 0..n {
            tie_start[i + 1] += tie_start[i];
        }
        let mut fill = tie_start.clone();
        let mut tie_links = std::mem::take(&mut self.tie_links);
        tie_links.clear();
        tie_links.resize(tie_start[n] as usize, Link { to: 0, k: 0.0 });
        for t in self.ties.iter().filter(|t| live_tie(t)) {
            let k = tie_k * self.rest_area[t.a as usize];
            for (from, to) in [(t.a, t.b), (t.b, t.a)] {
                let slot = &mut fill[from as usize];
                tie_links[*slot as usize] = Link { to, k };
                *slot += 1;
            }
        }
        self.tie_start = tie_start;
        self.tie_links = tie_links;
    }

    /// The shear-layer links and ties of point `i` (a missing shear link has k = 0 and adds
    /// nothing to any sum).
    #[inline]
    pub(super) fn links_of(&self, i: usize) -> impl Iterator<Item = Link> + '_ {
        let shear = self.mesh.neighbors[i]
            .iter()
            .zip(self.shear_k[i])
            .map(|(&to, k)| Link { to, k });
        let (s, e) = (self.tie_start[i] as usize, self.tie_start[i + 1] as usize);
        shear.chain(self.tie_links[s..e].iter().copied())
    }

    /// Where point `i` is held: its rest position, or for a piece cut free, its rest position
    /// carried by the piece's motion. None for a dead point.
    #[inline]
    pub(super) fn goal(&self, i: usize) -> Option<Vec3> {
        if !self.alive[i] {
            None
        } else if self.anchored[i] {
            Some(self.mesh.rest[i])
        } else {
            self.free_parts
                .get(self.part_of[i] as usize)
                .map(|p| p.rotation * self.mesh.rest[i] + p.translation)
        }
    }

    /// Displacement of point `i` from its goal (zero for a point without one).
    #[inline]
    pub(super) fn displacement(&self, i: usize) -> Vec3 {
        self.goal(i).map_or(Vec3::ZERO, |g| self.x[i] - g)
    }

    /// The foundation's stiffness at point `i`, N/m.
    #[inline]
    pub(super) fn foundation_k(&self, i: usize) -> f32 {
        if self.goal(i).is_some() {
            self.params.foundation_pa_per_m * self.rest_area[i]
        } else {
            0.0
        }
    }

    /// The stiffness holding point `i` where it is: its foundation and all its links, N/m.
    #[inline]
    pub(super) fn total_k(&self, i: usize) -> f32 {
        self.foundation_k(i) + self.links_of(i).map(|l| l.k).sum::<f32>()
    }

    /// The elastic foundation's and ties' force on point `i` where everything is now, N.
    #[inline]
    pub(super) fn link_force(&self, i: usize) -> Vec3 {
        let u = self.displacement(i);
        let mut f = u * -self.foundation_k(i);
        for l in self.links_of(i) {
            f += (self.displacement(l.to as usize) - u) * l.k;
        }
        f
    }

    /// How fast point `i`'s goal moves, m/s: zero when anchored, the carrying piece's rigid
    /// motion over the last step for a piece cut free.
    #[inline]
    pub(super) fn goal_velocity(&self, i: usize, dt: f32) -> Vec3 {
        if self.anchored[i] || !self.alive[i] || dt <= 0.0 {
            return Vec3::ZERO;
        }
        self.free_parts
            .get(self.part_of[i] as usize)
            .map_or(Vec3::ZERO, |p| {
                let r = self.mesh.rest[i];
                let now = p.rotation * r + p.translation;
                let before = p.prev_rotation * r + p.prev_translation;
                (now - before) / dt
            })
    }

    /// Everything the tissue does to point `i` where it is now: foundation, shear layer, ties,
    /// internal pressure, and the forces the stretch and bending constraints exerted in the
    /// last projection (their multipliers over dt^2). A tool holding the point in place feels
    /// exactly this.
    pub(super) fn tissue_force(&self, i: usize) -> Vec3 {
        let mut f = self.link_force(i);
        if let Some(&pg) = self.pressure_now.get(self.pressure_group[i] as usize) {
            f += forces::pressure_force(pg, self.normal[i], self.area[i]);
        }
        let (s, e) = (self.adj_start[i] as usize, self.adj_start[i + 1] as usize);
        for &id in &self.adj[s..e] {
            let lambda = self
                .constraint_lambda
                .binary_search_by_key(&id, |&(c, _)| c)
                .map_or(0.0, |k| self.constraint_lambda[k].1);
            if lambda == 0.0 || self.last_dt_s <= 0.0 {
                continue;
            }
            let scale = lambda / (self.last_dt_s * self.last_dt_s);
            match self.kind(id) {
                Constraint::Stretch(k) => {
                    let c = &self.stretch[k as usize];
                    let d = self.x[c.a as usize] - self.x[c.b as usize];
                    let n = d.normalize_or_zero() * scale;
                    f += if c.a as usize == i { n } else { -n };
                }
                Constraint::Bend(k) => {
                    let c = &self.bend[k as usize];
                    if let Some((_, g)) = xpbd::bend_gradient(&self.x, c) {
                        for (q, gq) in [c.a, c.b, c.c, c.d].into_iter().zip(g) {
                            if q as usize == i {
                                f += gq * scale;
                            }
                        }
                    }
                }
                Constraint::Tie(_) => {}
            }
        }
        f
    }

    /// Sorts the external forces by point and sums each point's, in the order they were
    /// applied (a stable sort keeps it), one entry a point.
    pub(super) fn merge_ext_forces(&mut self) {
        let ext = &mut self.ext_force;
        ext.sort_by_key(|e| e.0);
        let mut kept = 0;
        for k in 0..ext.len() {
            let (point, f) = ext[k];
            if kept > 0 && ext[kept - 1].0 == point {
                ext[kept - 1].1 += f;
            } else {
                ext[kept] = ext[k];
                kept += 1;
            }
        }
        ext.truncate(kept);
    }

    /// Point `i`'s couplings to other unknowns: (their slot, the link's stiffness).
    #[inline]
    fn couplings(&self, i: usize) -> impl Iterator<Item = (u32, f32)> + '_ {
        self.links_of(i)
            .filter(|l| l.k != 0.0)
            .map(|l| (self.slot[l.to as usize], l.k))
            .filter(|&(j, _)| j != NO_GROUP)
    }

    /// Point `i`'s row of the implicit step, row `k` of `run` (its couplings from `at` on):
    /// its diagonal, its couplings, its right-hand side (momentum plus the step's impulse of
    /// the external, foundation, link and pressure forces) and its last velocity as the
    /// starting guess.
    fn assemble_row(&self, i: usize, dt: f32, run: &mut RowsMut, k: usize, at: &mut usize) {
        let dt2 = dt * dt;
        let fk = self.foundation_k(i);
        let u = self.displacement(i);
        let ext = self
            .ext_force
            .binary_search_by_key(&(i as u32), |e| e.0)
            .map_or(Vec3::ZERO, |k| self.ext_force[k].1);
        let mut f = ext - u * fk;
        let mut ksum = 0.0;
        for l in self.links_of(i).filter(|l| l.k != 0.0) {
            ksum += l.k;
            f += (self.displacement(l.to as usize) - u) * l.k;
        }
        for (j, lk) in self.couplings(i) {
            run.col[*at] = j;
            run.w[*at] = dt2 * lk;
            *at += 1;
        }
        if let Some(&pg) = self.pressure_now.get(self.pressure_group[i] as usize) {
            f += forces::pressure_force(pg, self.normal[i], self.area[i]);
        }
        run.diag[k] = self.mass[i] * (1.0 + self.params.damping_per_s * dt) + dt2 * (fk + ksum);
        run.b[k] = (self.v[i] * self.mass[i] + f * dt).into();
        run.x[k] = self.v[i].into();
    }

    /// One backward-Euler step of mass, damping, foundation, shear layer and ties for the
    /// awake points that are free to move (pinned and held points stay where they are, as do
    /// sleeping ones), with the external forces in `self.ext_force` and the internal pressure.
    /// Moves the points and sets their velocities. Returns the CG iterations it took.
    pub(super) fn solve_implicit(&mut self, dt: f32) -> usize {
        // The unknowns: awake, alive, not held by a grasp or pinned by a tip.
        self.unknowns.clear();
        for &i in &self.active {
            let i = i as usize;
            if self.alive[i] && !self.kinematic[i] && self.pinned[i] == 0 {
                self.slot[i] = self.unknowns.len() as u32;
                self.unknowns.push(i as u32);
            }
        }
        // A = M (1 + c dt) + dt^2 (foundation + links) on the diagonal, minus dt^2 times the
        // links between unknowns off it; a link to a point that stays put is a known force.
        // The system is shaped from each row's count of couplings, then runs of rows are
        // filled in parallel, each in place.
        let mut sys = std::mem::take(&mut self.cg);
        let this = &*self;
        let mut counts = std::mem::take(&mut sys.counts);
        this.unknowns
            .par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|&i| this.couplings(i as usize).count() as u32)
            .collect_into_vec(&mut counts);
        sys.shape(&counts);
        sys.counts = counts;
        this.unknowns
            .par_chunks(ROWS_PER_TASK)
            .zip(sys.runs_mut(ROWS_PER_TASK))
            .for_each(|(rows, mut run)| {
                let mut at = 0;
                for (k, &i) in rows.iter().enumerate() {
                    this.assemble_row(i as usize, dt, &mut run, k, &mut at);
                }
            });
        let iterations = sys.solve(CG_TOLERANCE, dt * CG_FORCE_FLOOR_N, CG_MAX_ITERATIONS);
        let sol = std::mem::take(&mut sys.x);
        for (k, &i) in self.unknowns.iter().enumerate() {
            let i = i as usize;
            self.v[i] = sol[k].into();
            self.x[i] += self.v[i] * dt;
            self.slot[i] = NO_GROUP;
        }
        sys.x = sol;
        self.cg = sys;
        iterations
    }
}
