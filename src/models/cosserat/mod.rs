//! A Cosserat rod (the rectum paper's appendix A, eqs 7-13): a centreline of nodes with a frame
//! of directors on each element between them. The third director follows the centreline at
//! rest; the element's strain `gamma = R^T (x_{e+1} - x_e) / l0 - e3` measures shear (first two
//! components) and stretch (third); the curvature between two elements, `kappa = log(R_k^T
//! R_{k+1}) / D0`, measures bending (first two: the flexures kappa_1, kappa_2 of eq 8) and
//! torsion (third: tau). The energy is eq 11 with a shear term beside the stretch one:
//!
//!   U = sum_e 1/2 l0 (gamma - gamma0)^T S (gamma - gamma0)
//!     + sum_k 1/2 D0 (kappa - kappa0)^T B (kappa - kappa0),
//!
//! `S = diag(ks G A, ks G A, E A)`, `B = diag(E I1, E I2, G J)`, the rest values those of the
//! rod as built; eq 12's dissipation `1/2 gamma_d |d kappa / dt|^2` per unit length damps the
//! curvature rates. The kinetic energy is the centreline's (eq 10) plus the elements' small
//! rotational part (which the paper drops; kept here, it makes the frames' motion well posed).
//!
//! Time stepping is backward Euler, solved by Newton's method on the incremental potential
//! (eq 13's `M q'' + C q' + K q = R`, linearised each iteration) with a Gauss-Newton Hessian:
//! one 6 x 6 block per node and its element (position, rotation increment), block
//! tridiagonal, solved in O(n) (see [`blocks`]). The step is unconditionally stable, so a stiff
//! rod runs at the step its scene needs; the static equilibrium it settles to does not depend
//! on the step. SI units throughout; f64.

mod blocks;
pub mod reference;
pub mod skin;
pub mod skinned;
pub mod so3;
mod step;
#[cfg(test)]
mod tests;

use glam::{DMat3, DVec3};

/// The rod's material and section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodParams {
    /// Young's modulus E, Pa.
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio: the shear modulus is G = E / (2 (1 + nu)).
    pub poisson_ratio: f64,
    pub density_kg_per_m3: f64,
    /// Outer radius of the circular section, m.
    pub radius_m: f64,
    /// Wall thickness, m, for a tube; none for a solid section.
    pub wall_m: Option<f64>,
    /// Drag on the centreline's motion, 1/s (force -c m v).
    pub damping_per_s: f64,
    /// Eq 12's gamma: dissipation per unit length of the curvature rates, N m^2 s.
    pub curvature_damping_n_m2_s: f64,
    /// Gravity, m/s^2.
    pub gravity: DVec3,
}

impl RodParams {
    /// Shear modulus G, Pa.
    pub fn shear_modulus_pa(&self) -> f64 {
        self.youngs_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))
    }

    /// Section area A, second moment I (each bending axis) and polar moment J, SI.
    pub fn section(&self) -> (f64, f64, f64) {
        let ro = self.radius_m;
        let ri = self.wall_m.map_or(0.0, |w| (ro - w).max(0.0));
        let area = std::f64::consts::PI * (ro * ro - ri * ri);
        let i = std::f64::consts::FRAC_PI_4 * (ro.powi(4) - ri.powi(4));
        (area, i, 2.0 * i)
    }

    /// Timoshenko's shear coefficient: 6 (1 + nu) / (7 + 6 nu) for a solid circle, and
    /// 2 (1 + nu) / (4 + 3 nu) for a thin-walled tube.
    pub fn shear_coefficient(&self) -> f64 {
        let nu = self.poisson_ratio;
        match self.wall_m {
            Some(w) if w < 0.5 * self.radius_m => 2.0 * (1.0 + nu) / (4.0 + 3.0 * nu),
            _ => 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu),
        }
    }

    /// Shear-stretch stiffness `S` (ks G A, ks G A, E A), N.
    pub fn stretch_stiffness(&self) -> DVec3 {
        let (a, _, _) = self.section();
        let sg = self.shear_coefficient() * self.shear_modulus_pa() * a;
        DVec3::new(sg, sg, self.youngs_modulus_pa * a)
    }

    /// Bend-twist stiffness `B` (E I, E I, G J), N m^2.
    pub fn bend_stiffness(&self) -> DVec3 {
        let (_, i, j) = self.section();
        let e = self.youngs_modulus_pa;
        DVec3::new(e * i, e * i, self.shear_modulus_pa() * j)
    }
}

