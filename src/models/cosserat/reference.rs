//! Reference solutions for the rod, worked out independently of it: the planar cantilever
//! under its own weight as a boundary-value problem of Reissner's beam (the elastica with
//! stretch and shear; both can be switched off), solved by shooting on the clamp's moment with
//! fourth-order Runge-Kutta in arc length.
//!
//! The rod lies along +x from a clamp at the origin; the load is `q` per unit length along -y.
//! With `n(s)` the force the part beyond `s` puts on the part before it, and `m(s)` the bending
//! moment: `n' + f = 0` gives `n(s) = -q (L - s) y`; `m' + (r' x n) . z = 0` with
//! `m = EI theta'`, `r' = nu1 d1 + nu3 d3`, `d3 = (cos theta, sin theta)`,
//! `d1 = (-sin theta, cos theta)`, `nu3 = 1 + n.d3 / EA`, `nu1 = n.d1 / (ks G A)`; and
//! `theta(0) = 0`, `r(0) = 0`, `m(L) = 0`.

use super::{CosseratRod, RodParams};
use glam::DVec3;

/// The beam's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cantilever {
    pub length_m: f64,
    /// Load per unit length, N/m (downward).
    pub load_n_per_m: f64,
    /// Bending stiffness E I, N m^2.
    pub bend_n_m2: f64,
    /// Axial stiffness E A, N; infinite for an inextensible beam.
    pub axial_n: f64,
    /// Shear stiffness ks G A, N; infinite for an unshearable beam.
    pub shear_n: f64,
}

/// State along the beam: angle, moment, x, y.
type State = [f64; 4];

impl Cantilever {
    fn derivative(&self, s: f64, y: &State) -> State {
        let [theta, m, _, _] = *y;
        let (sin, cos) = theta.sin_cos();
        // n = -q (L - s) ŷ.
        let ny = -self.load_n_per_m * (self.length_m - s);
        let axial = ny * sin; // n . d3
        let shear = ny * cos; // n . d1
        let nu3 = 1.0 + axial / self.axial_n;
        let nu1 = shear / self.shear_n;
        let rx = nu1 * -sin + nu3 * cos;
        let ry = nu1 * cos + nu3 * sin;
        // (r' x n) . z with n = (0, ny).
        let cross = rx * ny;
        [m / self.bend_n_m2, -cross, rx, ry]
    }

    /// Integrates from the clamp with moment `m0` there; the state at the free end.
    fn shoot(&self, m0: f64, steps: usize) -> State {
        let h = self.length_m / steps as f64;
        let mut y: State = [0.0, m0, 0.0, 0.0];
        for k in 0..steps {
            let s = k as f64 * h;
            let add = |a: &State, b: &State, f: f64| -> State {
                std::array::from_fn(|i| a[i] + b[i] * f)
            };
            let k1 = self.derivative(s, &y);
            let k2 = self.derivative(s + 0.5 * h, &add(&y, &k1, 0.5 * h));
            let k3 = self.derivative(s + 0.5 * h, &add(&y, &k2, 0.5 * h));
            let k4 = self.derivative(s + h, &add(&y, &k3, h));
            y = std::array::from_fn(|i| {
                y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
            });
        }
        y
    }

    /// The free end's drop below the clamp, m (positive downward).
    pub fn tip_drop(&self) -> f64 {
        let steps = 20_000;
        // The clamp's moment lies between zero and that of the straight beam (q L^2 / 2,
        // hogging: negative with theta measured anticlockwise); m(L) is monotonic in it.
        let (mut lo, mut hi) = (-0.5 * self.load_n_per_m * self.length_m.powi(2) * 1.01, 0.0);
        let end_moment = |m0: f64| self.shoot(m0, steps)[1];
        let (mut f_lo, mut f_hi) = (end_moment(lo), end_moment(hi));
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            let f_mid = end_moment(mid);
            if (f_mid < 0.0) == (f_lo < 0.0) {
                lo = mid;
                f_lo = f_mid;
            } else {
                hi = mid;
                f_hi = f_mid;
            }
            if (hi - lo).abs() < 1e-15 * (1.0 + lo.abs()) {
                break;
            }
        }
        let _ = f_hi;
        -self.shoot(0.5 * (lo + hi), steps)[3]
    }
}

/// The heavy cantilever of the verification cases: E 1e5 Pa, radius 0.01 m, 1000 kg/m^3,
/// nu 0.5, under gravity, with drag to bring it to rest.
pub fn heavy_params() -> RodParams {
    RodParams {
        youngs_modulus_pa: 1e5,
        poisson_ratio: 0.5,
        density_kg_per_m3: 1000.0,
        radius_m: 0.01,
        wall_m: None,
        damping_per_s: 4.0,
        curvature_damping_n_m2_s: 0.0,
        gravity: DVec3::new(0.0, -9.81, 0.0),
    }
}

/// A cantilever along +x clamped at the origin, settled under gravity: stepped at `dt` until
/// every node is slower than `still` m/s (or `max_s` simulated seconds). Returns the rod and
/// the simulated time.
pub fn settled_cantilever(
    params: RodParams,
    n: usize,
    length: f64,
    dt: f64,
    still: f64,
    max_s: f64,
) -> (CosseratRod, f64) {
    let mut rod = CosseratRod::straight(n, length, DVec3::ZERO, DVec3::X, params);
    rod.fix_node(0, true);
    let mut t = 0.0;
    while t < max_s {
        rod.step(dt);
        t += dt;
        let fastest = rod
            .velocities()
            .iter()
            .map(|v| v.length())
            .fold(0.0, f64::max);
        if t > 0.5 && fastest < still {
            break;
        }
    }
    (rod, t)
}

/// The cantilever's reference with the rod's own section figures.
pub fn reference_for(params: &RodParams, length: f64) -> Cantilever {
    let (area, i, _) = params.section();
    let q = params.density_kg_per_m3 * area * params.gravity.length();
    let s = params.stretch_stiffness();
    Cantilever {
        length_m: length,
        load_n_per_m: q,
        bend_n_m2: params.youngs_modulus_pa * i,
        axial_n: s.z,
        shear_n: s.x,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_loads_give_the_linear_beam_and_large_ones_less() {
        let (l, ei): (f64, f64) = (0.2, 7.853_981_6e-4);
        let q = 0.01 * ei / l.powi(3);
        let stiff = Cantilever {
            length_m: l,
            load_n_per_m: q,
            bend_n_m2: ei,
            axial_n: f64::INFINITY,
            shear_n: f64::INFINITY,
        };
        let linear = q * l.powi(4) / (8.0 * ei);
        assert!((stiff.tip_drop() / linear - 1.0).abs() < 1e-3);
        // At q L^3 / EI = 31.4 the beam hangs far past the linear answer (3.9 L).
        let heavy = Cantilever {
            load_n_per_m: 31.4 * ei / l.powi(3),
            ..stiff
        };
        let drop = heavy.tip_drop();
        assert!(drop > 0.5 * l && drop < l, "{drop}");
    }
}
