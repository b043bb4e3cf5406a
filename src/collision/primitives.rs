//! Collision primitives for models that are not triangle meshes: sphere sets (mass-spring and
//! shape-matching clusters), capsule sets (instrument shafts and jaws) and generalized cylinders
//! (Cosserat rods and catheters: a centreline with a radius per point).
//!
//! The three share one set of queries (ray cast, signed distance, features near a point, contacts
//! with a rigid sphere tool), and every answer names the *feature* it concerns: a sphere, a
//! capsule, or a segment of the centreline. All of them reduce to one convex shape, the round
//! cone: the convex hull of two spheres. A sphere is a round cone whose two spheres coincide; a
//! capsule is one whose radii are equal. Distances and queries are exact (analytic), in metres.
//!
//! The sets borrow the model's own arrays; build them with `new` (which checks the arrays) or,
//! on hot paths where the arrays are known good, directly from the public fields. A set built
//! directly whose arrays differ in length uses only the entries all of them have.

use glam::Vec3;

/// Why a primitive set could not be built from the given arrays.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrimitiveError {
    /// Two arrays that must have one entry each per feature (or per point) differ in length.
    #[error("{array} has {found} entries but {expected} were expected (one per {per})")]
    LengthMismatch {
        array: &'static str,
        per: &'static str,
        expected: usize,
        found: usize,
    },
    /// A radius (metres) is not finite or not strictly positive.
    #[error("radius at index {index} is {value} m; every radius must be finite and > 0")]
    BadRadius { index: usize, value: f32 },
    /// A point (metres) has a non-finite coordinate.
    #[error("{array} at index {index} is {value}; every point must be finite")]
    BadPoint {
        array: &'static str,
        index: usize,
        value: Vec3,
    },
}

/// Where a ray first met a primitive set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrimitiveHit {
    /// The feature hit: sphere or capsule index, or centreline segment index.
    pub feature: u32,
    /// Where on the feature, as a parameter along its segment from 0 (first end) to 1 (second
    /// end); 0 for spheres. For a tapered segment this is the parameter of the inscribed sphere
    /// whose surface touches the hit point.
    pub t: f32,
    /// Distance along the unit ray, metres; 0 when the ray starts inside the set.
    pub distance_m: f32,
    /// The hit point, metres.
    pub point: Vec3,
    /// Unit outward surface normal at the hit point; `-dir` when the ray starts inside.
    pub normal: Vec3,
}

/// A rigid sphere tool penetrating one feature of a primitive set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceContact {
    /// The feature penetrated: sphere or capsule index, or centreline segment index.
    pub feature: u32,
    /// Parameter along the feature's segment (0..1) of the contact point; 0 for spheres.
    pub t: f32,
    /// The point of the primitive's surface nearest the tool's centre, metres.
    pub point: Vec3,
    /// Unit outward normal of the primitive at `point`.
    pub normal: Vec3,
    /// How far the tool sphere reaches into the primitive, metres (> 0).
    pub depth_m: f32,
}

/// A set of independent spheres; feature id = sphere index.
#[derive(Debug, Clone, Copy)]
pub struct SphereSet<'a> {
    /// Sphere centres, metres.
    pub centers: &'a [Vec3],
    /// Sphere radii, metres, one per centre.
    pub radii: &'a [f32],
}

/// A set of independent capsules: capsule `i` is the segment `a[i]`–`b[i]` swept by a sphere of
/// radius `radii[i]`; feature id = capsule index.
#[derive(Debug, Clone, Copy)]
pub struct CapsuleSet<'a> {
    /// First end of each capsule's segment, metres.
    pub a: &'a [Vec3],
    /// Second end of each capsule's segment, metres.
    pub b: &'a [Vec3],
    /// Capsule radii, metres, one per capsule.
    pub radii: &'a [f32],
}

