//! The force terms of the force-based soft body (nephrectomy paper, eqs 1-8), one function
//! each so that each can be checked by hand. Vertex mass is 1 (eq 7), so a force in newtons
//! is also an acceleration in m/s^2.

use glam::Vec3;

/// Spring force pulling a point back to its rest position: F_s = k (x0 - x).
pub fn spring_force(k_n_per_m: f32, x: Vec3, rest: Vec3) -> Vec3 {
    (rest - x) * k_n_per_m
}

/// Damped velocity, eq 5: v_d = v (1 - d dt). The factor is clamped at zero so that a large
/// damping never reverses the velocity.
pub fn damp_velocity(v: Vec3, damping_per_s: f32, dt_s: f32) -> Vec3 {
    v * (1.0 - damping_per_s * dt_s).max(0.0)
}

/// Pressure force on a surface element, eqs 3-4: F_p = P n dA.
pub fn pressure_force(pressure_pa: f32, normal: Vec3, area_m2: f32) -> Vec3 {
    normal * (pressure_pa * area_m2)
}

/// Contact falloff, eq 6: F_v = F / (1 + d^2), with d measured in units of the falloff length
/// (the paper's mesh is about one Unity unit across; ours is in metres).
pub fn falloff(force_n: f32, distance_m: f32, falloff_length_m: f32) -> f32 {
    let d = distance_m / falloff_length_m;
    force_n / (1.0 + d * d)
}

/// The offset point: the contact point lifted along the surface normal, so that every vertex
/// near the contact is driven into the surface and follows the contact normal.
pub fn offset_point(contact: Vec3, normal: Vec3, offset_m: f32) -> Vec3 {
    contact + normal * offset_m
}

/// Force a contact exerts on one vertex: the pressed force P dA, attenuated by eq 6 with the
/// distance from the offset point, directed from the offset point through the vertex. Its
/// component along the vertex normal is the pressure force, the rest the offset force.
pub struct ContactForce {
    pub pressure: Vec3,
    pub offset: Vec3,
}

pub fn contact_force(
    x: Vec3,
    vertex_normal: Vec3,
    offset_from: Vec3,
    pressed_force_n: f32,
    falloff_length_m: f32,
) -> ContactForce {
    let d = x - offset_from;
    let dist = d.length();
    if dist <= f32::EPSILON {
        return ContactForce {
            pressure: -vertex_normal * pressed_force_n,
            offset: Vec3::ZERO,
        };
    }
    let f = d / dist * falloff(pressed_force_n, dist, falloff_length_m);
    let pressure = vertex_normal * f.dot(vertex_normal);
    ContactForce {
        pressure,
        offset: f - pressure,
    }
}

/// Internal gas pressure that keeps the volume: P = k_v (V0 - V) / V0, in pascals.
pub fn volume_pressure(k_volume_pa: f32, rest_volume_m3: f32, volume_m3: f32) -> f32 {
    if rest_volume_m3 <= 0.0 {
        return 0.0;
    }
    k_volume_pa * (rest_volume_m3 - volume_m3) / rest_volume_m3
}

/// One explicit step with unit mass: eq 7 (dv = F dt), eq 5 (damping), eq 8 (dp = v dt).
pub fn integrate(x: Vec3, v: Vec3, force: Vec3, damping_per_s: f32, dt_s: f32) -> (Vec3, Vec3) {
    let v = damp_velocity(v + force * dt_s, damping_per_s, dt_s);
    (x + v * dt_s, v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-6
    }

    #[test]
    fn spring_force_matches_hooke() {
        // 20 N/m, displaced 5 mm along +x: 0.1 N back along -x.
        let f = spring_force(20.0, Vec3::new(0.005, 0.0, 0.0), Vec3::ZERO);
        assert!(close(f, Vec3::new(-0.1, 0.0, 0.0)), "{f}");
    }

    #[test]
    fn damping_follows_eq5() {
        // d = 5 /s, dt = 2 ms: factor 0.99.
        let v = damp_velocity(Vec3::new(1.0, -2.0, 0.5), 5.0, 0.002);
        assert!(close(v, Vec3::new(0.99, -1.98, 0.495)), "{v}");
        assert_eq!(damp_velocity(Vec3::ONE, 1000.0, 0.01), Vec3::ZERO);
    }

    #[test]
    fn pressure_force_is_pressure_times_area_along_normal() {
        // 1500 Pa on 1 cm^2: 0.15 N.
        let f = pressure_force(1500.0, Vec3::Z, 1e-4);
        assert!(close(f, Vec3::new(0.0, 0.0, 0.15)), "{f}");
    }

    #[test]
    fn falloff_is_full_at_zero_and_half_at_one_length() {
        assert_eq!(falloff(2.0, 0.0, 0.01), 2.0);
        assert!((falloff(2.0, 0.01, 0.01) - 1.0).abs() < 1e-6);
        assert!((falloff(2.0, 0.02, 0.01) - 0.4).abs() < 1e-6);
    }

    #[test]
    fn contact_force_splits_into_pressure_and_offset() {
        // Surface z = 0, normal +z, contact at origin, offset 2 mm: offset point (0,0,0.002).
        let q = offset_point(Vec3::ZERO, Vec3::Z, 0.002);
        assert!(close(q, Vec3::new(0.0, 0.0, 0.002)));
        // Vertex 2 mm to the side: d = (0.002, 0, -0.002), |d| = 2.828 mm, falloff length 1 mm
        // -> F = 0.3 / (1 + 8) = 1/30 N along d / |d|.
        let c = contact_force(Vec3::new(0.002, 0.0, 0.0), Vec3::Z, q, 0.3, 0.001);
        let s = std::f32::consts::FRAC_1_SQRT_2 / 30.0;
        assert!(close(c.pressure, Vec3::new(0.0, 0.0, -s)), "{}", c.pressure);
        assert!(close(c.offset, Vec3::new(s, 0.0, 0.0)), "{}", c.offset);
    }

    #[test]
    fn volume_pressure_pushes_out_when_compressed() {
        assert!((volume_pressure(2000.0, 1e-4, 0.99e-4) - 20.0).abs() < 1e-3);
        assert_eq!(volume_pressure(2000.0, 1e-4, 1e-4), 0.0);
        assert_eq!(volume_pressure(2000.0, 0.0, 1e-4), 0.0);
    }

    #[test]
    fn integration_follows_eqs_7_5_8_in_order() {
        // v = 0, F = 1 N, dt = 0.01, d = 10: v = (0 + 0.01) * 0.9 = 0.009; x = 0.00009.
        let (x, v) = integrate(Vec3::ZERO, Vec3::ZERO, Vec3::X, 10.0, 0.01);
        assert!(close(v, Vec3::new(0.009, 0.0, 0.0)));
        assert!(close(x, Vec3::new(0.00009, 0.0, 0.0)));
    }
}
