//! The operative field around a procedure's models: the cavity's lining and the neighbouring
//! anatomy that takes no part in the task, described as a few smooth shapes (the procedure
//! names them) and built once into one static mesh the renderer draws in one call.
//!
//! Each shape's surface carries relief: a displacement along its normal by a fractal value
//! noise of world position, deterministic (a hash of lattice points, no random state), so the
//! same field gives the same mesh on every machine and run.

use super::{ModelSnapshot, SurfaceRole, Viewpoint};
use crate::mesh::{TubeSpec, icosphere, tube, vertex_normals};
use glam::{Quat, Vec3};

/// One shape of the field.
#[derive(Debug, Clone, PartialEq)]
pub enum FieldShape {
    /// The cavity's lining seen from inside (the abdominal wall under its peritoneum): an
    /// ellipsoid whose surface faces inward. It must enclose the scope's tip.
    Cavity {
        centre: Vec3,
        radii: Vec3,
        role: SurfaceRole,
        relief_m: f32,
    },
    /// A solid mass: an ellipsoid with relief (an organ's edge, a pad of fat, a muscle).
    Blob {
        centre: Vec3,
        radii: Vec3,
        role: SurfaceRole,
        relief_m: f32,
    },
    /// A tube through the points of `path`, smoothed (a bowel loop, a vessel in the
    /// background), capped at both ends.
    Tube {
        path: Vec<Vec3>,
        radius_m: f32,
        role: SurfaceRole,
        relief_m: f32,
    },
}

impl FieldShape {
    /// The lining of a cavity (role [`SurfaceRole::Wall`]) with folds of 12 mm.
    pub fn cavity(centre: Vec3, radii: Vec3) -> Self {
        FieldShape::Cavity {
            centre,
            radii,
            role: SurfaceRole::Wall,
            relief_m: 0.012,
        }
    }

    /// A mass with relief of a tenth of its smallest radius.
    pub fn blob(centre: Vec3, radii: Vec3, role: SurfaceRole) -> Self {
        FieldShape::Blob {
            centre,
            radii,
            role,
            relief_m: 0.1 * radii.min_element(),
        }
    }

    /// A tube with relief of a fifth of its radius.
    pub fn tube(path: &[Vec3], radius_m: f32, role: SurfaceRole) -> Self {
        FieldShape::Tube {
            path: path.to_vec(),
            radius_m,
            role,
            relief_m: 0.2 * radius_m,
        }
    }
}

/// The laparoscope of a procedure: its optics and where it enters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scope {
    /// Full angle of view across the image circle, degrees (a laparoscope's is 70-80).
    pub fov_deg: f32,
    /// The angle between the optical axis and the shaft, degrees (0 for a forward-viewing
    /// scope, 30 for the usual angled one).
    pub angle_deg: f32,
    /// Where the scope passes the body wall (its port), metres.
    pub port: Vec3,
}

/// What surrounds a procedure's models, and the scope that sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct OperativeField {
    pub shapes: Vec<FieldShape>,
    pub scope: Scope,
}

/// Icosphere subdivision of the cavity (5,120 triangles) and of a blob (1,280).
const CAVITY_LEVEL: u32 = 4;
const BLOB_LEVEL: u32 = 3;
/// Wavelength of the relief's coarsest octave, metres (folds a few centimetres across).
const RELIEF_WAVELENGTH_M: f32 = 0.03;

impl OperativeField {
    /// A field seen by a scope at `view` with `fov_deg` across its image circle, its optical
    /// axis `angle_deg` below its shaft (the shaft is the axis turned up by that angle about
    /// the image's horizontal); its port is where the shaft, followed back from the tip,
    /// meets the cavity's lining (15 cm back where the field has no cavity).
    pub fn with_scope(
        shapes: Vec<FieldShape>,
        view: &Viewpoint,
        fov_deg: f32,
        angle_deg: f32,
    ) -> Self {
        let axis = (view.target - view.eye).normalize_or(Vec3::NEG_Z);
        let right = axis.cross(Vec3::Y).normalize_or(Vec3::X);
        let shaft = Quat::from_axis_angle(right, angle_deg.to_radians()) * axis;
        let back = -shaft;
        let depth = shapes
            .iter()
            .find_map(|s| match s {
                FieldShape::Cavity { centre, radii, .. } => {
                    ray_leaves_ellipsoid(view.eye, back, *centre, *radii)
                }
                _ => None,
            })
            .unwrap_or(0.15);
        OperativeField {
            shapes,
            scope: Scope {
                fov_deg,
                angle_deg,
                port: view.eye + back * depth,
            },
        }
    }