/// A tube along a polyline with a radius per point. Segment `i` (feature id `i`) is the convex
/// hull of the spheres (`centreline[i]`, `radii[i]`) and (`centreline[i + 1]`, `radii[i + 1]`),
/// a tapered capsule (round cone); the shape is the union of its segments. A single point is a
/// sphere (feature 0).
#[derive(Debug, Clone, Copy)]
pub struct GeneralizedCylinder<'a> {
    /// Centreline points, metres.
    pub centreline: &'a [Vec3],
    /// Tube radius at each centreline point, metres.
    pub radii: &'a [f32],
}

fn check_lengths(
    array: &'static str,
    per: &'static str,
    expected: usize,
    found: usize,
) -> Result<(), PrimitiveError> {
    if expected == found {
        Ok(())
    } else {
        Err(PrimitiveError::LengthMismatch {
            array,
            per,
            expected,
            found,
        })
    }
}

fn check_points(array: &'static str, points: &[Vec3]) -> Result<(), PrimitiveError> {
    match points.iter().position(|p| !p.is_finite()) {
        Some(index) => Err(PrimitiveError::BadPoint {
            array,
            index,
            value: points[index],
        }),
        None => Ok(()),
    }
}

fn check_radii(radii: &[f32]) -> Result<(), PrimitiveError> {
    match radii.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
        Some(index) => Err(PrimitiveError::BadRadius {
            index,
            value: radii[index],
        }),
        None => Ok(()),
    }
}

impl<'a> SphereSet<'a> {
    /// Checks that there is one radius per centre, that every radius is finite and > 0 (metres)
    /// and every centre finite.
    pub fn new(centers: &'a [Vec3], radii: &'a [f32]) -> Result<Self, PrimitiveError> {
        check_lengths("radii", "centre", centers.len(), radii.len())?;
        check_radii(radii)?;
        check_points("centers", centers)?;
        Ok(Self { centers, radii })
    }
}

impl<'a> CapsuleSet<'a> {
    /// Checks that `a`, `b` and `radii` have the same length, that every radius is finite and
    /// positive (metres) and every end point finite.
    pub fn new(a: &'a [Vec3], b: &'a [Vec3], radii: &'a [f32]) -> Result<Self, PrimitiveError> {
        check_lengths("b", "first end", a.len(), b.len())?;
        check_lengths("radii", "capsule", a.len(), radii.len())?;
        check_radii(radii)?;
        check_points("a", a)?;
        check_points("b", b)?;
        Ok(Self { a, b, radii })
    }
}

impl<'a> GeneralizedCylinder<'a> {
    /// Checks that there is one radius per centreline point, that every radius is finite and
    /// positive (metres) and every point finite.
    pub fn new(centreline: &'a [Vec3], radii: &'a [f32]) -> Result<Self, PrimitiveError> {
        check_lengths("radii", "centreline point", centreline.len(), radii.len())?;
        check_radii(radii)?;
        check_points("centreline", centreline)?;
        Ok(Self { centreline, radii })
    }
}

/// One feature, ready for queries: a sphere, or a round cone whose spheres do not contain
/// each other.
#[derive(Debug, Clone, Copy)]
enum Shape {
    /// A sphere; `t` is the segment parameter its answers carry (0 or 1).
    Ball {
        c: Vec3,
        r: f32,
        t: f32,
    },
    Cone(Cone),
}

/// The convex hull of spheres (a, ra) and (b, rb), with `len > |ra - rb|`. In the half-plane
/// (x along the axis from a, y away from it) the lateral surface is the line tangent to both
/// circles; its outward normal is (sin, cos) with sin = (ra - rb) / len.
#[derive(Debug, Clone, Copy)]
struct Cone {
    a: Vec3,
    b: Vec3,
    /// Unit axis from a to b.
    u: Vec3,
    len: f32,
    ra: f32,
    rb: f32,
    sin: f32,
    cos: f32,
}

/// The nearest surface point's description: signed distance (metres, negative inside), segment
/// parameter and unit outward normal.
#[derive(Debug, Clone, Copy)]
struct Closest {
    sd: f32,
    t: f32,
    normal: Vec3,
}

