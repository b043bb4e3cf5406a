//! Kelvin's fundamental solutions of 3-D isotropic linear elastostatics and their integrals
//! over flat constant elements (the myotomy paper's eq. 1).
//!
//! For a unit point force in direction `k` at the source `xi`, the displacement and the
//! traction at the field point `x` (normal `n`, `r = x - xi`, `d = r / |r|`) are
//!
//! ```text
//! U_ik = ((3 - 4 nu) delta_ik + d_i d_k) / (16 pi G (1 - nu) r)
//! P_ik = -(dr/dn ((1 - 2 nu) delta_ik + 3 d_i d_k) - (1 - 2 nu) (d_i n_k - d_k n_i))
//!        / (8 pi (1 - nu) r^2)
//! ```
//!
//! (Brebbia and Dominguez, "Boundary elements: an introductory course", ch. 6), so that
//! `c u(xi) + int P u dGamma = int U p dGamma`.
//!
//! Off its own element the integrals are Gauss rules on the triangle, finer (by splitting
//! the triangle into 4, 16 or 64) the nearer the source is relative to the element's size.
//! On its own element (the source at the centroid) they are taken in polar coordinates about
//! the source, edge by edge: `U`'s `1/r` cancels the Jacobian's `r`, and `P`, whose `dr/dn`
//! terms vanish on a flat element, leaves a Cauchy principal value `int e ln R(theta)
//! dtheta` (the `ln eps` part multiplies `int e dtheta = 0`).

use super::surface::Element;
use glam::{DMat3, DVec3};
use std::f64::consts::PI;

/// An isotropic linear elastic material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    pub young_pa: f64,
    pub poisson: f64,
}

impl Material {
    pub fn shear_pa(&self) -> f64 {
        self.young_pa / (2.0 * (1.0 + self.poisson))
    }
}

/// The two kernels at one pair of points, as matrices whose column `k` is the response to
/// a unit force along `k`: `(U, P)`.
pub fn kernels(m: &Material, xi: DVec3, x: DVec3, n: DVec3) -> (DMat3, DMat3) {
    let nu = m.poisson;
    let rv = x - xi;
    let r = rv.length();
    let d = rv / r;
    let dn = d.dot(n);
    let cu = 1.0 / (16.0 * PI * m.shear_pa() * (1.0 - nu) * r);
    let cp = -1.0 / (8.0 * PI * (1.0 - nu) * r * r);
    let a = 3.0 - 4.0 * nu;
    let b = 1.0 - 2.0 * nu;
    let dd = outer(d, d);
    let u = (DMat3::IDENTITY * a + dd) * cu;
    // (d_i n_k - d_k n_i): row i, column k.
    let skew = outer(d, n) - outer(n, d);
    let p = ((DMat3::IDENTITY * b + dd * 3.0) * dn - skew * b) * cp;
    (u, p)
}

/// `a b^T`.
fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Dunavant's 7-point rule (degree 5): barycentric points and weights summing to 1.
const SEVEN: [([f64; 3], f64); 7] = {
    const A1: f64 = 0.059_715_871_789_770;
    const B1: f64 = 0.470_142_064_105_115;
    const W1: f64 = 0.132_394_152_788_506;
    const A2: f64 = 0.797_426_985_353_087;
    const B2: f64 = 0.101_286_507_323_456;
    const W2: f64 = 0.125_939_180_544_827;
    [
        ([1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], 0.225),
        ([A1, B1, B1], W1),
        ([B1, A1, B1], W1),
        ([B1, B1, A1], W1),
        ([A2, B2, B2], W2),
        ([B2, A2, B2], W2),
        ([B2, B2, A2], W2),
    ]
};

/// The centroid rule (degree 1).
const ONE: [([f64; 3], f64); 1] = [([1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0], 1.0)];

/// The 3-point rule of degree 2.
const THREE: [([f64; 3], f64); 3] = [
    ([2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0], 1.0 / 3.0),
    ([1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0], 1.0 / 3.0),
    ([1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0], 1.0 / 3.0),
];

/// Gauss-Legendre, 12 points on [-1, 1] (positive half; symmetric).
const GL12: [(f64, f64); 6] = [
    (0.125_233_408_511_468_9, 0.249_147_045_813_402_8),
    (0.367_831_498_998_180_2, 0.233_492_536_538_354_8),
    (0.587_317_954_286_617_4, 0.203_167_426_723_065_9),
    (0.769_902_674_194_304_7, 0.160_078_328_543_346_2),
    (0.904_117_256_370_474_9, 0.106_939_325_995_318_4),
    (0.981_560_634_246_719_2, 0.047_175_336_386_511_8),
];

/// The kernels' constants for a material: `1 / (16 pi G (1 - nu))`, `-1 / (8 pi (1 - nu))`,
/// `3 - 4 nu` and `1 - 2 nu`.
#[derive(Debug, Clone, Copy)]
struct Constants {
    cu: f64,
    cp: f64,
    a: f64,
    b: f64,
}

