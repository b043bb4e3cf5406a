//! A vessel tree filled with skeleton balls on its wall's central surface (the paper's Figs
//! 7-10): straight tubes (the paper's bifurcation: a trunk and two branches of one diameter;
//! or a tree's centrelines cut into tubes, [`super::tree`]), the balls in rings along each
//! tube at its wall's mid-radius, those that fall inside another tube's lumen left out (which
//! opens the branchings), joined by damped springs to every ball within reach and tied to
//! where they rest by the tissue around the vessel; the first tube's inlet ring is held (the
//! paper fixes the vessel at one end). The tubes keep the balls by section along their axes
//! for the collision ([`super::collision`]).
//!
//! Frame: the first tube runs along `+x` from the inlet at the origin; the paper's branches
//! leave the trunk's end in the `x y` plane at `+-branch_angle`.

use super::tree::TubeSpec;
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

impl VesselParams {
    /// The paper's bifurcation as tubes: the trunk (`trunk`), then the branches towards `+y`
    /// (`right`: the patient's right, supine with the head towards `+x`) and `-y` (`left`).
    pub fn bifurcation(&self) -> (Vec<TubeSpec>, Vec<Branch>) {
        let a = self.branch_angle_deg.to_radians();
        let end = DVec3::X * self.trunk_m;
        let tube = |start, dir, length_m, parent, vessel| TubeSpec {
            start,
            dir,
            length_m,
            diameter_m: self.diameter_m,
            parent,
            vessel,
            offset_m: 0.0,
        };
        let tubes = vec![
            tube(DVec3::ZERO, DVec3::X, self.trunk_m, None, 0),
            tube(
                end,
                DVec3::new(a.cos(), a.sin(), 0.0),
                self.branch_m,
                Some(0),
                1,
            ),
            tube(
                end,
                DVec3::new(a.cos(), -a.sin(), 0.0),
                self.branch_m,
                Some(0),
                2,
            ),
        ];
        let branch = |name: &str, parent| Branch {
            name: name.to_string(),
            parent,
            length_m: if parent.is_some() {
                self.branch_m
            } else {
                self.trunk_m
            },
        };
        let names = vec![
            branch("trunk", None),
            branch("right", Some(0)),
            branch("left", Some(0)),
        ];
        (tubes, names)
    }
}

/// One vessel of the tree: its name, its parent vessel and its centreline's length.
#[derive(Debug, Clone, PartialEq)]
pub struct Branch {
    pub name: String,
    pub parent: Option<usize>,
    pub length_m: f64,
}

/// One straight tube of the vessel: where its axis starts, its direction and length, its
/// radii, where it sits in the tree, and its balls by section along the axis.
#[derive(Debug, Clone, PartialEq)]
pub struct Tube {
    pub start: DVec3,
    pub dir: DVec3,
    pub length_m: f64,
    /// The wall's mid-radius and the lumen's radius (the wall's inner surface), m.
    pub mid_radius_m: f64,
    pub lumen_m: f64,
    /// The tube its blood comes from, the vessel ([`Vessel::branches`]) it is part of, how far
    /// along that vessel it starts and how far from the inlet along the tree, m.
    pub parent: Option<usize>,
    pub vessel: usize,
    pub offset_m: f64,
    pub from_inlet_m: f64,
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

/// The vessel: its balls, springs, tethers (resting places), tubes and named vessels.
#[derive(Debug, Clone, PartialEq)]
pub struct Vessel {
    pub balls: Balls,
    pub springs: Vec<LinearSpring>,
    pub rest: Vec<DVec3>,
    pub tubes: Vec<Tube>,
    pub branches: Vec<Branch>,
    /// Each wall ball's share of an instrument's puncture force (1; less at the ostia).
    pub strength: Vec<f64>,
    pub params: VesselParams,
    /// Each ball's springs (`ball_springs[ball_start[i]..ball_start[i + 1]]`), with the sign
    /// of the spring's force on it: the forces are gathered per ball in a fixed order.
    ball_start: Vec<u32>,
    ball_springs: Vec<(u32, f64)>,
    /// Each spring's force on its first ball this step (scratch).
    spring_f: Vec<DVec3>,
}

impl Vessel {
    /// The paper's bifurcation ([`VesselParams::bifurcation`]).
    pub fn new(p: &VesselParams) -> Vessel {
        let (tubes, branches) = p.bifurcation();
        Vessel::of_tubes(p, &tubes, branches)
    }

