//! A closed triangle mesh as a solid: whether a point lies inside it, by the parity of the
//! surface's crossings along a line through the point. The crossings of a whole line are
//! found once and kept, so filling a lattice costs one pass over the triangles per row, not
//! per point.

use super::TriMesh;
use glam::{Vec2, Vec3};

/// A closed surface (any winding), for inside tests along lines parallel to x.
#[derive(Debug, Clone)]
pub struct Solid {
    mesh: TriMesh,
    lo: Vec3,
    hi: Vec3,
}

/// Rows are moved this small fraction of the box off their (y, z) so that a row through a
/// mesh vertex or edge (a lattice meets an axis-aligned mesh's edges) still crosses each
/// face once.
const NUDGE: f32 = 1.0e-5;

impl Solid {
    /// The solid `mesh` bounds; none for a mesh with no triangles or a point not finite.
    pub fn new(mesh: TriMesh) -> Option<Solid> {
        if mesh.triangles.is_empty() || !mesh.positions.iter().all(|p| p.is_finite()) {
            return None;
        }
        let lo = mesh.positions.iter().fold(Vec3::INFINITY, |a, p| a.min(*p));
        let hi = mesh
            .positions
            .iter()
            .fold(Vec3::NEG_INFINITY, |a, p| a.max(*p));
        Some(Solid { mesh, lo, hi })
    }

    /// The bounding box's corners, m.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }

    /// Where the line through (y, z) parallel to x crosses the surface: the crossings' x,
    /// sorted. Between the first and second, third and fourth, ... is inside.
    pub fn row(&self, y: f32, z: f32) -> Vec<f32> {
        let size = (self.hi - self.lo).max_element();
        // An odd direction (not one a regular mesh's edges take: the golden ratio's 0.618 and
        // 0.382 lie along an icosphere's edges).
        let q = Vec2::new(y + NUDGE * size * 0.8191, z + NUDGE * size * 0.2631);
        let mut xs = Vec::new();
        for t in &self.mesh.triangles {
            let [a, b, c] = t.map(|i| self.mesh.positions[i as usize]);
            let (a2, b2, c2) = (
                Vec2::new(a.y, a.z),
                Vec2::new(b.y, b.z),
                Vec2::new(c.y, c.z),
            );
            let area = (b2 - a2).perp_dot(c2 - a2);
            if area.abs() <= f32::MIN_POSITIVE {
                continue;
            }
            let u = (c2 - b2).perp_dot(q - b2) / area;
            let v = (a2 - c2).perp_dot(q - c2) / area;
            let w = 1.0 - u - v;
            if u >= 0.0 && v >= 0.0 && w >= 0.0 {
                xs.push(u * a.x + v * b.x + w * c.x);
            }
        }
        xs.sort_by(f32::total_cmp);
        xs
    }

    /// Whether `p` lies inside, given its row's crossings ([`Solid::row`]).
    pub fn inside_row(crossings: &[f32], x: f32) -> bool {
        crossings.iter().filter(|&&c| c < x).count() % 2 == 1
    }

    /// Whether `p` lies inside (one row's work: use [`Solid::row`] for many points).
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.lo).all()
            && p.cmple(self.hi).all()
            && Self::inside_row(&self.row(p.y, p.z), p.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_inside_a_sphere_mesh_are_inside_and_its_volume_is_found() {
        let mut m = crate::mesh::icosphere(3);
        for p in &mut m.positions {
            *p = *p * 0.01 + Vec3::new(0.1, 0.0, -0.02);
        }
        let s = Solid::new(m.clone()).expect("solid");
        assert!(s.contains(Vec3::new(0.1, 0.0, -0.02)));
        assert!(s.contains(Vec3::new(0.1, 0.009, -0.02)));
        assert!(!s.contains(Vec3::new(0.1, 0.0105, -0.02)));
        assert!(!s.contains(Vec3::new(0.0, 0.0, 0.0)));
        // Counting lattice points inside gives the mesh's own volume.
        let h = 0.0005;
        let (lo, hi) = s.bounds();
        let mut count = 0usize;
        let mut y = lo.y;
        while y <= hi.y {
            let mut z = lo.z;
            while z <= hi.z {
                let row = s.row(y, z);
                let mut x = lo.x;
                while x <= hi.x {
                    count += usize::from(Solid::inside_row(&row, x));
                    x += h;
                }
                z += h;
            }
            y += h;
        }
        let v = count as f32 * h * h * h;
        assert!((v / m.volume() - 1.0).abs() < 0.03, "{v} vs {}", m.volume());
    }

    #[test]
    fn a_row_through_a_box_edge_still_sees_inside() {
        // A unit cube; the row y = z = 0 runs along its edge-sharing diagonal faces.
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let triangles = vec![
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [3, 6, 2],
            [3, 7, 6],
            [0, 4, 7],
            [0, 7, 3],
            [1, 2, 6],
            [1, 6, 5],
        ];
        let s = Solid::new(TriMesh {
            positions,
            triangles,
        })
        .expect("solid");
        for (y, z) in [(0.5, 0.5), (0.0, 0.0), (0.5, 0.0), (1.0, 1.0)] {
            let row = s.row(y, z);
            assert_eq!(row.len() % 2, 0, "({y}, {z}): {row:?}");
            assert!(
                Solid::inside_row(&row, 0.5) || (y, z) == (1.0, 1.0),
                "({y}, {z})"
            );
        }
    }
}