impl Constants {
    fn of(m: &Material) -> Constants {
        let nu = m.poisson;
        Constants {
            cu: 1.0 / (16.0 * PI * m.shear_pa() * (1.0 - nu)),
            cp: -1.0 / (8.0 * PI * (1.0 - nu)),
            a: 3.0 - 4.0 * nu,
            b: 1.0 - 2.0 * nu,
        }
    }

    /// Adds `w U` and `w P` at one point to `su` and `sp` (row-major 3 x 3), the same
    /// arithmetic as [`kernels`] written out.
    #[inline]
    fn add(&self, xi: DVec3, x: DVec3, n: DVec3, w: f64, su: &mut [f64; 9], sp: &mut [f64; 9]) {
        let rv = x - xi;
        let r2 = rv.length_squared();
        let r = r2.sqrt();
        let d = (rv / r).to_array();
        let nn = n.to_array();
        let dn = d[0] * nn[0] + d[1] * nn[1] + d[2] * nn[2];
        let wu = w * self.cu / r;
        let wp = w * self.cp / r2;
        for i in 0..3 {
            for k in 0..3 {
                let delta = if i == k { 1.0 } else { 0.0 };
                let dd = d[i] * d[k];
                su[3 * i + k] += wu * (self.a * delta + dd);
                sp[3 * i + k] += wp
                    * (dn * (self.b * delta + 3.0 * dd) - self.b * (d[i] * nn[k] - d[k] * nn[i]));
            }
        }
    }
}

/// Row-major 3 x 3 to a matrix.
fn mat(rows: &[f64; 9]) -> DMat3 {
    DMat3::from_cols_array(rows).transpose()
}

/// `(int_e U dGamma, int_e P dGamma)` for a source `xi` off element `e`.
pub fn integrate_off(m: &Material, xi: DVec3, e: &Element) -> (DMat3, DMat3) {
    let ratio = (e.centroid - xi).length() / e.size_m;
    let (levels, rule): (u32, &[([f64; 3], f64)]) = if ratio >= 12.0 {
        (0, &ONE)
    } else if ratio >= 5.0 {
        (0, &THREE)
    } else if ratio >= 2.5 {
        (0, &SEVEN)
    } else if ratio >= 1.25 {
        (1, &SEVEN)
    } else if ratio >= 0.6 {
        (2, &SEVEN)
    } else {
        (3, &SEVEN)
    };
    let k = Constants::of(m);
    let mut su = [0.0f64; 9];
    let mut sp = [0.0f64; 9];
    let mut add = |c: [DVec3; 3], area: f64| {
        for &(b, w) in rule {
            let x = c[0] * b[0] + c[1] * b[1] + c[2] * b[2];
            k.add(xi, x, e.normal, w * area, &mut su, &mut sp);
        }
    };
    split(e.corners, levels, e.area_m2, &mut add);
    (mat(&su), mat(&sp))
}

/// Calls `f` on the `4^levels` triangles of `c`'s midpoint subdivision with their area.
fn split(c: [DVec3; 3], levels: u32, area: f64, f: &mut impl FnMut([DVec3; 3], f64)) {
    if levels == 0 {
        f(c, area);
        return;
    }
    let [a, b, d] = c;
    let (ab, bd, da) = ((a + b) * 0.5, (b + d) * 0.5, (d + a) * 0.5);
    let q = area * 0.25;
    split([a, ab, da], levels - 1, q, f);
    split([ab, b, bd], levels - 1, q, f);
    split([da, bd, d], levels - 1, q, f);
    split([ab, bd, da], levels - 1, q, f);
}

/// `(int_e U dGamma, PV int_e P dGamma)` for the source at `e`'s own centroid (without the
/// free term `c`).
pub fn integrate_self(m: &Material, e: &Element) -> (DMat3, DMat3) {
    let nu = m.poisson;
    let n = e.normal;
    let xi = e.centroid;
    let mut su = DMat3::ZERO;
    let mut sp = DMat3::ZERO;
    for k in 0..3 {
        let p = e.corners[k] - xi;
        let q = e.corners[(k + 1) % 3] - xi;
        // The edge's angular span seen from the source, and its line's distance `h` and
        // outward unit normal `m` (in the plane).
        let span = p.cross(q).dot(n).atan2(p.dot(q));
        let along = (q - p).normalize();
        let foot = p - along * p.dot(along);
        let h = foot.length();
        if h <= 0.0 || span == 0.0 {
            continue;
        }
        let mdir = foot / h;
        let t1 = p.normalize();
        let t2 = n.cross(t1);
        for &(s, w) in &GL12 {
            for s in [-s, s] {
                let theta = 0.5 * span * (1.0 + s);
                let dir = t1 * theta.cos() + t2 * theta.sin();
                let big_r = h / dir.dot(mdir);
                let wt = w * 0.5 * span;
                su += (DMat3::IDENTITY * (3.0 - 4.0 * nu) + outer(dir, dir)) * (big_r * wt);
                sp += (outer(dir, n) - outer(n, dir)) * (big_r.ln() * wt);
            }
        }
    }
    let u = su * (1.0 / (16.0 * PI * m.shear_pa() * (1.0 - nu)));
    let p = sp * ((1.0 - 2.0 * nu) / (8.0 * PI * (1.0 - nu)));
    (u, p)
}
