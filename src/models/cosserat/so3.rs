//! Rotations for the rod: the exponential and logarithm maps of SO(3) and the inverse of its
//! left Jacobian, in f64.

use glam::{DMat3, DVec3};

/// The cross-product matrix: `skew(a) * b == a.cross(b)`.
pub fn skew(a: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, a.z, -a.y),
        DVec3::new(-a.z, 0.0, a.x),
        DVec3::new(a.y, -a.x, 0.0),
    )
}

/// The rotation by the vector `phi` (axis times angle, radians): Rodrigues' formula.
pub fn exp(phi: DVec3) -> DMat3 {
    let theta2 = phi.length_squared();
    let k = skew(phi);
    let (a, b) = if theta2 < 1e-12 {
        // Taylor: sin t / t and (1 - cos t) / t^2 to second order.
        (1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0)
    } else {
        let t = theta2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / theta2)
    };
    DMat3::IDENTITY + k * a + k * k * b
}

/// The rotation vector of `r` (the inverse of [`exp`]), angle in [0, pi].
pub fn log(r: DMat3) -> DVec3 {
    let trace = r.x_axis.x + r.y_axis.y + r.z_axis.z;
    let cos = ((trace - 1.0) * 0.5).clamp(-1.0, 1.0);
    // The antisymmetric part: 2 sin(theta) times the unit axis.
    let w = DVec3::new(
        r.y_axis.z - r.z_axis.y,
        r.z_axis.x - r.x_axis.z,
        r.x_axis.y - r.y_axis.x,
    );
    let theta = cos.acos();
    if theta < 1e-6 {
        // theta / (2 sin theta) -> 1/2 + theta^2 / 12.
        return w * (0.5 + theta * theta / 12.0);
    }
    if std::f64::consts::PI - theta < 1e-6 {
        // Near a half turn the antisymmetric part vanishes: the axis from the symmetric part.
        let s = (r + r.transpose()) * 0.5 - DMat3::IDENTITY * cos;
        let cols = [s.x_axis, s.y_axis, s.z_axis];
        let best = cols
            .iter()
            .copied()
            .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
            .unwrap_or(DVec3::X);
        let axis = best.normalize_or(DVec3::X);
        // Pick the sign that agrees with what is left of the antisymmetric part.
        let axis = if axis.dot(w) < 0.0 { -axis } else { axis };
        return axis * theta;
    }
    w * (theta / (2.0 * theta.sin()))
}

/// The inverse of SO(3)'s left Jacobian at `phi`: `log(exp(u) exp(phi)) ~ phi + jl_inv(phi) u`
/// for small `u`.
pub fn jl_inv(phi: DVec3) -> DMat3 {
    let theta2 = phi.length_squared();
    let k = skew(phi);
    let c = if theta2 < 1e-8 {
        1.0 / 12.0 + theta2 / 720.0
    } else {
        let t = theta2.sqrt();
        1.0 / theta2 - (1.0 + t.cos()) / (2.0 * t * t.sin())
    };
    DMat3::IDENTITY - k * 0.5 + k * k * c
}

/// The frame nearest `r` that is a rotation (Gram-Schmidt on its columns), against rounding
/// drift after many products.
pub fn orthonormalise(r: DMat3) -> DMat3 {
    let z = r.z_axis.normalize_or(DVec3::Z);
    let x = (r.x_axis - z * r.x_axis.dot(z)).normalize_or(z.any_orthonormal_vector());
    let y = z.cross(x);
    DMat3::from_cols(x, y, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: DMat3, b: DMat3, tol: f64) -> bool {
        (a - b).to_cols_array().iter().all(|d| d.abs() < tol)
    }

    #[test]
    fn exp_and_log_invert_each_other_from_tiny_to_near_half_turns() {
        for phi in [
            DVec3::new(1e-9, -2e-9, 0.5e-9),
            DVec3::new(0.3, -0.2, 0.1),
            DVec3::new(-1.0, 2.0, 0.5),
            DVec3::new(0.0, 0.0, std::f64::consts::PI - 1e-7),
        ] {
            let r = exp(phi);
            assert!(close(r * r.transpose(), DMat3::IDENTITY, 1e-12));
            let back = log(r);
            assert!(
                (back - phi).length() < 1e-6 * phi.length().max(1e-9),
                "{phi} -> {back}"
            );
        }
        // A quarter turn about z takes x to y.
        let q = exp(DVec3::Z * std::f64::consts::FRAC_PI_2);
        assert!((q * DVec3::X - DVec3::Y).length() < 1e-12);
    }

    #[test]
    fn the_inverse_left_jacobian_predicts_the_log_of_a_perturbed_rotation() {
        let phi = DVec3::new(0.4, -0.7, 0.2);
        let u = DVec3::new(1e-6, 2e-6, -1.5e-6);
        let exact = log(exp(u) * exp(phi));
        let predicted = phi + jl_inv(phi) * u;
        assert!(
            (exact - predicted).length() < 1e-11,
            "{exact} vs {predicted}"
        );
        // At zero it is the identity.
        assert!(close(jl_inv(DVec3::ZERO), DMat3::IDENTITY, 1e-15));
    }
}
