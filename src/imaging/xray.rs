//! X-ray projection (fluoroscopy) of a scene of convex bodies: the C-arm's source is a point,
//! its detector a grid of pixels, and each pixel receives `N0 exp(-sum over materials of
//! mu_m L_m)` photons (Beer-Lambert), `L_m` the length of the ray from the source to the pixel
//! inside material `m` (bodies of one material that overlap count once: their intervals along
//! the ray are merged), `mu_m` its linear attenuation coefficient, 1/m. Quantum noise: the
//! count is Poisson, drawn here as a normal of mean and variance N (N is large wherever the
//! image is worth looking at), from a seeded generator so a frame is the same on every
//! machine. The image shown is the log of the transmission, as a fluoroscope shows it: dark
//! where the ray crossed much attenuation.
//!
//! Speed: the detector is cut into tiles of 16 x 16 pixels, and a tile's rays are tested only
//! against the bodies whose bounding spheres they can meet (a cone about the tile's centre ray
//! against each sphere's cone from the source), so a frame costs about pixels x (bodies a tile
//! sees) rather than pixels x bodies; rows are exposed in parallel, each row's noise from its
//! own seed, so the frame does not depend on the threads.

use glam::DVec3;
use rayon::prelude::*;

/// A convex body of one material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Body {
    Sphere {
        centre: DVec3,
        radius: f64,
    },
    /// The points within `radius` of the segment from `a` to `b` (a tube with round ends).
    Capsule {
        a: DVec3,
        b: DVec3,
        radius: f64,
    },
    /// A cylinder with flat ends from `a` to `b`.
    Cylinder {
        a: DVec3,
        b: DVec3,
        radius: f64,
    },
}

/// Where a ray `o + t d` (d unit) is inside a body: `[t0, t1]`, if it is.
pub fn chord(body: &Body, o: DVec3, d: DVec3) -> Option<(f64, f64)> {
    match *body {
        Body::Sphere { centre, radius } => sphere(o, d, centre, radius),
        Body::Capsule { a, b, radius } => {
            // Convex: the union of the tube and the two end spheres is one interval.
            let parts = [
                tube(o, d, a, b, radius),
                sphere(o, d, a, radius),
                sphere(o, d, b, radius),
            ];
            parts
                .into_iter()
                .flatten()
                .fold(None, |acc: Option<(f64, f64)>, (s, e)| {
                    Some(acc.map_or((s, e), |(x, y)| (x.min(s), y.max(e))))
                })
        }
        Body::Cylinder { a, b, radius } => tube(o, d, a, b, radius),
    }
}

fn sphere(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<(f64, f64)> {
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - r * r);
    (disc > 0.0).then(|| {
        let s = disc.sqrt();
        (-b - s, -b + s)
    })
}

/// The ray inside the infinite cylinder about `a`-`b` of radius `r`, cut to the slab between
/// the planes through `a` and `b`: a cylinder with flat ends (a capsule adds its end spheres).
fn tube(o: DVec3, d: DVec3, a: DVec3, b: DVec3, r: f64) -> Option<(f64, f64)> {
    let axis = b - a;
    let len = axis.length();
    if len <= 0.0 {
        return None;
    }
    let u = axis / len;
    // Across the axis.
    let (oa, dp) = (o - a, d - u * d.dot(u));
    let op = oa - u * oa.dot(u);
    let qa = dp.length_squared();
    let (mut t0, mut t1) = if qa < 1e-18 {
        // Along the axis: inside the side for every t, or never.
        if op.length_squared() < r * r {
            (f64::NEG_INFINITY, f64::INFINITY)
        } else {
            return None;
        }
    } else {
        let qb = op.dot(dp);
        let qc = op.length_squared() - r * r;
        let disc = qb * qb - qa * qc;
        if disc <= 0.0 {
            return None;
        }
        let s = disc.sqrt();
        ((-qb - s) / qa, (-qb + s) / qa)
    };
    // The slab 0 <= (p - a).u <= len.
    let (h0, dh) = (oa.dot(u), d.dot(u));
    if dh.abs() < 1e-18 {
        if !(0.0..=len).contains(&h0) {
            return None;
        }
    } else {
        let (s0, s1) = ((0.0 - h0) / dh, (len - h0) / dh);
        let (lo, hi) = (s0.min(s1), s0.max(s1));
        t0 = t0.max(lo);
        t1 = t1.min(hi);
    }
    (t1 > t0).then_some((t0, t1))
}

