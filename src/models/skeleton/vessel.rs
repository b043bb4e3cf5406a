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
use rayon::prelude::*;

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
    /// Its rings of balls, `around` to a ring (none where a ball was left out), from the
    /// start: the wall's mesh for drawing.
    pub rings: Vec<Vec<Option<u32>>>,
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
    /// Each ball's springs (`ball_springs[ball_start[i]..ball_start[i + 1]]`), with the sign
    /// of the spring's force on it: the forces are gathered per ball in a fixed order.
    ball_start: Vec<u32>,
    ball_springs: Vec<(u32, f64)>,
    /// Each spring's force on its first ball this step (scratch).
    spring_f: Vec<DVec3>,
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
                rings: Vec::new(),
            },
            Tube {
                start: end,
                dir: DVec3::new(a.cos(), a.sin(), 0.0),
                length_m: p.branch_m,
                sections: Vec::new(),
                rings: Vec::new(),
            },
            Tube {
                start: end,
                dir: DVec3::new(a.cos(), -a.sin(), 0.0),
                length_m: p.branch_m,
                sections: Vec::new(),
                rings: Vec::new(),
            },
        ];
        let around = p.around.max(3);
        let spacing = std::f64::consts::TAU * mid / around as f64;
        let mut balls = Balls::default();
        let mut owner: Vec<usize> = Vec::new();
        let mut all_rings: Vec<Vec<Vec<Option<u32>>>> = Vec::new();
        for (ti, tube) in tubes.iter().enumerate() {
            let rings = (tube.length_m / spacing).round().max(1.0) as usize;
            let mut grid = Vec::with_capacity(rings + 1);
            // A frame across the tube: z, and the in-plane normal.
            let side = DVec3::Z.cross(tube.dir).normalize_or(DVec3::Y);
            for k in 0..=rings {
                let mut ring = Vec::with_capacity(around);
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
                        ring.push(Some(b));
                    } else {
                        ring.push(None);
                    }
                }
                grid.push(ring);
            }
            all_rings.push(grid);
        }
        for (tube, grid) in tubes.iter_mut().zip(all_rings) {
            tube.rings = grid;
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
        let mut per_ball: Vec<Vec<(u32, f64)>> = vec![Vec::new(); balls.len()];
        for (k, sp) in springs.iter().enumerate() {
            per_ball[sp.a as usize].push((k as u32, 1.0));
            per_ball[sp.b as usize].push((k as u32, -1.0));
        }
        let mut ball_start = Vec::with_capacity(balls.len() + 1);
        let mut ball_springs = Vec::new();
        for list in per_ball {
            ball_start.push(ball_springs.len() as u32);
            ball_springs.extend(list);
        }
        ball_start.push(ball_springs.len() as u32);
        let spring_f = vec![DVec3::ZERO; springs.len()];
        Vessel {
            balls,
            springs,
            rest,
            tubes,
            mid_radius_m: mid,
            params: *p,
            ball_start,
            ball_springs,
            spring_f,
        }
    }

    /// Gathers the wall's forces (springs, tethers) on top of `external` (the contacts'
    /// reaction), then steps it by `dt_s`. The springs' forces are worked out in parallel,
    /// then each ball sums its own in a fixed order and moves (the same bytes on any number
    /// of threads).
    pub fn step(&mut self, external: &[DVec3], dt_s: f64) {
        const CHUNK: usize = 256;
        let balls = &self.balls;
        let springs = &self.springs;
        self.spring_f
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, out)| {
                for (k, f) in out.iter_mut().enumerate() {
                    *f = springs[c * CHUNK + k].force_on_a(balls);
                }
            });
        let k = self.params.tether_n_per_m;
        let (start, list, spring_f, rest) = (
            &self.ball_start,
            &self.ball_springs,
            &self.spring_f,
            &self.rest,
        );
        let b = &mut self.balls;
        let (x, v) = (&mut b.x, &mut b.v);
        let (mass, fixed, forces) = (&b.mass_kg, &b.fixed, &mut b.f);
        x.par_chunks_mut(CHUNK)
            .zip(v.par_chunks_mut(CHUNK))
            .zip(forces.par_chunks_mut(CHUNK))
            .enumerate()
            .for_each(|(c, ((xs, vs), fs))| {
                for j in 0..xs.len() {
                    let i = c * CHUNK + j;
                    let mut f =
                        external.get(i).copied().unwrap_or_default() + (rest[i] - xs[j]) * k;
                    for &(s, sign) in &list[start[i] as usize..start[i + 1] as usize] {
                        f += spring_f[s as usize] * sign;
                    }
                    fs[j] = f;
                    if fixed[i] {
                        vs[j] = DVec3::ZERO;
                        continue;
                    }
                    vs[j] += f * (dt_s / mass[i]);
                    xs[j] += vs[j] * dt_s;
                }
            });
    }

    /// The wall as triangles between neighbouring rings (wound outwards), where all four
    /// balls of a quad are present: its surface for drawing.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for tube in &self.tubes {
            for k in 0..tube.rings.len().saturating_sub(1) {
                let (r0, r1) = (&tube.rings[k], &tube.rings[k + 1]);
                let n = r0.len();
                for j in 0..n {
                    let jn = (j + 1) % n;
                    if let (Some(a), Some(b), Some(c), Some(d)) = (r0[j], r0[jn], r1[j], r1[jn]) {
                        out.push([a, b, c]);
                        out.push([b, d, c]);
                    }
                }
            }
        }
        out
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