    /// A vessel of `specs` (each one's parent before it, the first the inlet's) and the
    /// vessels they make up, with `p`'s wall and materials (its diameter and lengths unused).
    pub fn of_tubes(p: &VesselParams, specs: &[TubeSpec], branches: Vec<Branch>) -> Vessel {
        let around = p.around.max(3);
        let mut tubes: Vec<Tube> = Vec::with_capacity(specs.len());
        for s in specs {
            let from_inlet_m = s
                .parent
                .and_then(|k| tubes.get(k))
                .map_or(0.0, |t| t.from_inlet_m + t.length_m);
            tubes.push(Tube {
                start: s.start,
                dir: s.dir,
                length_m: s.length_m,
                mid_radius_m: 0.5 * (s.diameter_m - p.wall_m),
                lumen_m: (0.5 * s.diameter_m - p.wall_m).max(1e-4),
                parent: s.parent,
                vessel: s.vessel,
                offset_m: s.offset_m,
                from_inlet_m,
                sections: Vec::new(),
                rings: Vec::new(),
            });
        }
        let spacing_of = |t: &Tube| std::f64::consts::TAU * t.mid_radius_m / around as f64;
        let mut balls = Balls::default();
        let mut owner: Vec<usize> = Vec::new();
        let mut all_rings: Vec<Vec<Vec<Option<u32>>>> = Vec::new();
        for (ti, tube) in tubes.iter().enumerate() {
            let spacing = spacing_of(tube);
            let mid = tube.mid_radius_m;
            let rings = (tube.length_m / spacing).round().max(1.0) as usize;
            let mut grid = Vec::with_capacity(rings + 1);
            // A frame across the tube: the normal in the x y plane, and the one across both
            // (exactly z for a tube in that plane).
            let side = DVec3::Z.cross(tube.dir).normalize_or(DVec3::Y);
            let up = if tube.dir.z == 0.0 {
                DVec3::Z
            } else {
                tube.dir.cross(side).normalize()
            };
            for k in 0..=rings {
                let mut ring = Vec::with_capacity(around);
                let t = tube.length_m * k as f64 / rings as f64;
                for j in 0..around {
                    let phi = std::f64::consts::TAU * j as f64 / around as f64;
                    let x = tube.start + tube.dir * t + (side * phi.cos() + up * phi.sin()) * mid;
                    // Inside another tube's lumen: left out (the branchings' openings).
                    let inside = tubes.iter().enumerate().any(|(tj, other)| {
                        tj != ti && other.from_axis(x) < other.mid_radius_m - 0.25 * spacing
                    });
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
        // Springs to every ball within reach of the lattice's diagonal (the finer of the two
        // balls' tubes': a coarse tube's ball meeting a fine one's lattice takes no more
        // springs than its own lattice gives it, which keeps the step's stability).
        let reach: Vec<f64> = owner.iter().map(|&t| 1.5 * spacing_of(&tubes[t])).collect();
        let mut springs = Vec::new();
        for i in 0..balls.len() {
            for j in i + 1..balls.len() {
                if balls.x[i].distance(balls.x[j]) <= reach[i].min(reach[j]) {
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
        let strength = vec![1.0; balls.len()];
        Vessel {
            balls,
            springs,
            rest,
            strength,
            tubes,
            branches,
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

    /// Weakens the wall where two vessels' walls meet (the ostia, the carinae): a wall ball
    /// within `radius_m` of another vessel's tube's wall (its central surface, along that
    /// tube's length) punctures at `share` of an instrument's puncture force.
    pub fn weaken_ostia(&mut self, radius_m: f64, share: f64) {
        for (ti, tube) in self.tubes.iter().enumerate() {
            for &b in tube.sections.iter().flatten() {
                let x = self.rest[b as usize];
                let seam = self.tubes.iter().enumerate().any(|(tj, o)| {
                    tj != ti
                        && o.vessel != tube.vessel
                        && (0.0..=o.length_m).contains(&o.along(x))
                        && (o.from_axis(x) - o.mid_radius_m).abs() <= radius_m
                });
                if seam {
                    self.strength[b as usize] = share;
                }
            }
        }
    }

    /// The tube whose lumen holds `p` (the nearest axis of those it is within the length of)
    /// and how far along it `p` is, m; none outside every lumen.
    pub fn locate(&self, p: DVec3) -> Option<(usize, f64)> {
        self.tubes
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                (0.0..=t.length_m).contains(&t.along(p)) && t.from_axis(p) <= t.lumen_m
            })
            .min_by(|a, b| a.1.from_axis(p).total_cmp(&b.1.from_axis(p)))
            .map(|(k, t)| (k, t.along(p)))
    }

    /// How far along vessel `branch`'s centreline `p` is, m, when it lies within the wall's
    /// central surface of one of its tubes (the nearest axis of those; past the vessel's
    /// last tube's end, on along it).
    pub fn along_branch(&self, branch: usize, p: DVec3) -> Option<f64> {
        self.tubes
            .iter()
            .filter(|t| t.vessel == branch && t.from_axis(p) < t.mid_radius_m)
            .min_by(|a, b| a.from_axis(p).total_cmp(&b.from_axis(p)))
            .map(|t| t.offset_m + t.along(p))
    }

    /// How far `p` is from the inlet along the tree, m: along the tube whose axis is nearest
    /// (before the inlet, negative).
    pub fn path_m(&self, p: DVec3) -> f64 {
        let nearest = self
            .tubes
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.from_axis(p).total_cmp(&b.1.from_axis(p)));
        match nearest {
            Some((0, t)) => t.along(p).min(t.length_m),
            Some((_, t)) => t.from_inlet_m + t.along(p).clamp(0.0, t.length_m),
            None => 0.0,
        }
    }

    /// Whether vessel `a` is `b` or one of its ancestors.
    pub fn leads_to(&self, a: usize, b: usize) -> bool {
        let mut at = Some(b);
        while let Some(k) = at {
            if k == a {
                return true;
            }
            at = self.branches.get(k).and_then(|v| v.parent);
        }
        false
    }

    /// The first vessel more than `depth_m` along which `p` lies that does not
    /// lead to `target` (a wrong branch), if any.
    pub fn astray(&self, target: usize, p: DVec3, depth_m: f64) -> Option<usize> {
        (0..self.branches.len()).find(|&k| {
            !self.leads_to(k, target) && self.along_branch(k, p).is_some_and(|s| s > depth_m)
        })
    }
}
