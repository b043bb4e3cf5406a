//! A thin instrument against the wall's surface. The catheter's balls are wider than the
//! gaps between the wall's balls, so ball against ball holds it (the paper's Fig. 5); a
//! guidewire a tenth as wide would slip between them. The wire's balls collide instead with
//! the wall's central surface (the triangles between neighbouring rings, as drawn),
//! thickened by half the wall: each wire ball touches at most one triangle a substep (the
//! deepest, so that a ball on an edge is not pushed twice), the contact law's force acts
//! along the line from the nearest point of the triangle to the ball (inwards, for a ball
//! pushed past the central surface: the triangles are wound outwards), and the wall takes the
//! opposite force shared among the triangle's three balls by the nearest point's barycentric
//! weights (a force spread by area, not put on one ball).

use super::Balls;
use super::contact::{ContactForce, ContactLaw};
use super::vessel::Vessel;
use glam::DVec3;

/// One instrument ball touching one wall triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    pub ball: u32,
    pub triangle: u32,
    /// The nearest point's weights on the triangle's three balls (summing to 1).
    pub weights: [f64; 3],
    pub depth_m: f64,
    /// From the surface towards the instrument's ball.
    pub normal: DVec3,
}

/// The wall's triangles and which triangles each wall ball is a corner of.
#[derive(Debug, Clone, PartialEq)]
pub struct WallSurface {
    pub triangles: Vec<[u32; 3]>,
    of_ball: Vec<Vec<u32>>,
    /// The longest edge at rest, m: a ball touching a triangle is within this (and the
    /// touch's reach) of one of its corners.
    longest_edge_m: f64,
}

