use super::TriMesh;
use glam::Vec3;
use std::collections::HashMap;
use std::f32::consts::PI;

/// A unit icosphere: the icosahedron subdivided `level` times (20 * 4^level triangles).
pub fn icosphere(level: u32) -> TriMesh {
    let t = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(triangles.len() * 4);
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = ((positions[a as usize] + positions[b as usize]) * 0.5).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        for &[a, b, c] in &triangles {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    TriMesh {
        positions,
        triangles,
    }
}

/// Shape of the generated kidney, metres. Long axis along +y (superior), lateral +x,
/// anterior +z. The hilum is a notch on the medial (-x) border.
#[derive(Debug, Clone, Copy)]
pub struct KidneyShape {
    pub half_length_m: f32,
    pub half_width_m: f32,
    pub half_thickness_m: f32,
    pub hilum_depth_m: f32,
}

impl Default for KidneyShape {
    fn default() -> Self {
        // An adult kidney is about 11 x 6 x 4 cm.
        Self {
            half_length_m: 0.055,
            half_width_m: 0.03,
            half_thickness_m: 0.02,
            hilum_depth_m: 0.012,
        }
    }
}

impl KidneyShape {
    /// Maps a unit direction to the kidney surface.
    pub fn surface(&self, d: Vec3) -> Vec3 {
        let mut p = Vec3::new(
            d.x * self.half_width_m,
            d.y * self.half_length_m,
            d.z * self.half_thickness_m,
        );
        // Medial notch: pull the medial border inwards around the equator, smoothly.
        let medial = (-d.x).max(0.0);
        let notch = (-(d.y / 0.35).powi(2) - (d.z / 0.7).powi(2)).exp();
        p.x += self.hilum_depth_m * medial * medial * notch;
        p
    }
}

/// The kidney surface: an icosphere of `level` mapped through [`KidneyShape::surface`].
pub fn kidney(shape: &KidneyShape, level: u32) -> TriMesh {
    let mut m = icosphere(level);
    for p in &mut m.positions {
        *p = shape.surface(*p);
    }
    m
}

/// A closed tube (capped both ends) along a polyline, for vessels and the ureter.
#[derive(Debug, Clone)]
pub struct TubeSpec {
    pub path: Vec<Vec3>,
    pub radius_m: f32,
    pub segments: u32,
    pub rings: u32,
}

/// Builds the tube: `segments` around, `rings` along (resampled along the polyline), with a fan
/// cap at each end. Triangles: 2 * segments * (rings - 1) + 2 * segments.
pub fn tube(spec: &TubeSpec) -> TriMesh {
    let rings = spec.rings.max(2) as usize;
    let seg = spec.segments.max(3) as usize;
    let samples = resample(&spec.path, rings);
    let mut positions = Vec::with_capacity(rings * seg + 2);
    let mut triangles = Vec::new();
    // Parallel-transport frame so the rings do not twist.
    let t0 = (samples[1] - samples[0]).normalize();
    let mut normal = t0.any_orthonormal_vector();
    for i in 0..rings {
        let tangent = if i + 1 < rings {
            (samples[i + 1] - samples[i]).normalize()
        } else {
            (samples[i] - samples[i - 1]).normalize()
        };
        normal = (normal - tangent * normal.dot(tangent)).normalize();
        let binormal = tangent.cross(normal);
        for s in 0..seg {
            let a = 2.0 * PI * s as f32 / seg as f32;
            positions.push(samples[i] + (normal * a.cos() + binormal * a.sin()) * spec.radius_m);
        }
    }
    let idx = |i: usize, s: usize| (i * seg + s % seg) as u32;
    for i in 0..rings - 1 {
        for s in 0..seg {
            triangles.push([idx(i, s), idx(i + 1, s), idx(i + 1, s + 1)]);
            triangles.push([idx(i, s), idx(i + 1, s + 1), idx(i, s + 1)]);
        }
    }
    let start = positions.len() as u32;
    positions.push(samples[0]);
    let end = positions.len() as u32;
    positions.push(samples[rings - 1]);
    for s in 0..seg {
        triangles.push([start, idx(0, s), idx(0, s + 1)]);
        triangles.push([end, idx(rings - 1, s + 1), idx(rings - 1, s)]);
    }
    let mut m = TriMesh {
        positions,
        triangles,
    };
    if m.volume() < 0.0 {
        for t in &mut m.triangles {
            t.swap(1, 2);
        }
    }
    m
}

/// `n` points evenly spaced by arc length along a polyline.
fn resample(path: &[Vec3], n: usize) -> Vec<Vec3> {
    let mut cum = vec![0.0f32];
    for w in path.windows(2) {
        cum.push(cum.last().copied().unwrap_or(0.0) + (w[1] - w[0]).length());
    }
    let total = cum.last().copied().unwrap_or(0.0);
    (0..n)
        .map(|i| {
            let s = total * i as f32 / (n - 1) as f32;
            let k = cum
                .iter()
                .rposition(|&c| c <= s)
                .unwrap_or(0)
                .min(path.len() - 2);
            let seg_len = (cum[k + 1] - cum[k]).max(f32::EPSILON);
            path[k].lerp(path[k + 1], ((s - cum[k]) / seg_len).clamp(0.0, 1.0))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_is_closed_with_expected_counts() {
        let m = icosphere(3);
        assert_eq!(m.triangle_count(), 20 * 64);
        assert_eq!(m.vertex_count(), 10 * 64 + 2);
        let adj = m.edge_adjacency().expect("closed");
        assert!(adj.iter().flatten().all(|&f| f != u32::MAX));
        // Volume approaches 4/3 pi from below.
        let v = m.volume();
        assert!(v > 4.0 && v < 4.0 / 3.0 * PI, "{v}");
    }

    #[test]
    fn tube_is_closed_and_outward() {
        let m = tube(&TubeSpec {
            path: vec![
                Vec3::ZERO,
                Vec3::new(0.0, 0.0, 0.05),
                Vec3::new(0.02, 0.0, 0.08),
            ],
            radius_m: 0.003,
            segments: 12,
            rings: 10,
        });
        assert_eq!(m.triangle_count(), 2 * 12 * 9 + 24);
        m.edge_adjacency().expect("closed");
        assert!(m.volume() > 0.0);
        let fans = m
            .vertex_fans(&m.edge_adjacency().expect("closed"))
            .expect("fans");
        assert_eq!(
            fans.iter().map(Vec::len).sum::<usize>(),
            3 * m.triangle_count()
        );
    }
}
