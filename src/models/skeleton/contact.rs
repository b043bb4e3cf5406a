//! The contact force between a catheter ball and the vessel wall (the paper's eqs 8-10): the
//! normal force from the collision depth `D` and the velocity `v` into the wall,
//! `|F_N| = k D + c v + t` (eq 9, the paper's `F_N = -k D - c v + t` with its signs read
//! along the wall's inward normal), never pulling; the friction along the wall against the
//! sliding, `|F_f| = mu |F_N|` (eq 8); the catheter ball feels `F = F_N + F_f` (eq 10), the
//! wall minus it.
//!
//! `t` is the paper's constant: read as the force a touching wall exerts at zero depth (a
//! preload), so a contact starts at `t` and the 0.5-3.5 N the paper measured is its range.

use glam::DVec3;

/// Sliding slower than this, m/s, the friction grows from zero in proportion to the speed.
pub const STICK_M_PER_S: f64 = 1e-3;

/// The contact law's coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLaw {
    /// `k`, N/m.
    pub stiffness_n_per_m: f64,
    /// `c`, N/(m/s).
    pub damping_n_s_per_m: f64,
    /// `t`, N.
    pub preload_n: f64,
    /// `mu`.
    pub friction: f64,
}

/// One contact's forces on the catheter ball, N.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ContactForce {
    pub normal: DVec3,
    pub friction: DVec3,
}

impl ContactForce {
    /// `F = F_N + F_f` (eq 10).
    pub fn total(&self) -> DVec3 {
        self.normal + self.friction
    }
}

impl ContactLaw {
    /// The forces on a catheter ball `depth_m` into the wall, whose outward normal (from the
    /// wall towards the catheter) is `n`, moving at `v_rel` relative to the wall.
    pub fn force(&self, depth_m: f64, n: DVec3, v_rel: DVec3) -> ContactForce {
        if depth_m <= 0.0 {
            return ContactForce::default();
        }
        // The speed into the wall (positive while the ball goes deeper).
        let v_in = -v_rel.dot(n);
        let magnitude =
            (self.stiffness_n_per_m * depth_m + self.damping_n_s_per_m * v_in + self.preload_n)
                .max(0.0);
        let normal = n * magnitude;
        let slide = v_rel - n * v_rel.dot(n);
        let speed = slide.length();
        // Against the sliding, `mu |F_N|` once it slides faster than `STICK_M_PER_S` (below,
        // in proportion: a Coulomb law that does not chatter at rest).
        let friction = if speed > 0.0 {
            -slide / speed * (self.friction * magnitude * (speed / STICK_M_PER_S).min(1.0))
        } else {
            DVec3::ZERO
        };
        ContactForce { normal, friction }
    }
}