/// The total length of the union of intervals (each `start <= end`), clipped to `[lo, hi]`.
pub fn union_length(mut spans: Vec<(f64, f64)>, lo: f64, hi: f64) -> f64 {
    spans.retain(|s| s.1 > lo && s.0 < hi);
    spans.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (mut total, mut at) = (0.0, lo);
    for (s, e) in spans {
        let (s, e) = (s.max(at), e.min(hi));
        if e > s {
            total += e - s;
            at = e;
        }
    }
    total
}

/// A material: its name and linear attenuation coefficient, 1/m.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    pub mu_per_m: f64,
}

/// The scene: bodies, each of a material (an index into `materials`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    pub materials: Vec<Material>,
    pub bodies: Vec<(Body, usize)>,
}

/// A sphere holding the body: its centre and radius.
pub fn bound(body: &Body) -> (DVec3, f64) {
    match *body {
        Body::Sphere { centre, radius } => (centre, radius),
        Body::Capsule { a, b, radius } | Body::Cylinder { a, b, radius } => {
            (0.5 * (a + b), 0.5 * (b - a).length() + radius)
        }
    }
}

/// Pixels along a side of the tiles that share one list of bodies.
const TILE: usize = 16;

impl Scene {
    /// The attenuation `sum mu_m L_m` along the segment from `source` to `pixel`.
    pub fn attenuation(&self, source: DVec3, pixel: DVec3) -> f64 {
        self.attenuation_among(source, pixel, 0..self.bodies.len())
    }

    /// [`Scene::attenuation`] through the bodies `among` (indices, in order) alone.
    pub fn attenuation_among(
        &self,
        source: DVec3,
        pixel: DVec3,
        among: impl IntoIterator<Item = usize>,
    ) -> f64 {
        let span = pixel - source;
        let length = span.length();
        if length <= 0.0 {
            return 0.0;
        }
        let d = span / length;
        let mut per: Vec<Vec<(f64, f64)>> = vec![Vec::new(); self.materials.len()];
        for (body, m) in among.into_iter().filter_map(|k| self.bodies.get(k)) {
            if let (Some(c), Some(list)) = (chord(body, source, d), per.get_mut(*m)) {
                list.push(c);
            }
        }
        per.into_iter()
            .zip(&self.materials)
            .map(|(spans, m)| m.mu_per_m * union_length(spans, 0.0, length))
            .sum()
    }

    /// For each tile of `arm`'s detector (rows of tiles, then columns), the bodies its rays
    /// may meet: those whose bounding sphere's cone from the source meets the cone holding
    /// the rays to the tile's pixels. A body the source is inside is in every list.
    fn tiles(&self, arm: &CArm) -> Vec<Vec<usize>> {
        let (tw, th) = (arm.width.div_ceil(TILE), arm.height.div_ceil(TILE));
        let dir = |p: DVec3| (p - arm.source).normalize_or_zero();
        let cones: Vec<Option<(DVec3, f64)>> = self
            .bodies
            .iter()
            .map(|(b, _)| {
                let (c, r) = bound(b);
                let dist = (c - arm.source).length();
                (dist > r).then(|| (dir(c), (r / dist).asin()))
            })
            .collect();
        let angle = |a: DVec3, b: DVec3| a.dot(b).clamp(-1.0, 1.0).acos();
        let mut out = Vec::with_capacity(tw * th);
        for ty in 0..th {
            for tx in 0..tw {
                let (i0, j0) = (tx * TILE, ty * TILE);
                let (i1, j1) = (
                    (i0 + TILE).min(arm.width) - 1,
                    (j0 + TILE).min(arm.height) - 1,
                );
                let centre = dir(0.5 * (arm.pixel(i0, j0) + arm.pixel(i1, j1)));
                let spread = [(i0, j0), (i1, j0), (i0, j1), (i1, j1)]
                    .into_iter()
                    .map(|(i, j)| angle(centre, dir(arm.pixel(i, j))))
                    .fold(0.0f64, f64::max);
                out.push(
                    cones
                        .iter()
                        .enumerate()
                        .filter(|(_, cone)| {
                            cone.is_none_or(|(d, half)| angle(centre, d) <= spread + half + 1e-9)
                        })
                        .map(|(k, _)| k)
                        .collect(),
                );
            }
        }
        out
    }
}