    /// The field as one static mesh: one region per shape, each with its shape's role.
    pub fn mesh(&self) -> ModelSnapshot {
        let mut positions: Vec<Vec3> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut regions: Vec<u8> = Vec::new();
        let mut roles: Vec<SurfaceRole> = Vec::new();
        for (k, shape) in self.shapes.iter().enumerate() {
            let (mut points, triangles, role, relief, inward) = match shape {
                FieldShape::Cavity {
                    centre,
                    radii,
                    role,
                    relief_m,
                } => {
                    let m = icosphere(CAVITY_LEVEL);
                    let p = m.positions.iter().map(|u| *centre + *u * *radii).collect();
                    (p, m.triangles, *role, *relief_m, true)
                }
                FieldShape::Blob {
                    centre,
                    radii,
                    role,
                    relief_m,
                } => {
                    let m = icosphere(BLOB_LEVEL);
                    let p = m.positions.iter().map(|u| *centre + *u * *radii).collect();
                    (p, m.triangles, *role, *relief_m, false)
                }
                FieldShape::Tube {
                    path,
                    radius_m,
                    role,
                    relief_m,
                } => {
                    let smooth = smooth_path(path, 6);
                    let length: f32 = smooth.windows(2).map(|w| (w[1] - w[0]).length()).sum();
                    // Rings about a radius apart along the tube.
                    let rings = ((length / radius_m.max(1e-3)) as u32).clamp(2, 400);
                    let m = tube(&TubeSpec {
                        path: smooth,
                        radius_m: *radius_m,
                        segments: 16,
                        rings,
                    });
                    (m.positions, m.triangles, *role, *relief_m, false)
                }
            };
            // Relief along the undisplaced normals, so a fold never turns a face inside out.
            let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
            let normals = vertex_normals(&points, &flat);
            let seed = k as u32 * 7919;
            for (p, n) in points.iter_mut().zip(&normals) {
                *p += *n * relief * (fbm(*p / RELIEF_WAVELENGTH_M, seed) - 0.5);
            }
            let base = positions.len() as u32;
            positions.extend_from_slice(&points);
            for t in &triangles {
                let t = if inward { [t[0], t[2], t[1]] } else { *t };
                indices.extend(t.iter().map(|i| base + i));
                regions.push(k.min(255) as u8);
            }
            roles.push(role);
        }
        let normals = vertex_normals(&positions, &indices);
        ModelSnapshot {
            seared: Vec::new(),
            name: "operative field".into(),
            cut_edge: vec![false; positions.len()],
            positions,
            normals,
            indices,
            regions,
            roles,
        }
    }