/// A fixed frame joined to an end element (see [`CosseratRod::fix_node`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Clamp {
    element: usize,
    frame: DMat3,
    /// The clamp comes before the element along the rod (the first node), else after it.
    before: bool,
}

impl Clamp {
    /// The joint's rotation vector (rad) and its derivative with respect to a rotation of the
    /// element's frame (world), over the joint's length `d0`.
    fn joint(&self, r: DMat3) -> (DVec3, DMat3) {
        if self.before {
            let phi = so3::log(self.frame.transpose() * r);
            (phi, so3::jl_inv(phi) * self.frame.transpose())
        } else {
            let phi = so3::log(r.transpose() * self.frame);
            (phi, -(so3::jl_inv(phi) * r.transpose()))
        }
    }
}

/// How a step's Newton iteration went.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepStats {
    pub iterations: u32,
    /// The largest position update of the last iteration, m.
    pub last_update_m: f64,
}

/// A Cosserat rod of `n` elements between `n + 1` nodes.
#[derive(Debug, Clone)]
pub struct CosseratRod {
    pub params: RodParams,
    /// Node positions and velocities, m and m/s.
    x: Vec<DVec3>,
    v: Vec<DVec3>,
    /// Element frames (columns d1, d2, d3: material to world) and angular velocities (world).
    frames: Vec<DMat3>,
    omega: Vec<DVec3>,
    rest_len: Vec<f64>,
    /// Rest length between element centres (one fewer than elements).
    voronoi: Vec<f64>,
    rest_strain: Vec<DVec3>,
    rest_curvature: Vec<DVec3>,
    mass: Vec<f64>,
    /// Element rotational inertia in its material frame, kg m^2.
    inertia: Vec<DVec3>,
    stretch_k: DVec3,
    bend_k: DVec3,
    fixed_node: Vec<bool>,
    fixed_frame: Vec<bool>,
    /// Clamps: a fixed frame joined to an end element by a bending joint half that element
    /// long, so the rod bends from the clamp itself, not from the end element's far node.
    clamps: Vec<Clamp>,
    /// Forces on nodes and torques on elements (world) for the next step, N and N m
    /// (cleared after it).
    force: Vec<DVec3>,
    torque: Vec<DVec3>,
    /// The given forces' stiffness per node for the next step, N/m (cleared after it): see
    /// [`CosseratRod::add_node_stiffness`].
    given_k: Vec<f64>,
    /// Newton: stop when the largest update is below this, m (rotations: per metre of
    /// element).
    pub tolerance_m: f64,
    pub max_iterations: u32,
    scratch: step::Scratch,
}

