//! The catheter paper's skeleton-spring model (its eqs 1-7): balls with mass and radius joined
//! by damped linear springs (`F_a = -(F_k + F_c)`, `F_k = -k_a dl`, `F_c = -c dl/dt`) and by
//! angle springs whose torque `tau = k_t alpha` acts on each arm's far ball as `F_t = tau /
//! lambda` (eq 4), perpendicular to the arm. Both the catheter and the vessel wall are made of
//! it ([`catheter`], [`vessel`]); the balls collide as spheres ([`collision`]) with the
//! paper's contact force (eqs 8-10, [`contact`]); the catheter's tip bends actively along an
//! arc of constant curvature (eqs 11-16, [`bending`]).
//!
//! Integration is semi-implicit Euler (velocities first, then positions), in f64, every loop
//! in index order: the same bytes on any number of threads.

pub mod bending;
pub mod catheter;
pub mod collision;
pub mod contact;
pub mod guidewire;
pub mod in_vessel;
pub mod model;
pub mod surface;
pub mod tree;
pub mod vessel;
pub mod wall;

use glam::DVec3;

/// Balls: where they are, how fast they move, their mass and radius, which are held still,
/// and the force gathered on each this step.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Balls {
    pub x: Vec<DVec3>,
    pub v: Vec<DVec3>,
    pub mass_kg: Vec<f64>,
    pub radius_m: Vec<f64>,
    pub fixed: Vec<bool>,
    pub f: Vec<DVec3>,
}

impl Balls {
    /// Adds a free ball at rest.
    pub fn push(&mut self, x: DVec3, mass_kg: f64, radius_m: f64) -> u32 {
        self.x.push(x);
        self.v.push(DVec3::ZERO);
        self.mass_kg.push(mass_kg);
        self.radius_m.push(radius_m);
        self.fixed.push(false);
        self.f.push(DVec3::ZERO);
        (self.x.len() - 1) as u32
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Clears the gathered forces and adds gravity.
    pub fn start_forces(&mut self, gravity: DVec3) {
        for (f, m) in self.f.iter_mut().zip(&self.mass_kg) {
            *f = gravity * *m;
        }
    }

    /// Semi-implicit Euler over `dt_s`: velocities from the gathered forces, then positions;
    /// fixed balls stay where they are.
    pub fn integrate(&mut self, dt_s: f64) {
        for i in 0..self.x.len() {
            if self.fixed[i] {
                self.v[i] = DVec3::ZERO;
                continue;
            }
            self.v[i] += self.f[i] * (dt_s / self.mass_kg[i]);
            self.x[i] += self.v[i] * dt_s;
        }
    }

    /// The introducer sheath: every ball but the handle (ball 0) that lies behind `entry`
    /// along `axis` is put back on the axis, keeping only its speed along it.
    pub fn hold_behind(&mut self, entry: DVec3, axis: DVec3) {
        for i in 1..self.x.len() {
            let along = (self.x[i] - entry).dot(axis);
            if along < 0.0 {
                self.x[i] = entry + axis * along;
                let va = self.v[i].dot(axis);
                self.v[i] = axis * va;
            }
        }
    }

    /// The kinetic energy, J.
    pub fn kinetic_energy_j(&self) -> f64 {
        self.v
            .iter()
            .zip(&self.mass_kg)
            .map(|(v, m)| 0.5 * m * v.length_squared())
            .sum()
    }

    pub fn heap_bytes(&self) -> usize {
        self.x.capacity() * 24 * 3 + self.mass_kg.capacity() * 16 + self.fixed.capacity()
    }
}

/// A rod as a straight chain of `n` balls along `axis` ending at `tip`: each ball carries its
/// share of the rod's mass (half a segment at either end) from the density and the cross
/// section of `radius_m`, the first ball is held (the handle), and a damped linear spring
/// (`k`, `c`) joins each pair of neighbours at rest.
pub struct Rod {
    pub length_m: f64,
    pub radius_m: f64,
    pub density_kg_per_m3: f64,
    pub n: usize,
}

impl Rod {
    pub fn chain(&self, tip: DVec3, axis: DVec3, k: f64, c: f64) -> (Balls, Vec<LinearSpring>) {
        let n = self.n.max(2);
        let spacing = self.length_m / (n - 1) as f64;
        let area = std::f64::consts::PI * self.radius_m * self.radius_m;
        let mut balls = Balls::default();
        for i in 0..n {
            let share = if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
            let m = self.density_kg_per_m3 * area * spacing * share;
            balls.push(
                tip - axis * (self.length_m - spacing * i as f64),
                m,
                self.radius_m,
            );
        }
        balls.fixed[0] = true;
        let springs = (0..n - 1)
            .map(|i| LinearSpring::between(&balls, i as u32, i as u32 + 1, k, c))
            .collect();
        (balls, springs)
    }
}

/// A damped linear spring between two balls (eqs 1-3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearSpring {
    pub a: u32,
    pub b: u32,
    pub rest_m: f64,
    /// `k_a`, N/m.
    pub stiffness_n_per_m: f64,
    /// `c`, N/(m/s): on the rate of stretch.
    pub damping_n_s_per_m: f64,
}

