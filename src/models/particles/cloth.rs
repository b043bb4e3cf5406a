//! The cloth fascia between the gallbladder and the liver: the cholecystectomy paper's surface
//! mesh (its section 4.2, eqs 5-7), a triangle mesh of particles held by springs along its
//! edges and across its hinges.
//!
//! - Stretch (eq 5): every edge of the mesh, counted once however many triangles share it,
//!   keeps its rest length `l0`: `C = |p1 - p2| - l0`.
//! - Bending (eq 6): every pair of triangles sharing an edge keeps its rest dihedral angle
//!   `phi0`. Eq 6 writes the angle as `acos(n1 . n2)`; we use the signed dihedral of
//!   [`xpbd::dihedral`] (0 when flat, positive folded one way, negative the other), which
//!   tells a bump from a dent and has a bounded gradient when flat.
//! - Eq 7's energy `E = sum(k_stretch C_stretch^2 + k_bend C_bend^2)` is taken as
//!   `E = sum(k C^2 / 2)` with `k` the spring constant: an edge stretched by `C` metres pulls
//!   its ends together with `k_stretch C` newtons, and a hinge turned `C` radians from rest
//!   exerts a torque of `k_bend C` newton-metres (the paper's `k` is half ours).
//!
//! Rest lengths and angles are those of the particles when the cloth is built. Both kinds of
//! constraint are XPBD constraints (Macklin et al. 2016) with compliance `1 / k` and their
//! multipliers kept over the iterations of a step (zeroed by [`Cloth::begin_step`]): the
//! cloth's stiffness depends neither on `dt` nor on the iteration count once the iterations
//! converge, which they do in a few sweeps while `k dt^2 / m` stays below about 1 (`m` a
//! particle's mass); a far stiffer cloth is as stiff as the iterations can make it. (A
//! 10 x 10 sheet hung from one side sags alike at 5 and 20 sweeps to 0.02 % at
//! `k dt^2 / m = 0.25`, 3 % at 1, 20 % at 2.5, by a factor 2.5 at 10.)
//!
//! The stiffness is a property of the mesh's springs, not of the tissue: for a mesh of
//! spacing `h` and a sheet of Young's modulus `E` and thickness `t`, `k_stretch` is of the
//! order of `E t` and `k_bend` of the order of `E t^3 / 12` (both nearly independent of `h`).
//!
//! Determinism: one sweep projects every edge, then every hinge, one after another in a fixed
//! order: colour by colour (`colour.rs`: constraints of one colour share no particle), and
//! within a colour edges by their particles, hinges by their edge. So the same inputs give
//! the same bytes, and a GPU that projects a colour's constraints all at once runs the same
//! sweep.

use super::{Particles, colour};
use crate::models::xpbd::{self, Bend, Stretch};
use glam::Vec3;

/// The cloth's two spring constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClothParams {
    /// Each edge's spring constant, N/m (compliance `1 / k`, m/N).
    pub stretch_stiffness_n_per_m: f32,
    /// Each hinge's angular spring constant, N m/rad (compliance `1 / k`, rad/(N m)).
    pub bend_stiffness_n_m_per_rad: f32,
}

impl ClothParams {
    /// Checks that both constants are positive finite numbers.
    pub fn validate(&self) -> Result<(), ClothError> {
        for (field, value) in [
            ("stretch_stiffness_n_per_m", self.stretch_stiffness_n_per_m),
            (
                "bend_stiffness_n_m_per_rad",
                self.bend_stiffness_n_m_per_rad,
            ),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ClothError::Stiffness { field, value });
            }
        }
        Ok(())
    }
}

/// Why a cloth was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClothError {
    #[error(
        "triangle {triangle}: corner {corner} is particle {particle}, which does not exist \
         ({len} particles)"
    )]
    NoParticle {
        triangle: usize,
        corner: usize,
        particle: u32,
        len: usize,
    },
    #[error("triangle {triangle}: particle {particle} is both corner {first} and corner {second}")]
    Repeated {
        triangle: usize,
        particle: u32,
        first: usize,
        second: usize,
    },
    #[error("triangle {triangle} (particles {corners:?}) has no area: its corners are in a line")]
    Degenerate { triangle: usize, corners: [u32; 3] },
    #[error("{field} must be a positive finite number (got {value})")]
    Stiffness { field: &'static str, value: f32 },
}