impl CosseratRod {
    /// A rod along the polyline `points` (at least two, none repeated), at rest as built; the
    /// first director of the first element is `d1` made normal to the centreline, and each
    /// next element's frame is the previous one carried along by the smallest rotation
    /// (parallel transport), so the rod is untwisted at rest.
    pub fn along(points: &[DVec3], d1: DVec3, params: RodParams) -> CosseratRod {
        let n = points.len().saturating_sub(1).max(1);
        let mut frames = Vec::with_capacity(n);
        let mut prev: Option<DMat3> = None;
        for e in 0..n {
            let a = points[e.min(points.len() - 1)];
            let b = points.get(e + 1).copied().unwrap_or(a + DVec3::Z);
            let t = (b - a).normalize_or(DVec3::Z);
            let r = match prev {
                None => {
                    let d1 = (d1 - t * d1.dot(t)).normalize_or(t.any_orthonormal_vector());
                    DMat3::from_cols(d1, t.cross(d1), t)
                }
                Some(p) => {
                    let axis = p.z_axis.cross(t);
                    let angle = axis.length().atan2(p.z_axis.dot(t));
                    let q = so3::exp(axis.normalize_or_zero() * angle);
                    so3::orthonormalise(q * p)
                }
            };
            frames.push(r);
            prev = Some(r);
        }
        let x: Vec<DVec3> = if points.len() >= 2 {
            points.to_vec()
        } else {
            vec![points.first().copied().unwrap_or(DVec3::ZERO); 2]
        };
        let rest_len: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).length()).collect();
        let voronoi: Vec<f64> = rest_len.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        let (area, i, j) = params.section();
        let rho = params.density_kg_per_m3;
        let mut mass = vec![0.0; n + 1];
        for (e, l) in rest_len.iter().enumerate() {
            mass[e] += 0.5 * rho * area * l;
            mass[e + 1] += 0.5 * rho * area * l;
        }
        let inertia = rest_len
            .iter()
            .map(|l| DVec3::new(i, i, j) * (rho * l))
            .collect();
        let mut rod = CosseratRod {
            params,
            v: vec![DVec3::ZERO; n + 1],
            omega: vec![DVec3::ZERO; n],
            rest_strain: vec![DVec3::ZERO; n],
            rest_curvature: vec![DVec3::ZERO; n.saturating_sub(1)],
            mass,
            inertia,
            stretch_k: params.stretch_stiffness(),
            bend_k: params.bend_stiffness(),
            fixed_node: vec![false; n + 1],
            fixed_frame: vec![false; n],
            clamps: Vec::new(),
            force: vec![DVec3::ZERO; n + 1],
            torque: vec![DVec3::ZERO; n],
            given_k: vec![0.0; n + 1],
            tolerance_m: 1e-10,
            max_iterations: 12,
            scratch: step::Scratch::default(),
            x,
            frames,
            rest_len,
            voronoi,
        };
        for e in 0..n {
            rod.rest_strain[e] = rod.strain(e);
        }
        for k in 0..n.saturating_sub(1) {
            rod.rest_curvature[k] = rod.curvature(k);
        }
        rod
    }

    /// A straight rod of `n` elements and `length` from `origin` along `direction`.
    pub fn straight(
        n: usize,
        length: f64,
        origin: DVec3,
        direction: DVec3,
        params: RodParams,
    ) -> CosseratRod {
        let d = direction.normalize_or(DVec3::X);
        let n = n.max(1);
        let points: Vec<DVec3> = (0..=n)
            .map(|i| origin + d * (length * i as f64 / n as f64))
            .collect();
        CosseratRod::along(&points, d.any_orthonormal_vector(), params)
    }

    pub fn elements(&self) -> usize {
        self.frames.len()
    }

    pub fn positions(&self) -> &[DVec3] {
        &self.x
    }

    pub fn velocities(&self) -> &[DVec3] {
        &self.v
    }

    pub fn frames(&self) -> &[DMat3] {
        &self.frames
    }

    pub fn masses(&self) -> &[f64] {
        &self.mass
    }

    /// Holds node `i` where it is; with `clamped`, an end node also keeps the rod's direction
    /// and twist there (a clamp: the end element is joined to a fixed frame at the node).
    pub fn fix_node(&mut self, i: usize, clamped: bool) {
        if let Some(f) = self.fixed_node.get_mut(i) {
            *f = true;
            self.v[i] = DVec3::ZERO;
        }
        let n = self.frames.len();
        if clamped && (i == 0 || i == n) {
            let element = if i == 0 { 0 } else { n - 1 };
            self.clamps.push(Clamp {
                element,
                frame: self.frames[element],
                before: i == 0,
            });
        }
    }

    /// Holds element `e`'s frame where it is (it still moves with its nodes' positions only
    /// through shear).
    pub fn fix_frame(&mut self, e: usize) {
        if let Some(f) = self.fixed_frame.get_mut(e) {
            *f = true;
            self.omega[e] = DVec3::ZERO;
        }
    }

    /// Adds a force on node `i` for the next step, N.
    pub fn add_force(&mut self, i: usize, f: DVec3) {
        if let Some(slot) = self.force.get_mut(i)
            && f.is_finite()
        {
            *slot += f;
        }
    }

    /// Says that the force given on node `i` for the next step falls by `k` (N/m) for every
    /// metre the node moves during it, as a spring's does (another model's tissue holding
    /// the rod): the step takes `f_i - k (x_i - x_i(start))` implicitly, so a stiff given load
    /// cannot ring against the step's lag. A negative or non-finite `k` is ignored.
    pub fn add_node_stiffness(&mut self, i: usize, k: f64) {
        if let Some(slot) = self.given_k.get_mut(i)
            && k.is_finite()
            && k > 0.0
        {
            *slot += k;
        }
    }

    /// Adds a torque (world frame) on element `e` for the next step, N m.
    pub fn add_torque(&mut self, e: usize, t: DVec3) {
        if let Some(slot) = self.torque.get_mut(e)
            && t.is_finite()
        {
            *slot += t;
        }
    }

    /// Element `e`'s strain: shear (x, y) and stretch (z) in its material frame.
    pub fn strain(&self, e: usize) -> DVec3 {
        step::strain(&self.x, &self.frames, &self.rest_len, e)
    }

    /// The curvature between elements `k` and `k + 1` in `k`'s material frame, 1/m.
    pub fn curvature(&self, k: usize) -> DVec3 {
        step::curvature(&self.frames, &self.voronoi, k)
    }

    /// Elastic energy (eq 11 with shear), J.
    pub fn elastic_energy(&self) -> f64 {
        let mut u = 0.0;
        for e in 0..self.elements() {
            let d = self.strain(e) - self.rest_strain[e];
            u += 0.5 * self.rest_len[e] * (d * d).dot(self.stretch_k);
        }
        for k in 0..self.voronoi.len() {
            let d = self.curvature(k) - self.rest_curvature[k];
            u += 0.5 * self.voronoi[k] * (d * d).dot(self.bend_k);
        }
        for c in &self.clamps {
            let d0 = 0.5 * self.rest_len[c.element];
            let kappa = c.joint(self.frames[c.element]).0 / d0;
            u += 0.5 * d0 * (kappa * kappa).dot(self.bend_k);
        }
        u
    }

    /// Kinetic energy: the centreline's and the elements' rotation, J.
    pub fn kinetic_energy(&self) -> f64 {
        let lin: f64 = self
            .x
            .iter()
            .zip(&self.v)
            .zip(&self.mass)
            .map(|((_, v), m)| 0.5 * m * v.length_squared())
            .sum();
        let rot: f64 = self
            .frames
            .iter()
            .zip(&self.omega)
            .zip(&self.inertia)
            .map(|((r, w), i)| {
                let wm = r.transpose() * *w;
                0.5 * (wm * wm).dot(*i)
            })
            .sum();
        lin + rot
    }

    /// Gravity's potential energy, J (zero at the origin's height).
    pub fn gravity_energy(&self) -> f64 {
        -self
            .x
            .iter()
            .zip(&self.mass)
            .map(|(x, m)| m * self.params.gravity.dot(*x))
            .sum::<f64>()
    }

    /// One backward-Euler step of `dt_s`.
    pub fn step(&mut self, dt_s: f64) -> StepStats {
        step::step(self, dt_s)
    }

    /// Whether every position, velocity and frame is finite.
    /// Puts a NaN into the middle node's velocity, where the next step meets it (fault
    /// injection: a failing solve would leave one); false for a rod with no free node.
    pub fn inject_nan(&mut self) -> bool {
        let mid = self.v.len() / 2;
        match self.v.get_mut(mid) {
            Some(v) if mid > 0 && mid + 1 < self.x.len() => {
                v.x = f64::NAN;
                true
            }
            _ => false,
        }
    }

    pub fn is_finite(&self) -> bool {
        self.x
            .iter()
            .chain(&self.v)
            .chain(&self.omega)
            .all(|p| p.is_finite())
            && self.frames.iter().all(|r| r.is_finite())
    }

    /// A digest of the state's bits.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        let mut put = |c: f64| {
            let b = c.to_bits();
            h.write(b as u32);
            h.write((b >> 32) as u32);
        };
        for p in self.x.iter().chain(&self.v).chain(&self.omega) {
            p.to_array().into_iter().for_each(&mut put);
        }
        for r in &self.frames {
            r.to_cols_array().into_iter().for_each(&mut put);
        }
        h.0
    }
}
