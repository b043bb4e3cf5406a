//! The block: a closed box surface of near-equilateral triangles in alternating rows, so every
//! simplex point stands for about the same area and the model behaves the same wherever and
//! in whichever direction it is touched. Plain (sharp) edges: the faces' centroids lie exactly on the box's planes, so
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

/// Row spacing over column spacing of an equilateral triangle lattice.
const ROW_RATIO: f32 = 0.866_025_4;

/// How many segments each of the box's edges along x, y and z is divided into, for
/// `resolution` segments along the longest edge: the other edges get rows of equilateral
/// triangles (spacing sqrt(3)/2 of the longest's), rounded to an even count so the rows
/// alternate evenly.
pub fn divisions(size_m: Vec3, resolution: u32) -> [u32; 3] {
    let longest = size_m.max_element().max(f32::MIN_POSITIVE);
    let step = longest / resolution.max(1) as f32;
    let li = (0..3).find(|&a| size_m[a] >= longest).unwrap_or(0);
    [0, 1, 2].map(|a| {
        if a == li {
            resolution.max(1)
        } else {
            ((size_m[a] / (step * ROW_RATIO) / 2.0).round() as u32).max(1) * 2
        }
    })
}

/// Of a face's in-plane axes `p` and `q`, the one its rows are stacked along (an even count,
/// the shorter step) and the one along each row: (rows, columns).
fn rows_and_columns(n: [u32; 3], step: [f32; 3], p: usize, q: usize) -> (usize, usize) {
    let even = |a: usize| n[a].is_multiple_of(2);
    match (even(p), even(q)) {
        (true, true) if step[q] < step[p] => (q, p),
        (true, _) => (p, q),
        _ => (q, p),
    }
}

/// Triangles of the block for edge divisions `n` (see [`divisions`]): each face has rows
/// of 2 c + 1 triangles (c columns, every other row shifted half a column).
pub fn triangle_count(size_m: Vec3, n: [u32; 3]) -> u64 {
    let step = [0, 1, 2].map(|a| size_m[a] / n[a].max(1) as f32);
    (0..3)
        .map(|axis| {
            let (r, c) = rows_and_columns(n, step, (axis + 1) % 3, (axis + 2) % 3);
            2 * n[r] as u64 * (2 * n[c] as u64 + 1)
        })
        .sum()
}

/// The block's surface with its edges divided `n` times along x, y and z ([`divisions`]),
/// and the region of each triangle. Each face is a lattice of near-equilateral triangles:
/// rows stacked along one axis, every other row shifted half a column (the rows on the
/// face's border are not, so faces meet edge to edge). Equilateral cells make the shear
/// layer between neighbouring simplex points the same in every direction.
pub fn block(shape: &BlockShape, n: [u32; 3]) -> (TriMesh, Vec<u8>) {
    let n = n.map(|c| c.max(1));
    let lo = shape.centre() - 0.5 * shape.size_m;
    let step = shape.size_m / Vec3::new(n[0] as f32, n[1] as f32, n[2] as f32);
    let steps = [step.x, step.y, step.z];
    let mut mesh = TriMesh::default();
    let mut regions = Vec::new();
    // Lattice points in half steps, shared between the sides that meet at an edge.
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut vertex = |l: [u32; 3], mesh: &mut TriMesh| -> u32 {
        *index.entry(l).or_insert_with(|| {
            let [i, j, k] = l.map(|c| c as f32 * 0.5);
            mesh.positions.push(lo + step * Vec3::new(i, j, k));
            mesh.positions.len() as u32 - 1
        })
    };
    for axis in 0..3 {
        for high in [false, true] {
            // In-plane axes (u, v) with u x v along the outward normal, so that triangles
            // wound counter-clockwise in (u, v) face outward.
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
            let (r, c) = rows_and_columns(n, steps, u, v);
            // Counter-clockwise in (column, row) is clockwise in (u, v) when rows run
            // along u.
            let flip = r == u;
            // A row's points, in half steps along the columns.
            let row = |j: u32| -> Vec<u32> {
                if j % 2 == 1 && j != n[r] {
                    std::iter::once(0)
                        .chain((0..n[c]).map(|i| 2 * i + 1))
                        .chain(std::iter::once(2 * n[c]))
                        .collect()
                } else {
                    (0..=n[c]).map(|i| 2 * i).collect()
                }
            };
            let key = |col: u32, j: u32| {
                let mut l = [0u32; 3];
                l[axis] = if high { 2 * n[axis] } else { 0 };
                l[c] = col;
                l[r] = 2 * j;
                l
            };
            for j in 0..n[r] {
                let (lower, upper) = (row(j), row(j + 1));
                // Zip the two rows together, always advancing the row whose next point
                // comes first.
                let (mut a, mut b) = (0usize, 0usize);
                while a + 1 < lower.len() || b + 1 < upper.len() {
                    let take_lower = b + 1 >= upper.len()
                        || (a + 1 < lower.len() && lower[a + 1] <= upper[b + 1]);
                    let tri = if take_lower {
                        a += 1;
                        [key(lower[a - 1], j), key(lower[a], j), key(upper[b], j + 1)]
                    } else {
                        b += 1;
                        [
                            key(lower[a], j),
                            key(upper[b], j + 1),
                            key(upper[b - 1], j + 1),
                        ]
                    };
                    let [p0, p1, p2] = tri.map(|l| vertex(l, &mut mesh));
                    mesh.triangles
                        .push(if flip { [p0, p2, p1] } else { [p0, p1, p2] });
                    regions.push(region);
                }
            }
        }
    }
    (mesh, regions)
}