/// A triangle mesh of particles held by stretch and bending springs.
#[derive(Debug, Clone)]
pub struct Cloth {
    stretch: Vec<Stretch>,
    bend: Vec<Bend>,
    /// XPBD multipliers over the step, N s^2 (stretch) and N m s^2 (bending).
    stretch_lambda: Vec<f32>,
    bend_lambda: Vec<f32>,
    /// Each constraint's colour (`colour.rs`): the lists are sorted by it.
    stretch_colour: Vec<u32>,
    bend_colour: Vec<u32>,
    /// `1 / k`, m/N and rad/(N m).
    stretch_compliance: f32,
    bend_compliance: f32,
    /// The number of particles the constraints need (their largest index plus one).
    needs: usize,
}

/// One side of an edge as a triangle goes round it: the edge's particles sorted (its key),
/// the triangle, and the edge in the triangle's winding with the opposite corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Side {
    key: (u32, u32),
    triangle: u32,
    from: u32,
    to: u32,
    wing: u32,
}

impl Cloth {
    /// A cloth over `triangles` (indices into `particles`, wound consistently if the signs of
    /// its angles are to mean anything outside this module), at rest where the particles are
    /// now: one stretch constraint per distinct edge and one bending constraint per pair of
    /// triangles sharing an edge.
    pub fn new(
        particles: &Particles,
        triangles: &[[u32; 3]],
        params: ClothParams,
    ) -> Result<Cloth, ClothError> {
        params.validate()?;
        let n = particles.len();
        let mut sides = Vec::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for (corner, &i) in tri.iter().enumerate() {
                if i as usize >= n {
                    return Err(ClothError::NoParticle {
                        triangle: t,
                        corner,
                        particle: i,
                        len: n,
                    });
                }
            }
            for (first, second) in [(0, 1), (0, 2), (1, 2)] {
                if tri[first] == tri[second] {
                    return Err(ClothError::Repeated {
                        triangle: t,
                        particle: tri[first],
                        first,
                        second,
                    });
                }
            }
            let [a, b, c] = tri.map(|i| particles.x[i as usize]);
            let longest2 = (b - a)
                .length_squared()
                .max((c - b).length_squared())
                .max((a - c).length_squared());
            // Twice the area against the longest edge squared: 0 for corners in a line (and
            // false for non-finite positions).
            let area2 = (b - a).cross(c - a).length();
            if !(area2.is_finite() && area2 > 1e-6 * longest2) {
                return Err(ClothError::Degenerate {
                    triangle: t,
                    corners: *tri,
                });
            }
            for k in 0..3 {
                let (from, to, wing) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                sides.push(Side {
                    key: (from.min(to), from.max(to)),
                    triangle: t as u32,
                    from,
                    to,
                    wing,
                });
            }
        }
        sides.sort_unstable();
        let x = &particles.x;
        let mut stretch = Vec::new();
        let mut bend = Vec::new();
        for group in sides.chunk_by(|s, t| s.key == t.key) {
            let (a, b) = group[0].key;
            stretch.push(Stretch {
                a,
                b,
                rest_m: x[a as usize].distance(x[b as usize]),
            });
            // Every pair of the edge's triangles (one pair on a manifold mesh): the first's
            // winding gives the hinge and its wing c, so that n1 is its normal; the second is
            // the wing d, n2 its normal when it goes round the edge the other way.
            for (k, s) in group.iter().enumerate() {
                for o in &group[k + 1..] {
                    let mut h = Bend {
                        a: s.from,
                        b: s.to,
                        c: s.wing,
                        d: o.wing,
                        rest_rad: 0.0,
                    };
                    h.rest_rad = xpbd::dihedral(x, &h);
                    bend.push(h);
                }
            }
        }
        let needs = triangles
            .iter()
            .flatten()
            .map(|&i| i as usize + 1)
            .max()
            .unwrap_or(0);
        // Colour by colour (no two constraints of a colour share a particle): the order the
        // GPU's dispatches take them.
        let (stretch, stretch_colour) = colour::sorted(&stretch, |c| [c.a, c.b]);
        let (bend, bend_colour) = colour::sorted(&bend, |c| [c.a, c.b, c.c, c.d]);
        Ok(Cloth {
            stretch_lambda: vec![0.0; stretch.len()],
            bend_lambda: vec![0.0; bend.len()],
            stretch,
            bend,
            stretch_colour,
            bend_colour,
            stretch_compliance: 1.0 / params.stretch_stiffness_n_per_m,
            bend_compliance: 1.0 / params.bend_stiffness_n_m_per_rad,
            needs,
        })
    }

    /// Stretch constraints (distinct edges) left.
    pub fn edges(&self) -> usize {
        self.stretch.len()
    }

    /// Bending constraints (pairs of triangles sharing an edge) left.
    pub fn hinges(&self) -> usize {
        self.bend.len()
    }

    /// The stretch constraints, in projection order.
    pub fn stretch_constraints(&self) -> &[Stretch] {
        &self.stretch
    }

    /// The bending constraints, in projection order.
    pub fn bend_constraints(&self) -> &[Bend] {
        &self.bend
    }

    /// Each stretch and bending constraint's colour (their lists are sorted by it).
    pub fn colours(&self) -> (&[u32], &[u32]) {
        (&self.stretch_colour, &self.bend_colour)
    }

    /// The stretch and bending compliances, m/N and rad/(N m).
    pub fn compliances(&self) -> (f32, f32) {
        (self.stretch_compliance, self.bend_compliance)
    }

    /// Starts a step: the multipliers back to zero.
    pub fn begin_step(&mut self) {
        self.stretch_lambda.fill(0.0);
        self.bend_lambda.fill(0.0);
    }

    /// One Gauss-Seidel sweep of a step of `dt` seconds: every edge, then every hinge, in
    /// order. Does nothing when `dt` is not a positive number or `p` lacks the cloth's
    /// particles.
    pub fn project(&mut self, p: &mut Particles, dt: f32) {
        if !(dt.is_finite() && dt > 0.0) || p.len() < self.needs {
            return;
        }
        for (c, l) in self.stretch.iter().zip(&mut self.stretch_lambda) {
            *l += xpbd::project_stretch(&mut p.x, &p.w, c, self.stretch_compliance, dt, *l);
        }
        for (c, l) in self.bend.iter().zip(&mut self.bend_lambda) {
            *l += xpbd::project_bend(&mut p.x, &p.w, c, self.bend_compliance, dt, *l);
        }
    }

    /// Removes every edge with an end, and every hinge with one of its four particles, within
    /// `radius_m` of `centre` (m): the hook's or the scissors' cut. A hinge goes with any of
    /// its particles because a triangle that lost a corner's edges bends no more. Returns how
    /// many constraints (edges and hinges) were removed.
    pub fn cut_near(&mut self, centre: Vec3, radius_m: f32, p: &Particles) -> usize {
        if radius_m.is_nan() || radius_m < 0.0 || p.len() < self.needs {
            return 0;
        }
        let r2 = radius_m * radius_m;
        let near = |i: u32| p.x[i as usize].distance_squared(centre) <= r2;
        let before = self.stretch.len() + self.bend.len();
        retain_with(
            &mut self.stretch,
            &mut self.stretch_lambda,
            &mut self.stretch_colour,
            |c| !(near(c.a) || near(c.b)),
        );
        retain_with(
            &mut self.bend,
            &mut self.bend_lambda,
            &mut self.bend_colour,
            |c| ![c.a, c.b, c.c, c.d].into_iter().any(near),
        );
        before - self.stretch.len() - self.bend.len()
    }

    /// The largest edge strain `|C| / l0` (dimensionless; 0 with no edges or when `p` lacks the
    /// cloth's particles).
    pub fn max_stretch_strain(&self, p: &Particles) -> f32 {
        if p.len() < self.needs {
            return 0.0;
        }
        self.stretch
            .iter()
            .filter(|c| c.rest_m > 0.0)
            .map(|c| {
                let len = p.x[c.a as usize].distance(p.x[c.b as usize]);
                (len - c.rest_m).abs() / c.rest_m
            })
            .fold(0.0, f32::max)
    }

    /// The largest hinge error `|phi - phi0|`, radians (the shorter way round, so at most pi;
    /// an angle needs no further normalising), over the hinges that are not degenerate now.
    pub fn max_bend_error(&self, p: &Particles) -> f32 {
        if p.len() < self.needs {
            return 0.0;
        }
        self.bend
            .iter()
            .filter_map(|c| xpbd::bend_gradient(&p.x, c))
            .map(|(c, _)| c.abs())
            .fold(0.0, f32::max)
    }

    /// Heap bytes.
    pub fn heap_bytes(&self) -> usize {
        self.stretch.capacity() * std::mem::size_of::<Stretch>()
            + self.bend.capacity() * std::mem::size_of::<Bend>()
            + (self.stretch_lambda.capacity() + self.bend_lambda.capacity()) * 4
    }
}

/// Keeps the items (and their multipliers and colours, side by side) for which `keep` holds,
/// in order.
fn retain_with<T>(
    items: &mut Vec<T>,
    lambda: &mut Vec<f32>,
    colour: &mut Vec<u32>,
    keep: impl Fn(&T) -> bool,
) {
    let mut kept = 0;
    for i in 0..items.len() {
        if keep(&items[i]) {
            items.swap(kept, i);
            lambda.swap(kept, i);
            colour.swap(kept, i);
            kept += 1;
        }
    }
    items.truncate(kept);
    lambda.truncate(kept);
    colour.truncate(kept);
}

#[cfg(test)]
#[path = "cloth_tests.rs"]
mod tests;