/// The C-arm: a point source and a flat detector of `width` x `height` pixels of `pixel_m`,
/// its centre `distance_m` from the source along `forward`, its rows along `right`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CArm {
    pub source: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub distance_m: f64,
    pub width: usize,
    pub height: usize,
    pub pixel_m: f64,
}

impl CArm {
    /// The centre of pixel (column `i`, row `j`; row 0 at the top). The picture is the
    /// detector seen from the side the beam leaves it, looking back at the source, as a
    /// fluoroscope's monitor shows it: `right` to the right, up = forward x right (in a
    /// frontal view of a supine patient, the patient's right on the left of the picture).
    pub fn pixel(&self, i: usize, j: usize) -> DVec3 {
        let f = self.forward.normalize_or_zero();
        let r = self.right.normalize_or_zero();
        let up = f.cross(r);
        let x = (i as f64 + 0.5 - self.width as f64 / 2.0) * self.pixel_m;
        let y = (self.height as f64 / 2.0 - j as f64 - 0.5) * self.pixel_m;
        self.source + f * self.distance_m + r * x + up * y
    }
}

/// A frame: each pixel's detected photons, and what the fluoroscope shows.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub width: usize,
    pub height: usize,
    /// Photons each pixel counted (noisy).
    pub counts: Vec<f64>,
    /// `-ln(counts / N0)`: the measured line integral (0 where nothing attenuates, and
    /// outside the collimated field).
    pub line_integrals: Vec<f64>,
    /// The collimated field, pixels: columns `open[0]..open[1]`, rows `open[2]..open[3]`;
    /// nothing outside it was exposed (0 counts).
    pub open: [usize; 4],
}

impl Frame {
    /// Whether pixel (column `i`, row `j`) lies in the exposed field.
    pub fn exposed(&self, i: usize, j: usize) -> bool {
        (self.open[0]..self.open[1]).contains(&i) && (self.open[2]..self.open[3]).contains(&j)
    }
}

/// One exposure: `photons` per pixel without attenuation (the dose per frame sets it), noise
/// drawn from `seed` (none with `seed = None`: the expected counts).
pub fn expose(scene: &Scene, arm: &CArm, photons: f64, seed: Option<u64>) -> Frame {
    expose_within(scene, arm, photons, seed, [0, arm.width, 0, arm.height])
}

/// [`expose`] with the beam collimated to `open` (see [`Frame::open`]; clipped to the
/// detector).
pub fn expose_within(
    scene: &Scene,
    arm: &CArm,
    photons: f64,
    seed: Option<u64>,
    open: [usize; 4],
) -> Frame {
    let open = [
        open[0].min(arm.width),
        open[1].min(arm.width),
        open[2].min(arm.height),
        open[3].min(arm.height),
    ];
    let tiles = scene.tiles(arm);
    let tiles_across = arm.width.div_ceil(TILE);
    let rows: Vec<Vec<(f64, f64)>> = (0..arm.height)
        .into_par_iter()
        .map(|j| {
            // Each row's own stream: the same frame on any number of threads.
            let mut noise = seed.map(|s| {
                crate::rng::SplitMix64(s ^ (j as u64 + 1).wrapping_mul(0xd1b5_4a32_d192_ed03))
            });
            (0..arm.width)
                .map(|i| {
                    let inside = (open[0]..open[1]).contains(&i) && (open[2]..open[3]).contains(&j);
                    if !inside {
                        return (0.0, 0.0);
                    }
                    let among = tiles[(j / TILE) * tiles_across + i / TILE].iter().copied();
                    let mu_l = scene.attenuation_among(arm.source, arm.pixel(i, j), among);
                    let mean = photons * (-mu_l).exp();
                    let c = match &mut noise {
                        Some(g) => (mean + mean.sqrt() * g.normal()).max(1.0),
                        None => mean.max(1e-300),
                    };
                    (c, -(c / photons).ln())
                })
                .collect()
        })
        .collect();
    let (counts, line_integrals) = rows.into_iter().flatten().unzip();
    Frame {
        width: arm.width,
        height: arm.height,
        counts,
        line_integrals,
        open,
    }
}

#[cfg(test)]
#[path = "xray_tests.rs"]
mod tests;
