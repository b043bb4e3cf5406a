//! The catheter: a chain of skeleton balls (the paper's 10 mm by 100 mm catheter, balls as
//! wide as it, one radius apart) joined by damped linear springs along it, angle springs at
//! every inner ball against bending, and torsion springs between neighbours' twist angles
//! (so a twist at the handle turns the tip). The device drives the proximal ball: how far it
//! is inserted along the entry's axis and how far it is twisted; behind the entry the catheter
//! runs in the introducer sheath (held on the axis). Its distal part bends actively along an
//! arc of constant curvature ([`super::bending`]) towards its own "up", which the twist turns:
//! bending and twisting choose the branch.
//!
//! The paper gives no catheter material: masses here come from a polymer's density and each
//! ball's share of the rod, the springs' stiffnesses are ours (documented in the scenario).

use super::{AngleSpring, Balls, LinearSpring, Rod, add_angle_forces, add_spring_forces, bending};
use glam::{DQuat, DVec3};

/// The fastest the handle follows the device, m/s (a hand pushes a catheter at centimetres a
/// second).
pub const HANDLE_M_PER_S: f64 = 0.5;

/// The catheter's size and materials.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CatheterParams {
    pub length_m: f64,
    pub diameter_m: f64,
    pub density_kg_per_m3: f64,
    /// Each segment's axial spring, N/m, and the springs' damping, N/(m/s).
    pub axial_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    /// The bending stiffness as a force per metre of sideways deflection at one segment's
    /// length (`k_t = k lambda^2`), N/m.
    pub bending_n_per_m: f64,
    /// Between neighbours' twist angles, N m/rad, and the damping of their relative spin,
    /// N m s/rad.
    pub torsion_n_m_per_rad: f64,
    pub torsion_damping: f64,
    /// The distal part that bends, m, and its largest bending angle `theta` (half the arc's
    /// turning), degrees.
    pub bend_length_m: f64,
    pub max_bend_deg: f64,
}

impl Default for CatheterParams {
    fn default() -> Self {
        CatheterParams {
            length_m: 0.100,
            diameter_m: 0.010,
            density_kg_per_m3: 1100.0,
            axial_n_per_m: 2000.0,
            damping_n_s_per_m: 0.3,
            bending_n_per_m: 200.0,
            torsion_n_m_per_rad: 1e-3,
            torsion_damping: 1e-5,
            bend_length_m: 0.030,
            max_bend_deg: 45.0,
        }
    }
}

/// What the device asks of the catheter this step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Drive {
    /// How far the tip is past the entry along its axis when straight, m.
    pub insertion_m: f64,
    /// The handle's twist, rad.
    pub twist_rad: f64,
    /// The active bend, 0 (straight) to 1 (the largest).
    pub bend: f64,
}

/// The catheter: its balls (0 at the handle, the last the tip) and springs, each ball's twist
/// and spin, and where it enters the vessel.
#[derive(Debug, Clone, PartialEq)]
pub struct Catheter {
    pub balls: Balls,
    pub springs: Vec<LinearSpring>,
    pub angles: Vec<AngleSpring>,
    pub twist: Vec<f64>,
    spin: Vec<f64>,
    inertia: Vec<f64>,
    /// Each ball's bending direction ("up"), across the catheter.
    pub up: Vec<DVec3>,
    pub entry: DVec3,
    pub axis: DVec3,
    /// The balls of the bending part (the last ones).
    pub bend_balls: usize,
    pub params: CatheterParams,
}

impl Catheter {
    /// A straight catheter along `axis` with its tip at `entry` (all of it in the sheath).
    pub fn new(p: &CatheterParams, entry: DVec3, axis: DVec3) -> Catheter {
        let axis = axis.normalize_or(DVec3::X);
        let r = 0.5 * p.diameter_m;
        let n = ((p.length_m / r).round() as usize + 1).max(3);
        let spacing = p.length_m / (n - 1) as f64;
        let rod = Rod {
            length_m: p.length_m,
            radius_m: r,
            density_kg_per_m3: p.density_kg_per_m3,
            n,
        };
        let (balls, springs) = rod.chain(entry, axis, p.axial_n_per_m, p.damping_n_s_per_m);
        let k_t = p.bending_n_per_m * spacing * spacing;
        let angles = (1..n - 1)
            .map(|i| AngleSpring {
                prev: i as u32 - 1,
                mid: i as u32,
                next: i as u32 + 1,
                stiffness_n_m_per_rad: k_t,
                damping_n_m_s_per_rad: p.damping_n_s_per_m * spacing * spacing,
                rest_turn: DVec3::ZERO,
            })
            .collect();
        let inertia = balls.mass_kg.iter().map(|m| 0.4 * m * r * r).collect();
        let bend_balls = ((p.bend_length_m / spacing).round() as usize + 1).clamp(2, n);
        let up0 = any_across(axis);
        Catheter {
            balls,
            springs,
            angles,
            twist: vec![0.0; n],
            spin: vec![0.0; n],
            inertia,
            up: vec![up0; n],
            entry,
            axis,
            bend_balls,
            params: *p,
        }
    }

    /// The first ball past the entry (those before it are in the sheath, outside the vessel).
    pub fn first_inside(&self) -> usize {
        self.balls
            .x
            .iter()
            .position(|x| (*x - self.entry).dot(self.axis) >= 0.0)
            .unwrap_or(self.balls.len())
    }

