//! A bifurcating vessel filled with skeleton balls on its wall's central surface (the paper's
//! Figs 7-10): a trunk and two branches, straight tubes of the same diameter, the balls in
//! rings along each tube at the wall's mid-radius, those that fall inside another tube's lumen
//! left out (which opens the bifurcation), joined by damped springs to every ball within
//! reach and tied to where they rest by the tissue around the vessel; the trunk's inlet ring
//! is held (the paper fixes the vessel at one end). The tubes keep the balls by section along
//! their axes for the collision ([`super::collision`]).
//!
//! Frame: the trunk runs along `+x` from the inlet at the origin; the branches leave its end
//! in the `x y` plane at `+-branch_angle`.

use super::{Balls, LinearSpring};
use glam::DVec3;

/// The vessel's shape, resolution and materials.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VesselParams {
    /// Outer diameter and wall thickness, m.
    pub diameter_m: f64,
    pub wall_m: f64,
    pub trunk_m: f64,
    pub branch_m: f64,
    pub branch_angle_deg: f64,
    /// Balls around each ring.
    pub around: usize,
    pub ball_mass_kg: f64,
    /// The wall's springs: `k_a` and `c`.
    pub spring_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    /// Each ball's tie to its resting place (the tissue around the vessel), N/m.
    pub tether_n_per_m: f64,
    /// The collision sections' length along each tube, m.
    pub section_m: f64,
}

impl Default for VesselParams {
    fn default() -> Self {
        VesselParams {
            diameter_m: 0.020,
            wall_m: 0.002,
            trunk_m: 0.060,
            branch_m: 0.060,
            branch_angle_deg: 30.0,
            around: 16,
            ball_mass_kg: 0.002,
            spring_n_per_m: 100.0,
            damping_n_s_per_m: 0.3,
            tether_n_per_m: 20.0,
            section_m: 0.010,
        }
    }
}

/// One straight tube of the vessel: where its axis starts, its direction and length, and its
/// balls by section along the axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    pub start: DVec3,
    pub dir: DVec3,
    pub length_m: f64,
    pub sections: Vec<Vec<u32>>,
}

impl Tube {
    /// How far along the axis `p` projects, m (unclamped).
    pub fn along(&self, p: DVec3) -> f64 {
        (p - self.start).dot(self.dir)
    }

    /// The distance from `p` to the axis segment, m.
    pub fn from_axis(&self, p: DVec3) -> f64 {
        let t = self.along(p).clamp(0.0, self.length_m);
        (p - (self.start + self.dir * t)).length()
    }
}

/// The vessel: its balls, springs, tethers (resting places) and tubes.
#[derive(Debug, Clone, PartialEq)]
pub struct Vessel {
    pub balls: Balls,
    pub springs: Vec<LinearSpring>,
    pub rest: Vec<DVec3>,
    pub tubes: Vec<Tube>,
    /// The wall's mid-radius, m.
    pub mid_radius_m: f64,
    pub params: VesselParams,
}

impl Vessel {
    pub fn new(p: &VesselParams) -> Vessel {
        let mid = 0.5 * (p.diameter_m - p.wall_m);
        let a = p.branch_angle_deg.to_radians();
        let end = DVec3::X * p.trunk_m;
        let mut tubes = vec![
            Tube {
                start: DVec3::ZERO,
                dir: DVec3::X,
                length_m: p.trunk_m,
                sections: Vec::new(),
            },
            Tube {
                start: end,
                dir: DVec3::new(a.cos(), a.sin(), 0.0),
                length_m: p.branch_m,
                sections: Vec::new(),
            },
            Tube {
                start: end,
                dir: DVec3::new(a.cos(), -a.sin(), 0.0),
                length_m: p.branch_m,
                sections: Vec::new(),
            },
        ];
        let around = p.around.max(3);
        let spacing = std::f64::consts::TAU * mid / around as f64;
        let mut balls = Balls::default();
        let mut owner: Vec<usize> = Vec::new();
        for (ti, tube) in tubes.iter().enumerate() {
            let rings = (tube.length_m / spacing).round().max(1.0) as usize;
            // A frame across the tube: z, and the in-plane normal.
            let side = DVec3::Z.cross(tube.dir).normalize_or(DVec3::Y);
            for k in 0..=rings {
                let t = tube.length_m * k as f64 / rings as f64;
                for j in 0..around {
                    let phi = std::f64::consts::TAU * j as f64 / around as f64;
                    let x =
                        tube.start + tube.dir * t + (side * phi.cos() + DVec3::Z * phi.sin()) * mid;
                    // Inside another tube's lumen: left out (the bifurcation's openings).
                    let inside = tubes
                        .iter()
                        .enumerate()
                        .any(|(tj, other)| tj != ti && other.from_axis(x) < mid - 0.25 * spacing);
                    // A ring where another tube's ring already is (the junction's shared
                    // ring): left out too.
                    let taken = balls.x.iter().any(|y| y.distance(x) < 0.3 * spacing);
                    if !inside && !taken {
                        let b = balls.push(x, p.ball_mass_kg, 0.5 * p.wall_m);
                        if ti == 0 && k == 0 {
                            balls.fixed[b as usize] = true;
                        }
                        owner.push(ti);
                    }
                }
            }
        }
        // Springs to every ball within reach of the lattice's diagonal.
        let reach = 1.5 * spacing;
        let mut springs = Vec::new();
        for i in 0..balls.len() {
            for j in i + 1..balls.len() {
                if balls.x[i].distance(balls.x[j]) <= reach {
                    springs.push(LinearSpring::between(
                        &balls,
                        i as u32,
                        j as u32,
                        p.spring_n_per_m,
                        p.damping_n_s_per_m,
                    ));
                }
            }
        }
        for (ti, tube) in tubes.iter_mut().enumerate() {
            let n = (tube.length_m / p.section_m).ceil().max(1.0) as usize;
            tube.sections = vec![Vec::new(); n];
            for (b, x) in balls.x.iter().enumerate() {
                if owner[b] == ti {
                    let k = ((tube.along(*x) / p.section_m).floor().max(0.0) as usize).min(n - 1);
                    tube.sections[k].push(b as u32);
                }
            }
        }
        let rest = balls.x.clone();
        Vessel {
            balls,
            springs,
            rest,
            tubes,
            mid_radius_m: mid,
            params: *p,
        }
    }

    /// Gathers the wall's forces (springs, tethers, damping of each ball against its rest)
    /// on top of `external` (the contacts' reaction), then steps it by `dt_s`.
    pub fn step(&mut self, external: &[DVec3], dt_s: f64) {
        self.balls.start_forces(DVec3::ZERO);
        for (f, e) in self.balls.f.iter_mut().zip(external) {
            *f += *e;
        }
        super::add_spring_forces(&mut self.balls, &self.springs);
        let k = self.params.tether_n_per_m;
        for i in 0..self.balls.len() {
            self.balls.f[i] += (self.rest[i] - self.balls.x[i]) * k;
        }
        self.balls.integrate(dt_s);
    }

    /// The largest distance of a ball from where it rests, m.
    pub fn largest_displacement_m(&self) -> f64 {
        self.balls
            .x
            .iter()
            .zip(&self.rest)
            .map(|(x, r)| x.distance(*r))
            .fold(0.0, f64::max)
    }
}