    /// The angle between the scope's optical axis (from `eye` to `target`) and its shaft
    /// (from the port to `eye`), degrees.
    pub fn scope_axis_angle_deg(&self, eye: Vec3, target: Vec3) -> f32 {
        let shaft = (eye - self.scope.port).normalize_or_zero();
        let axis = (target - eye).normalize_or_zero();
        shaft.dot(axis).clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// How far along `dir` (unit) a ray from `from`, inside the ellipsoid, leaves it.
fn ray_leaves_ellipsoid(from: Vec3, dir: Vec3, centre: Vec3, radii: Vec3) -> Option<f32> {
    let (o, d) = ((from - centre) / radii, dir / radii);
    let (a, b, c) = (d.dot(d), 2.0 * o.dot(d), o.dot(o) - 1.0);
    let disc = b * b - 4.0 * a * c;
    if c >= 0.0 || disc < 0.0 {
        return None;
    }
    Some((-b + disc.sqrt()) / (2.0 * a))
}

/// A path refined `n` times between its points by centripetal-free (uniform) Catmull-Rom.
fn smooth_path(path: &[Vec3], n: usize) -> Vec<Vec3> {
    if path.len() < 3 {
        return path.to_vec();
    }
    let at = |i: isize| path[i.clamp(0, path.len() as isize - 1) as usize];
    let mut out = Vec::with_capacity(path.len() * n);
    for i in 0..path.len() as isize - 1 {
        let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
        for s in 0..n {
            let t = s as f32 / n as f32;
            let (t2, t3) = (t * t, t * t * t);
            out.push(
                0.5 * (2.0 * p1
                    + (p2 - p0) * t
                    + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
                    + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3),
            );
        }
    }
    out.push(at(path.len() as isize - 1));
    out
}

/// A lattice point's value in [0, 1): an integer hash (no state, the same everywhere).
fn lattice(x: i32, y: i32, z: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f)
        ^ seed.wrapping_mul(0x1656_67b1);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^= h >> 15;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Value noise in [0, 1): lattice values blended with a smoothstep.
pub fn value_noise(p: Vec3, seed: u32) -> f32 {
    let f = p.floor();
    let (x, y, z) = (f.x as i32, f.y as i32, f.z as i32);
    let t = p - f;
    let s = t * t * (Vec3::splat(3.0) - 2.0 * t);
    let mut sum = 0.0;
    for dz in 0..2 {
        for dy in 0..2 {
            for dx in 0..2 {
                let w = (if dx == 1 { s.x } else { 1.0 - s.x })
                    * (if dy == 1 { s.y } else { 1.0 - s.y })
                    * (if dz == 1 { s.z } else { 1.0 - s.z });
                sum += w * lattice(x + dx, y + dy, z + dz, seed);
            }
        }
    }
    sum
}

/// Three octaves of value noise, each twice the frequency and half the amplitude of the last,
/// scaled back to [0, 1).
pub fn fbm(p: Vec3, seed: u32) -> f32 {
    let (mut sum, mut amp, mut freq) = (0.0, 1.0, 1.0);
    for o in 0..3 {
        sum += amp * value_noise(p * freq, seed.wrapping_add(o));
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / 1.75
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> OperativeField {
        OperativeField {
            shapes: vec![
                FieldShape::Cavity {
                    centre: Vec3::ZERO,
                    radii: Vec3::new(0.2, 0.15, 0.25),
                    role: SurfaceRole::Wall,
                    relief_m: 0.01,
                },
                FieldShape::Blob {
                    centre: Vec3::new(0.0, -0.1, 0.0),
                    radii: Vec3::splat(0.04),
                    role: SurfaceRole::Fat,
                    relief_m: 0.004,
                },
                FieldShape::Tube {
                    path: vec![
                        Vec3::new(-0.05, -0.05, 0.0),
                        Vec3::new(0.0, -0.04, 0.02),
                        Vec3::new(0.05, -0.05, 0.0),
                    ],
                    radius_m: 0.012,
                    role: SurfaceRole::Viscus,
                    relief_m: 0.002,
                },
            ],
            scope: Scope {
                fov_deg: 70.0,
                angle_deg: 30.0,
                port: Vec3::new(0.0, 0.14, 0.1),
            },
        }
    }

    #[test]
    fn the_mesh_has_a_region_per_shape_and_unit_normals() {
        let m = sample().mesh();
        assert_eq!(
            m.roles,
            vec![SurfaceRole::Wall, SurfaceRole::Fat, SurfaceRole::Viscus]
        );
        assert_eq!(m.regions.len() * 3, m.indices.len());
        assert_eq!(m.regions.iter().filter(|&&r| r == 0).count(), 5120);
        assert_eq!(m.regions.iter().filter(|&&r| r == 1).count(), 1280);
        assert!(m.indices.iter().all(|&i| (i as usize) < m.positions.len()));
        for n in &m.normals {
            assert!((n.length() - 1.0).abs() < 1e-3, "{n}");
        }
        assert!(m.positions.iter().all(|p| p.is_finite()));
    }

    #[test]
    fn the_cavity_faces_inward_and_the_blob_outward() {
        let m = sample().mesh();
        // A vertex's normal points towards the cavity's centre for the lining and away from
        // the blob's centre for the blob.
        let centre_of = |r: u8| -> Vec3 {
            if r == 0 {
                Vec3::ZERO
            } else {
                Vec3::new(0.0, -0.1, 0.0)
            }
        };
        for (t, &r) in m.regions.iter().enumerate().filter(|(_, r)| **r < 2) {
            let i = m.indices[3 * t] as usize;
            let out = (m.positions[i] - centre_of(r)).normalize();
            let d = m.normals[i].dot(out);
            if r == 0 {
                assert!(d < -0.5, "lining normal {d}");
            } else {
                assert!(d > 0.5, "blob normal {d}");
            }
        }
    }

    #[test]
    fn relief_is_bounded_and_deterministic() {
        let a = sample().mesh();
        assert_eq!(a, sample().mesh());
        // The cavity's vertices lie within half its relief of the ellipsoid.
        let radii = Vec3::new(0.2, 0.15, 0.25);
        let mut moved = 0.0f32;
        for (t, _) in a.regions.iter().enumerate().filter(|(_, r)| **r == 0) {
            let p = a.positions[a.indices[3 * t] as usize];
            let u = p / radii;
            // Distance from the ellipsoid along the radius, roughly.
            let d = (u.length() - 1.0).abs() * radii.min_element();
            assert!(
                d <= 0.0051 * radii.max_element() / radii.min_element(),
                "{d}"
            );
            moved = moved.max(d);
        }
        assert!(moved > 0.001, "the relief shows: {moved}");
    }

    #[test]
    fn noise_stays_in_its_range_and_varies() {
        let mut lo: f32 = 1.0;
        let mut hi: f32 = 0.0;
        for k in 0..2000 {
            let p = Vec3::new(
                k as f32 * 0.137,
                (k % 17) as f32 * 0.31,
                (k % 5) as f32 * 0.7,
            );
            let v = fbm(p, 3);
            assert!((0.0..1.0).contains(&v), "{v}");
            lo = lo.min(v);
            hi = hi.max(v);
        }
        assert!(hi - lo > 0.4, "{lo}..{hi}");
        // Continuous: a tiny step changes it a little.
        let p = Vec3::new(1.3, 2.7, -0.4);
        assert!((value_noise(p, 1) - value_noise(p + Vec3::splat(1e-4), 1)).abs() < 1e-2);
    }

    #[test]
    fn the_scope_angle_is_measured_between_shaft_and_axis() {
        let mut f = sample();
        let eye = Vec3::new(0.0, 0.1, 0.1);
        // Shaft straight down from the port; an axis 30 degrees off it.
        f.scope.port = eye + Vec3::Y * 0.05;
        let target = eye + Vec3::new(30f32.to_radians().sin(), -30f32.to_radians().cos(), 0.0);
        assert!((f.scope_axis_angle_deg(eye, target) - 30.0).abs() < 1e-3);
    }

    #[test]
    fn an_angled_scope_enters_where_its_shaft_meets_the_lining() {
        let view = Viewpoint {
            eye: Vec3::new(0.0, 0.05, 0.12),
            target: Vec3::ZERO,
        };
        let f = OperativeField::with_scope(sample().shapes, &view, 70.0, 30.0);
        assert!((f.scope_axis_angle_deg(view.eye, view.target) - 30.0).abs() < 0.01);
        // On the cavity's ellipsoid (before relief), behind the tip.
        let u = f.scope.port / Vec3::new(0.2, 0.15, 0.25);
        assert!((u.length() - 1.0).abs() < 1e-4, "{}", u.length());
        assert!((f.scope.port - view.target).length() > (view.eye - view.target).length());
        // The shaft is shallower than the line of sight: the port lies below the line of
        // sight followed back from the tip (the angled lens looks down over the field).
        let axis = (view.target - view.eye).normalize();
        let back = (f.scope.port - view.eye).normalize();
        assert!(back.y < (-axis).y, "{back} {axis}");
    }
}
