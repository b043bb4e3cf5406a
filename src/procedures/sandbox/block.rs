//! The block: a closed box surface on an even grid of square cells, two triangles a cell, so
//! every simplex point stands for about the same area and the model behaves the same wherever
//! it is touched. Plain (sharp) edges: the faces' centroids lie exactly on the box's planes, so
//! depth into the undeformed block is the distance to a plane.

use crate::mesh::TriMesh;
use glam::Vec3;
use std::collections::HashMap;

/// The sides (front, back, left, right): ordinary tissue.
pub const REGION_SIDES: u8 = 0;
/// The top: what the probe presses and the grasper lifts.
pub const REGION_TOP: u8 = 1;
/// The bottom, resting on the table.
pub const REGION_BOTTOM: u8 = 2;

/// The undeformed block: an axis-aligned box on the table top (y = 0), centred on x = z = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockShape {
    /// Width, height and depth, m.
    pub size_m: Vec3,
}

impl BlockShape {
    pub fn centre(&self) -> Vec3 {
        Vec3::new(0.0, 0.5 * self.size_m.y, 0.0)
    }

    /// Height of the top face, m.
    pub fn top_y(&self) -> f32 {
        self.size_m.y
    }

    /// Signed distance from `p` to the box's surface: negative inside, m.
    pub fn signed_distance(&self, p: Vec3) -> f32 {
        let q = (p - self.centre()).abs() - 0.5 * self.size_m;
        q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
    }

    /// How deep a sphere at `centre` of `radius_m` reaches into the box, m (0: not at all).
    pub fn penetration(&self, centre: Vec3, radius_m: f32) -> f32 {
        (radius_m - self.signed_distance(centre)).max(0.0)
    }

    /// Whether `p` lies over (or under) the top face.
    pub fn over_top(&self, p: Vec3) -> bool {
        p.x.abs() <= 0.5 * self.size_m.x && p.z.abs() <= 0.5 * self.size_m.z
    }
}

/// The block's surface with `cells` cells along x, y and z, and the region of each triangle.
pub fn block(shape: &BlockShape, cells: [u32; 3]) -> (TriMesh, Vec<u8>) {
    let n = cells.map(|c| c.max(1));
    let lo = shape.centre() - 0.5 * shape.size_m;
    let step = shape.size_m / Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32);
    let mut mesh = TriMesh::default();
    let mut regions = Vec::new();
    // Lattice points are shared between the sides that meet at an edge: one vertex each.
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut vertex = |l: [u32; 3], mesh: &mut TriMesh| -> u32 {
        *index.entry(l).or_insert_with(|| {
            let [i, j, k] = l.map(|c| c as f32);
            mesh.positions.push(lo + step * Vec3::new(i, j, k));
            mesh.positions.len() as u32 - 1
        })
    };
    for axis in 0..3 {
        for high in [false, true] {
            // In-plane axes (u, v) with u x v along the outward normal, so that cells wound
            // u then v are counter-clockwise seen from outside.
            let (u, v) = if high {
                ((axis + 1) % 3, (axis + 2) % 3)
            } else {
                ((axis + 2) % 3, (axis + 1) % 3)
            };
            let region = match (axis, high) {
                (1, true) => REGION_TOP,
                (1, false) => REGION_BOTTOM,
                _ => REGION_SIDES,
            };
            for a in 0..n[u] {
                for b in 0..n[v] {
                    let corner = |da: u32, db: u32| {
                        let mut l = [0u32; 3];
                        l[axis] = if high { n[axis] } else { 0 };
                        l[u] = a + da;
                        l[v] = b + db;
                        l
                    };
                    let [p00, p10, p11, p01] =
                        [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)]
                            .map(|l| vertex(l, &mut mesh));
                    // Diagonals alternate like a chequerboard, so the surface is as stiff
                    // one way as the other and a press on a lattice point pushes straight
                    // back.
                    if (a + b) % 2 == 0 {
                        mesh.triangles.push([p00, p10, p11]);
                        mesh.triangles.push([p00, p11, p01]);
                    } else {
                        mesh.triangles.push([p00, p10, p01]);
                        mesh.triangles.push([p10, p11, p01]);
                    }
                    regions.extend([region, region]);
                }
            }
        }
    }
    (mesh, regions)
}