/// A ray's entry into one feature: distance (metres), segment parameter, unit outward normal.
#[derive(Debug, Clone, Copy)]
struct Entry {
    dist: f32,
    t: f32,
    normal: Vec3,
}

impl Shape {
    fn ball(c: Vec3, r: f32) -> Self {
        Shape::Ball { c, r, t: 0.0 }
    }

    /// The convex hull of spheres (a, ra) and (b, rb); the bigger sphere alone when it contains
    /// the other (ties to a).
    fn round_cone(a: Vec3, b: Vec3, ra: f32, rb: f32) -> Self {
        let d = b - a;
        let len = d.length();
        let bigger = if ra >= rb {
            Shape::Ball {
                c: a,
                r: ra,
                t: 0.0,
            }
        } else {
            Shape::Ball {
                c: b,
                r: rb,
                t: 1.0,
            }
        };
        if len <= (ra - rb).abs() {
            return bigger;
        }
        let sin = (ra - rb) / len;
        let cos = ((1.0 - sin) * (1.0 + sin)).max(0.0).sqrt();
        if !(sin.abs() < 1.0 && cos > 0.0) {
            return bigger;
        }
        Shape::Cone(Cone {
            a,
            b,
            u: d / len,
            len,
            ra,
            rb,
            sin,
            cos,
        })
    }

    /// A sphere containing the feature: centre and radius, metres.
    fn bound(&self) -> (Vec3, f32) {
        match *self {
            Shape::Ball { c, r, .. } => (c, r),
            Shape::Cone(k) => ((k.a + k.b) * 0.5, 0.5 * k.len + k.ra.max(k.rb)),
        }
    }

    fn closest(&self, p: Vec3) -> Closest {
        match *self {
            Shape::Ball { c, r, t } => {
                let q = p - c;
                let d = q.length();
                let normal = if d > 0.0 { q / d } else { Vec3::Z };
                Closest {
                    sd: d - r,
                    t,
                    normal,
                }
            }
            Shape::Cone(k) => k.closest(p),
        }
    }

    /// Where a ray (unit `dir`) starting outside this feature first enters it, at a
    /// non-negative distance; `o_s` is the ray's point nearest the feature's bounding centre,
    /// `t_c` its distance along the ray (computing relative to it keeps the quadratics small).
    /// Entries up to `tol` metres behind the origin (rounding) count as entries at 0.
    fn entry(&self, o_s: Vec3, t_c: f32, dir: Vec3, tol: f32) -> Option<Entry> {
        match *self {
            Shape::Ball { c, r, t } => {
                let tau = sphere_near_root(o_s - c, dir, r)?;
                let dist = t_c + tau;
                (dist >= -tol).then(|| Entry {
                    dist: dist.max(0.0),
                    t,
                    normal: (o_s + dir * tau - c).normalize_or(-dir),
                })
            }
            Shape::Cone(k) => k.entry(o_s, t_c, dir, tol),
        }
    }
}

/// The nearer intersection (may be negative) of the line `rel + tau * dir` with the sphere of
/// radius `r` at the origin; None when it misses.
fn sphere_near_root(rel: Vec3, dir: Vec3, r: f32) -> Option<f32> {
    let b = rel.dot(dir);
    // |rel|² - b² is the squared distance from the centre to the line, computed from its
    // perpendicular part to avoid cancellation.
    let perp = rel - dir * b;
    let disc = (r - perp.length()) * (r + perp.length());
    (disc >= 0.0).then(|| -b - disc.sqrt())
}

impl Cone {
    /// The half-plane coordinates of `q` (relative to a): axial x, radial vector, its length y.
    fn coords(&self, q: Vec3) -> (f32, Vec3, f32) {
        let x = q.dot(self.u);
        let radial = q - self.u * x;
        (x, radial, radial.length())
    }