impl WallSurface {
    pub fn new(vessel: &Vessel) -> WallSurface {
        let triangles = vessel.triangles();
        let mut of_ball = vec![Vec::new(); vessel.balls.len()];
        let mut longest: f64 = 0.0;
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                of_ball[tri[k] as usize].push(t as u32);
                let (a, b) = (
                    vessel.rest[tri[k] as usize],
                    vessel.rest[tri[(k + 1) % 3] as usize],
                );
                longest = longest.max(a.distance(b));
            }
        }
        WallSurface {
            triangles,
            of_ball,
            longest_edge_m: longest,
        }
    }

    /// The (ball, triangle) pairs that may touch this step: for each of `balls` from `from`
    /// on, the triangles whose nearest point is within the ball's reach (its radius and half
    /// the wall) and `margin_m`, none with a corner in `holes`, found among the triangles
    /// of the wall balls within that reach and a stretched edge (1.2 times the longest at
    /// rest); in ball order, each ball's triangles ascending. Returns the ball pairs tested.
    pub fn candidates(
        &self,
        balls: &Balls,
        from: usize,
        vessel: &Vessel,
        holes: &[bool],
        margin_m: f64,
        out: &mut Vec<(u32, u32)>,
    ) -> u64 {
        self.candidates_of(balls, (from, &[]), vessel, holes, margin_m, out)
    }

    /// [`WallSurface::candidates`] leaving out the balls marked in `skip` (those another
    /// body shields from the wall).
    pub fn candidates_of(
        &self,
        balls: &Balls,
        (from, skip): (usize, &[bool]),
        vessel: &Vessel,
        holes: &[bool],
        margin_m: f64,
        out: &mut Vec<(u32, u32)>,
    ) -> u64 {
        out.clear();
        let mut near = Vec::new();
        // The shielded balls are left out of the wide search too.
        let tests = super::collision::detect_skipping(
            balls,
            (from, skip),
            vessel,
            holes,
            margin_m + 1.2 * self.longest_edge_m,
            &mut near,
        );
        let half_wall = 0.5 * vessel.params.wall_m;
        let mut start = 0;
        let mut tris: Vec<u32> = Vec::new();
        while start < near.len() {
            let ball = near[start].catheter;
            let end = start + near[start..].partition_point(|h| h.catheter == ball);
            if skip.get(ball as usize).copied().unwrap_or(false) {
                start = end;
                continue;
            }
            let x = balls.x[ball as usize];
            let reach = balls.radius_m[ball as usize] + half_wall + margin_m;
            tris.clear();
            tris.extend(
                near[start..end]
                    .iter()
                    .flat_map(|h| self.of_ball[h.wall as usize].iter().copied()),
            );
            tris.sort_unstable();
            tris.dedup();
            out.extend(
                tris.iter()
                    .copied()
                    .filter(|&t| {
                        let tri = self.triangles[t as usize];
                        if tri
                            .iter()
                            .any(|&c| holes.get(c as usize).copied().unwrap_or(false))
                        {
                            return false;
                        }
                        let [a, b, c] = tri.map(|k| vessel.balls.x[k as usize]);
                        nearest_on_triangle(x, a, b, c).0.distance_squared(x) <= reach * reach
                    })
                    .map(|t| (ball, t)),
            );
            start = end;
        }
        tests
    }

    /// The candidates that touch where the balls are now: for each ball its deepest
    /// triangle (the first of equals), in ball order.
    pub fn narrow(
        &self,
        candidates: &[(u32, u32)],
        balls: &Balls,
        vessel: &Vessel,
        out: &mut Vec<SurfaceHit>,
    ) {
        out.clear();
        let reach_wall = 0.5 * vessel.params.wall_m;
        for &(ball, t) in candidates {
            let i = ball as usize;
            let tri = self.triangles[t as usize];
            let [a, b, c] = tri.map(|k| vessel.balls.x[k as usize]);
            let (p, weights) = nearest_on_triangle(balls.x[i], a, b, c);
            let d = balls.x[i] - p;
            let dist = d.length();
            // The triangles are wound outwards: a ball whose centre has crossed the central
            // surface within a face is pushed back in, its depth counted through it (at an
            // edge or corner the line to the ball decides: a seam with another tube's wall
            // is no face to be behind).
            let outward = (b - a).cross(c - a).normalize_or_zero();
            let in_face = weights.iter().all(|&w| w > 0.0);
            let (depth, normal) = if in_face && d.dot(outward) > 0.0 {
                (balls.radius_m[i] + reach_wall + dist, -outward)
            } else if dist > 0.0 {
                (balls.radius_m[i] + reach_wall - dist, d / dist)
            } else {
                (balls.radius_m[i] + reach_wall, -outward)
            };
            if depth <= 0.0 || normal == DVec3::ZERO {
                continue;
            }
            let hit = SurfaceHit {
                ball,
                triangle: t,
                weights,
                depth_m: depth,
                normal,
            };
            match out.last_mut() {
                Some(last) if last.ball == ball => {
                    if depth > last.depth_m {
                        *last = hit;
                    }
                }
                _ => out.push(hit),
            }
        }
    }

    /// The hits' forces: added to `on_balls` (per instrument ball) and, with the opposite
    /// sign shared by the weights, to `on_wall` (per wall ball); each hit's force on the
    /// instrument is returned in hit order. The wall's speed at the touch is its corners'
    /// by the same weights.
    pub fn forces(
        &self,
        hits: &[SurfaceHit],
        law: &ContactLaw,
        balls: &Balls,
        vessel: &Vessel,
        on_balls: &mut [DVec3],
        on_wall: &mut [DVec3],
    ) -> Vec<ContactForce> {
        hits.iter()
            .map(|h| {
                let tri = self.triangles[h.triangle as usize];
                let wall_v: DVec3 = tri
                    .iter()
                    .zip(h.weights)
                    .map(|(&k, w)| vessel.balls.v[k as usize] * w)
                    .sum();
                let f = law.force(h.depth_m, h.normal, balls.v[h.ball as usize] - wall_v);
                on_balls[h.ball as usize] += f.total();
                for (&k, w) in tri.iter().zip(h.weights) {
                    on_wall[k as usize] -= f.total() * w;
                }
                f
            })
            .collect()
    }
}

/// The point of triangle `abc` nearest `p`, and its barycentric weights on `a`, `b`, `c`
/// (by regions of the triangle's corners, edges and face).
pub fn nearest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, [f64; 3]) {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, [0.0, 1.0 - w, w]);
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (a + ab * v + ac * w, [1.0 - v - w, v, w])
}

#[cfg(test)]
#[path = "surface_tests.rs"]
mod tests;