impl LinearSpring {
    /// A spring at rest between `a` and `b` where they are now.
    pub fn between(balls: &Balls, a: u32, b: u32, k: f64, c: f64) -> LinearSpring {
        LinearSpring {
            a,
            b,
            rest_m: balls.x[a as usize].distance(balls.x[b as usize]),
            stiffness_n_per_m: k,
            damping_n_s_per_m: c,
        }
    }

    /// The force on `a` (b takes minus it): `(k_a dl + c dl/dt)` along the spring.
    pub fn force_on_a(&self, balls: &Balls) -> DVec3 {
        let (a, b) = (self.a as usize, self.b as usize);
        let d = balls.x[b] - balls.x[a];
        let len = d.length();
        if len <= 0.0 {
            return DVec3::ZERO;
        }
        let u = d / len;
        let stretch = len - self.rest_m;
        let rate = (balls.v[b] - balls.v[a]).dot(u);
        u * (self.stiffness_n_per_m * stretch + self.damping_n_s_per_m * rate)
    }
}

/// Adds every spring's forces to the balls, in order.
pub fn add_spring_forces(balls: &mut Balls, springs: &[LinearSpring]) {
    for s in springs {
        let f = s.force_on_a(balls);
        balls.f[s.a as usize] += f;
        balls.f[s.b as usize] -= f;
    }
}

/// An angle spring at ball `mid` between the arms to `prev` and `next` (eqs 4-5): the torque
/// `k_t` times the difference between the arms' turning (the rotation vector from the first
/// arm's direction to the second's) and its rest value, less its damping times the arms'
/// relative turning rate, acts on each arm's far ball as the force `tau / lambda`
/// perpendicular to its arm, and `mid` takes minus their sum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AngleSpring {
    pub prev: u32,
    pub mid: u32,
    pub next: u32,
    /// `k_t`, N m/rad.
    pub stiffness_n_m_per_rad: f64,
    /// The damping of the arms' relative turning rate, N m s/rad.
    pub damping_n_m_s_per_rad: f64,
    /// The turning at rest: its axis times the rest angle, rad.
    pub rest_turn: DVec3,
}

impl AngleSpring {
    /// The turning from the first arm to the second now: axis times angle, rad.
    pub fn turn(&self, balls: &Balls) -> DVec3 {
        let e1 = (balls.x[self.mid as usize] - balls.x[self.prev as usize]).normalize_or_zero();
        let e2 = (balls.x[self.next as usize] - balls.x[self.mid as usize]).normalize_or_zero();
        turn_between(e1, e2)
    }

    /// The forces on (prev, mid, next).
    pub fn forces(&self, balls: &Balls) -> [DVec3; 3] {
        let (p, m, n) = (
            balls.x[self.prev as usize],
            balls.x[self.mid as usize],
            balls.x[self.next as usize],
        );
        let (a1, a2) = (m - p, n - m);
        let (l1, l2) = (a1.length(), a2.length());
        if l1 <= 0.0 || l2 <= 0.0 {
            return [DVec3::ZERO; 3];
        }
        let (e1, e2) = (a1 / l1, a2 / l2);
        // The torque that turns the second arm back towards its rest turning (and the first
        // the other way).
        // The arms' angular velocities, and the damping of their difference.
        let w1 = e1.cross(balls.v[self.mid as usize] - balls.v[self.prev as usize]) / l1;
        let w2 = e2.cross(balls.v[self.next as usize] - balls.v[self.mid as usize]) / l2;
        let tau = (self.rest_turn - turn_between(e1, e2)) * self.stiffness_n_m_per_rad
            - (w2 - w1) * self.damping_n_m_s_per_rad;
        let f_next = tau.cross(e2) / l2;
        let f_prev = tau.cross(e1) / l1;
        [f_prev, -(f_next + f_prev), f_next]
    }
}

/// The rotation vector (axis times angle) that turns unit `e1` onto unit `e2`.
pub fn turn_between(e1: DVec3, e2: DVec3) -> DVec3 {
    let axis = e1.cross(e2);
    let s = axis.length();
    let c = e1.dot(e2);
    if s <= 1e-15 {
        return DVec3::ZERO;
    }
    axis * (s.atan2(c) / s)
}

/// Adds every angle spring's forces to the balls, in order.
pub fn add_angle_forces(balls: &mut Balls, springs: &[AngleSpring]) {
    for s in springs {
        let [fp, fm, fn_] = s.forces(balls);
        balls.f[s.prev as usize] += fp;
        balls.f[s.mid as usize] += fm;
        balls.f[s.next as usize] += fn_;
    }
}

#[cfg(test)]
mod tests;