    fn closest(&self, p: Vec3) -> Closest {
        let q = p - self.a;
        let (x, radial, y) = self.coords(q);
        // Position along the lateral line, 0 at its tangent point on sphere a and len * cos at
        // its tangent point on sphere b.
        let w = x * self.cos - y * self.sin;
        let band = self.len * self.cos;
        if w <= 0.0 {
            let d = q.length();
            Closest {
                sd: d - self.ra,
                t: 0.0,
                normal: if d > 0.0 { q / d } else { -self.u },
            }
        } else if w >= band {
            let qb = p - self.b;
            let d = qb.length();
            Closest {
                sd: d - self.rb,
                t: 1.0,
                normal: if d > 0.0 { qb / d } else { self.u },
            }
        } else {
            let e = if y > 0.0 {
                radial / y
            } else {
                self.u.any_orthonormal_vector()
            };
            Closest {
                sd: x * self.sin + y * self.cos - self.ra,
                t: (w / band).clamp(0.0, 1.0),
                normal: (self.u * self.sin + e * self.cos).normalize_or(e),
            }
        }
    }

    /// The lateral-surface hit at `tau` along the ray from `o` (relative to a), if it lies on
    /// the band between the tangent circles: (segment parameter, outward normal).
    fn on_band(&self, o: Vec3, dir: Vec3, tau: f32) -> Option<(f32, Vec3)> {
        let (x, radial, y) = self.coords(o + dir * tau);
        let w = x * self.cos - y * self.sin;
        let band = self.len * self.cos;
        // The other nappe of the double cone has ra - x sin < 0.
        if !(self.ra - x * self.sin >= 0.0 && (0.0..=band).contains(&w) && y > 0.0) {
            return None;
        }
        let e = radial / y;
        Some((w / band, (self.u * self.sin + e * self.cos).normalize_or(e)))
    }

    fn entry(&self, o_s: Vec3, t_c: f32, dir: Vec3, tol: f32) -> Option<Entry> {
        let mut best: Option<Entry> = None;
        let mut offer = |e: Entry| {
            if e.dist < -tol {
                return;
            }
            let e = Entry {
                dist: e.dist.max(0.0),
                ..e
            };
            if best.is_none_or(|b| e.dist < b.dist) {
                best = Some(e);
            }
        };
        // The shape is sphere a ∪ sphere b ∪ the frustum between the tangent circles. From
        // outside, its entry is the earliest of: each sphere's near root, and the lateral band.
        for (c, r, t) in [(self.a, self.ra, 0.0), (self.b, self.rb, 1.0)] {
            if let Some(tau) = sphere_near_root(o_s - c, dir, r) {
                offer(Entry {
                    dist: t_c + tau,
                    t,
                    normal: (o_s + dir * tau - c).normalize_or(-dir),
                });
            }
        }
        // Lateral surface: cos² y² = (ra - sin x)² along x = ox + tau dx, y² = |op + tau dp|².
        let o = o_s - self.a;
        let (ox, op, y0) = self.coords(o);
        let dx = dir.dot(self.u);
        let dp = dir - self.u * dx;
        let h = self.ra - self.sin * ox;
        // dir is unit, so |dp|² = 1 - dx² and cos² |dp|² - sin² dx² = cos² - dx².
        let qa = (self.cos - dx) * (self.cos + dx);
        let qb = self.cos * self.cos * op.dot(dp) + h * self.sin * dx;
        let qc = (self.cos * y0 - h) * (self.cos * y0 + h);
        let disc = qb * qb - qa * qc;
        if disc >= 0.0 {
            // qa tau² + 2 qb tau + qc = 0, roots without cancellation.
            let q = -(qb + qb.signum() * disc.sqrt());
            let roots = if q != 0.0 {
                [qc / q, q / qa]
            } else {
                [-qb / qa, f32::NAN]
            };
            for tau in roots.into_iter().filter(|tau| tau.is_finite()) {
                // Only entering crossings: from outside, the convex surface's exit comes after
                // its entry anyway; this keeps a rounding-missed entry from reporting the exit.
                if let Some((t, normal)) = self.on_band(o, dir, tau).filter(|h| h.1.dot(dir) < 0.0)
                {
                    offer(Entry {
                        dist: t_c + tau,
                        t,
                        normal,
                    });
                }
            }
        }
        best
    }
}