    pub fn tip(&self) -> DVec3 {
        self.balls.x[self.balls.len() - 1]
    }

    /// The segments' rest length, m.
    pub fn spacing_m(&self) -> f64 {
        self.params.length_m / (self.balls.len() - 1) as f64
    }

    /// Brings each ball's "up" and the bending part's rest turns up to date with the drive:
    /// once a step (they follow the twist and the trigger, which change at the step's rate).
    pub fn orient(&mut self, drive: &Drive) {
        self.twist[0] = drive.twist_rad;
        self.frames();
        self.set_bend(drive.bend.clamp(0.0, 1.0));
    }

    /// One sub-step of `dt_s` under the device's drive and the contact forces on each ball
    /// (after [`Catheter::orient`] for the step).
    pub fn step(&mut self, drive: &Drive, contact: &[DVec3], dt_s: f64) {
        let v0 = self.gather(drive, contact, dt_s);
        self.advance(dt_s, v0);
    }

    /// The first half of a substep: the handle moved by the drive and the forces gathered
    /// (contact, springs, bending). Returns the handle's speed, for [`Catheter::advance`].
    fn gather(&mut self, drive: &Drive, contact: &[DVec3], dt_s: f64) -> DVec3 {
        let p = self.params;
        // The handle: kinematic, along the axis, at most `HANDLE_M_PER_S` fast (a drive that
        // jumps is followed, not obeyed at once).
        let want = self.entry + self.axis * (drive.insertion_m - p.length_m);
        let step = want - self.balls.x[0];
        let most = HANDLE_M_PER_S * dt_s;
        let handle = self.balls.x[0] + step.clamp_length_max(most);
        let v0 = (handle - self.balls.x[0]) / dt_s.max(1e-12);
        self.balls.x[0] = handle;
        self.twist[0] = drive.twist_rad;
        self.balls.start_forces(DVec3::ZERO);
        for (f, c) in self.balls.f.iter_mut().zip(contact) {
            *f += *c;
        }
        add_spring_forces(&mut self.balls, &self.springs);
        add_angle_forces(&mut self.balls, &self.angles);
        v0
    }

    /// The second half: the balls moved under the gathered forces, the sheath, the twist.
    fn advance(&mut self, dt_s: f64, v0: DVec3) {
        let n = self.balls.len();
        let p = self.params;
        self.balls.integrate(dt_s);
        self.balls.v[0] = v0;
        // The sheath: behind the entry, on the axis.
        self.balls.hold_behind(self.entry, self.axis);
        // Twist: damped torsion springs between neighbours (the damping on their relative
        // spin: a catheter turned as a whole is not held back), the handle's held.
        let (k, c) = (p.torsion_n_m_per_rad, p.torsion_damping);
        let handle_spin = self.spin[0];
        self.spin[0] = 0.0;
        let spin = self.spin.clone();
        for i in 1..n {
            let mut torque = k * (self.twist[i - 1] - self.twist[i]) + c * (spin[i - 1] - spin[i]);
            if i + 1 < n {
                torque += k * (self.twist[i + 1] - self.twist[i]) + c * (spin[i + 1] - spin[i]);
            }
            self.spin[i] += torque / self.inertia[i] * dt_s;
        }
        self.spin[0] = handle_spin;
        for i in 1..n {
            self.twist[i] += self.spin[i] * dt_s;
        }
    }

    /// Each ball's "up": the handle's, turned by its twist, carried along the chain (parallel
    /// transport) and turned by each ball's twist relative to the one before.
    fn frames(&mut self) {
        let n = self.balls.len();
        self.up[0] = DQuat::from_axis_angle(self.axis, self.twist[0]) * any_across(self.axis);
        for i in 1..n {
            let e = (self.balls.x[i] - self.balls.x[i - 1]).normalize_or(self.axis);
            let carried = (self.up[i - 1] - e * e.dot(self.up[i - 1])).normalize_or(self.up[i - 1]);
            self.up[i] = DQuat::from_axis_angle(e, self.twist[i] - self.twist[i - 1]) * carried;
        }
    }

    /// The bending part's angle springs rest on the arc of [`bending`] for `bend` of the
    /// largest angle, turning towards each ball's "up"; the others rest straight.
    fn set_bend(&mut self, bend: f64) {
        let n = self.balls.len();
        let nb = self.bend_balls;
        let theta = bend * self.params.max_bend_deg.to_radians();
        let per_ball = bending::turn_per_ball(nb, theta);
        let first = n - nb;
        for s in &mut self.angles {
            let mid = s.mid as usize;
            // The arc leaves the straight part along its tangent: the first chord turns by
            // half a step, the others by a whole one.
            let angle = if mid > first {
                per_ball
            } else if mid == first {
                0.5 * per_ball
            } else {
                0.0
            };
            let e1 = (self.balls.x[mid] - self.balls.x[s.prev as usize]).normalize_or(self.axis);
            let bend_axis = e1.cross(self.up[mid]).normalize_or_zero();
            s.rest_turn = bend_axis * angle;
        }
    }
}

/// A unit vector across `axis`: `+y` made perpendicular to it (or `+z` for an axis along y).
pub fn any_across(axis: DVec3) -> DVec3 {
    let y = DVec3::Y - axis * axis.dot(DVec3::Y);
    if y.length_squared() > 1e-12 {
        y.normalize()
    } else {
        (DVec3::Z - axis * axis.dot(DVec3::Z)).normalize_or(DVec3::Z)
    }
}