/// The features of a primitive set, as shapes.
trait Features {
    fn count(&self) -> usize;
    /// Feature `i < count()`.
    fn shape(&self, i: usize) -> Shape;
}

impl Features for SphereSet<'_> {
    fn count(&self) -> usize {
        self.centers.len().min(self.radii.len())
    }
    fn shape(&self, i: usize) -> Shape {
        Shape::ball(self.centers[i], self.radii[i])
    }
}

impl Features for CapsuleSet<'_> {
    fn count(&self) -> usize {
        self.a.len().min(self.b.len()).min(self.radii.len())
    }
    fn shape(&self, i: usize) -> Shape {
        let r = self.radii[i];
        Shape::round_cone(self.a[i], self.b[i], r, r)
    }
}

impl Features for GeneralizedCylinder<'_> {
    fn count(&self) -> usize {
        let points = self.centreline.len().min(self.radii.len());
        if points == 1 {
            1
        } else {
            points.saturating_sub(1)
        }
    }
    fn shape(&self, i: usize) -> Shape {
        if self.centreline.len().min(self.radii.len()) == 1 {
            return Shape::ball(self.centreline[0], self.radii[0]);
        }
        Shape::round_cone(
            self.centreline[i],
            self.centreline[i + 1],
            self.radii[i],
            self.radii[i + 1],
        )
    }
}

/// Every feature with its id (features past `u32::MAX` are not addressable and ignored).
fn features<F: Features>(set: &F) -> impl Iterator<Item = (u32, Shape)> + '_ {
    (0..set.count().min(u32::MAX as usize)).map(|i| (i as u32, set.shape(i)))
}

/// Slack on bounding-sphere rejections, metres, so rounding never rejects a true answer.
fn bound_slack(r: f32) -> f32 {
    r * 1e-5 + 1e-7
}

fn cast_ray_in<F: Features>(set: &F, origin: Vec3, dir: Vec3, max_m: f32) -> Option<PrimitiveHit> {
    if !(origin.is_finite() && dir.is_finite() && max_m >= 0.0 && !max_m.is_nan()) {
        return None;
    }
    let dir = dir.try_normalize()?;
    let mut best: Option<PrimitiveHit> = None;
    for (feature, shape) in features(set) {
        let limit = best.map_or(max_m, |h| h.distance_m);
        let (centre, r) = shape.bound();
        let r = r + bound_slack(r);
        let rel = centre - origin;
        let t_c = rel.dot(dir);
        let o_s = origin + dir * t_c;
        if (o_s - centre).length_squared() > r * r || t_c + r < 0.0 || t_c - r > limit {
            continue;
        }
        // Rounding of the entry distance, metres.
        let tol = 4.0 * f32::EPSILON * (t_c.abs() + r);
        let inside = (rel.length_squared() <= r * r)
            .then(|| shape.closest(origin))
            .filter(|c| c.sd <= 0.0);
        let entry = match inside {
            Some(c) => Some(Entry {
                dist: 0.0,
                t: c.t,
                normal: -dir,
            }),
            None => shape.entry(o_s, t_c, dir, tol),
        };
        let Some(e) = entry else { continue };
        if e.dist <= limit && best.is_none_or(|h| e.dist < h.distance_m) {
            best = Some(PrimitiveHit {
                feature,
                t: e.t,
                distance_m: e.dist,
                point: if e.dist > 0.0 {
                    origin + dir * e.dist
                } else {
                    origin
                },
                normal: e.normal,
            });
        }
    }
    best
}

fn distance_in<F: Features>(set: &F, p: Vec3) -> Option<(f32, u32, f32)> {
    if !p.is_finite() {
        return None;
    }
    let mut best: Option<(f32, u32, f32)> = None;
    for (feature, shape) in features(set) {
        let (centre, r) = shape.bound();
        // The feature's distance is at least the bound's.
        if best.is_some_and(|b| (p - centre).length() - r - bound_slack(r) > b.0) {
            continue;
        }
        let c = shape.closest(p);
        if best.is_none_or(|b| c.sd < b.0) {
            best = Some((c.sd, feature, c.t));
        }
    }
    best
}

/// Each feature whose signed surface distance from `p` is at most `reach` (metres), with its
/// nearest-point description, in feature order.
fn within<F: Features>(set: &F, p: Vec3, reach: f32) -> impl Iterator<Item = (u32, Closest)> + '_ {
    let valid = p.is_finite() && reach.is_finite();
    features(set)
        .take_while(move |_| valid)
        .filter_map(move |(feature, shape)| {
            let (centre, r) = shape.bound();
            if (p - centre).length() - r - bound_slack(r) > reach {
                return None;
            }
            let c = shape.closest(p);
            (c.sd <= reach).then_some((feature, c))
        })
}

fn nearest_within_in<F: Features>(set: &F, center: Vec3, radius_m: f32) -> Vec<(f32, u32)> {
    let mut found: Vec<(f32, u32)> = within(set, center, radius_m)
        .map(|(feature, c)| (c.sd, feature))
        .collect();
    found.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    found
}

fn sphere_contacts_in<F: Features>(set: &F, center: Vec3, radius_m: f32) -> Vec<SurfaceContact> {
    within(set, center, radius_m)
        .filter(|(_, c)| c.sd < radius_m)
        .map(|(feature, c)| SurfaceContact {
            feature,
            t: c.t,
            point: center - c.normal * c.sd,
            normal: c.normal,
            depth_m: radius_m - c.sd,
        })
        .collect()
}

macro_rules! primitive_queries {
    ($set:ident) => {
        impl $set<'_> {
            /// How many features the set has (ids `0..feature_count()`).
            pub fn feature_count(&self) -> usize {
                Features::count(self)
            }

            /// The nearest point where a ray from `origin` along `dir` (unit; normalized if not)
            /// enters the set within `max_m` metres, over all features (ties to the lowest
            /// feature id). A ray starting inside or on a feature hits it at distance 0 with
            /// normal `-dir`. None on a miss or non-finite input.
            pub fn cast_ray(&self, origin: Vec3, dir: Vec3, max_m: f32) -> Option<PrimitiveHit> {
                cast_ray_in(self, origin, dir, max_m)
            }

            /// The nearest feature to `p`: (signed distance to its surface in metres, negative
            /// inside; feature id; segment parameter 0..1 of the nearest surface point). Ties go
            /// to the lowest feature id. None for an empty set or a non-finite `p`.
            pub fn distance(&self, p: Vec3) -> Option<(f32, u32, f32)> {
                distance_in(self, p)
            }

            /// The features whose surface lies within `radius_m` metres of `center` (signed
            /// surface distance <= `radius_m`), as (signed distance in metres, feature id),
            /// nearest first, ties by feature id.
            pub fn nearest_within(&self, center: Vec3, radius_m: f32) -> Vec<(f32, u32)> {
                nearest_within_in(self, center, radius_m)
            }

            /// Every feature a rigid sphere tool (centre `center`, radius `radius_m`, metres)
            /// penetrates, with the point of the feature's surface nearest the tool's centre,
            /// the feature's outward normal there and the depth, sorted by feature id.
            pub fn sphere_contacts(&self, center: Vec3, radius_m: f32) -> Vec<SurfaceContact> {
                sphere_contacts_in(self, center, radius_m)
            }
        }
    };
}

primitive_queries!(SphereSet);
primitive_queries!(CapsuleSet);
primitive_queries!(GeneralizedCylinder);

#[cfg(test)]
#[path = "primitives_tests.rs"]
mod tests;
