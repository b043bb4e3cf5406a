//! What a cut leaves on a solid organ's surface, for drawing. The body is a surface, and a cut
//! removes whole faces, so the hole it leaves has a ragged outline of triangle edges and shows
//! whatever lies behind. Here each hole's outline is smoothed along itself (Taubin's
//! lambda-mu filter, which does not shrink the loop) and the hole is closed by a shallow bed of
//! raw tissue: a wall down from the outline, in two bands, and a floor. Where an energy
//! instrument cut, the outline and the upper band are seared (charred). Only the drawing
//! changes: the physics keeps its faces as they are.

use crate::sim::ModelSnapshot;
use glam::Vec3;
use std::collections::{HashMap, HashSet};

/// Depth of the bed under the outline, m (at most half the hole's mean radius, so a narrow
/// groove stays shallow).
pub const BED_DEPTH_M: f32 = 0.004;
/// The floor is this much narrower than the outline (a sloping wall), as a share of the
/// distance to the hole's middle.
const WALL_INSET: f32 = 0.25;
/// Taubin's filter: passes, and the shrinking and inflating weights.
const SMOOTH_PASSES: usize = 8;
const LAMBDA: f32 = 0.5;
const MU: f32 = -0.53;

/// Per vertex, what the drawing makes of it beyond its region: cut tissue (raw) and seared.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CutLook {
    pub raw: bool,
    pub seared: bool,
}

/// What one pass over a surface's triangles finds of the vertices `open` accepts: the edges
/// whose two ends it accepts, in the order the triangles come; each accepted vertex's first
/// triangle; and the triangles with an accepted corner.
struct OpenScan {
    edges: Vec<(u32, u32)>,
    first: Vec<u32>,
    touching: Vec<u32>,
}

/// No triangle (in [`OpenScan::first`]).
const NONE: u32 = u32::MAX;

impl OpenScan {
    fn of(m: &ModelSnapshot, open: impl Fn(u32) -> bool) -> Self {
        let mut scan = OpenScan {
            edges: Vec::new(),
            first: vec![NONE; m.positions.len()],
            touching: Vec::new(),
        };
        for (t, tri) in m.indices.chunks_exact(3).enumerate() {
            let ok = [tri[0], tri[1], tri[2]].map(&open);
            if ok == [false; 3] {
                continue;
            }
            scan.touching.push(t as u32);
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if ok[k]
                    && let Some(f) = scan.first.get_mut(a as usize)
                    && *f == NONE
                {
                    *f = t as u32;
                }
                if ok[k] && ok[(k + 1) % 3] {
                    scan.edges.push((a, b));
                }
            }
        }
        scan
    }
}

/// The holes' outlines in `m`: closed loops of boundary edges (an edge of one triangle whose
/// reverse no triangle has), in the direction the triangles run, in the order the triangles
/// come. A loop through a vertex where two boundaries touch is left out. Only edges whose two
/// ends `open` accepts are looked at (a boundary edge's reverse has the same ends, so a
/// boundary among them is found whole).
#[cfg(test)]
pub fn holes(m: &ModelSnapshot, open: impl Fn(u32) -> bool) -> Vec<Vec<u32>> {
    outlines(&OpenScan::of(m, open).edges)
}

/// The closed loops of boundary edges among `edges` (see [`holes`]).
fn outlines(edges: &[(u32, u32)]) -> Vec<Vec<u32>> {
    let all: HashSet<(u32, u32)> = edges.iter().copied().collect();
    // Boundary edges, in the order the triangles come.
    let mut order = Vec::new();
    let mut next: HashMap<u32, u32> = HashMap::new();
    let mut pinched: HashSet<u32> = HashSet::new();
    for &(a, b) in edges {
        if !all.contains(&(b, a)) {
            if next.insert(a, b).is_some() {
                pinched.insert(a);
            }
            order.push(a);
        }
    }
    let mut seen: HashSet<u32> = HashSet::with_capacity(order.len());
    let mut loops = Vec::new();
    for &start in &order {
        if !seen.insert(start) {
            continue;
        }
        let mut ring = vec![start];
        let mut at = start;
        let mut closed = false;
        while ring.len() <= order.len() {
            let Some(&b) = next.get(&at) else { break };
            if b == start {
                closed = true;
                break;
            }
            if !seen.insert(b) {
                break;
            }
            ring.push(b);
            at = b;
        }
        if closed && ring.len() >= 3 && !ring.iter().any(|v| pinched.contains(v)) {
            loops.push(ring);
        }
    }
    loops
}

/// Smooths `ring`'s points along the loop (Taubin: a shrinking and an inflating Laplacian
/// step per pass, so the loop keeps its size).
pub fn smooth_loop(points: &mut [Vec3]) {
    let n = points.len();
    if n < 3 {
        return;
    }
    let mut next = points.to_vec();
    for _ in 0..SMOOTH_PASSES {
        for w in [LAMBDA, MU] {
            for i in 0..n {
                let mid = (points[(i + n - 1) % n] + points[(i + 1) % n]) * 0.5;
                next[i] = points[i] + (mid - points[i]) * w;
            }
            points.copy_from_slice(&next);
        }
    }
}

/// Smooths the outline of every hole in `m` and closes it with a bed of raw tissue; returns
/// how each vertex looks (the new ones appended). `seared`: an energy instrument made the
/// cuts, so outlines and upper walls are charred.
pub fn close_cuts(m: &mut ModelSnapshot, seared: bool) -> Vec<CutLook> {
    let mut look: Vec<CutLook> = m
        .cut_edge
        .iter()
        .map(|&raw| CutLook { raw, seared: false })
        .collect();
    look.resize(m.positions.len(), CutLook::default());
    // A hole's outline runs through the vertices a cut split (`cut_edge`): only their edges
    // are looked at, and an uncut body (every frame until the first cut) costs one scan.
    if !look.iter().any(|l| l.raw) {
        return look;
    }
    // One pass over the triangles; an outline's vertices are all cut, so what follows looks
    // at the triangles with a cut corner only.
    let scan = OpenScan::of(m, |v| look[v as usize].raw);
    let loops = outlines(&scan.edges);
    // Each outline's region: that of the first triangle with a corner at the outline's first
    // vertex.
    let region_of = |v: u32| match scan.first.get(v as usize) {
        Some(&t) if t != NONE => m.regions.get(t as usize).copied().unwrap_or(0),
        _ => 0,
    };
    let regions: Vec<u8> = loops.iter().map(|ring| region_of(ring[0])).collect();
    // The surface's own triangles: where one has a corner on an outline, a corner off it
    // goes first, so that the triangle keeps the surface's look (the first corner sets the
    // flat attributes) and the outline shows as the smoothed loop, not a fringe of triangles.
    let surface_triangles = m.indices.len() / 3;
    let mut on_outline = vec![false; m.positions.len()];
    for ring in &loops {
        for &v in ring {
            on_outline[v as usize] = true;
        }
    }
    for &t in &scan.touching {
        let t = t as usize;
        let tri = &mut m.indices[3 * t..3 * t + 3];
        if let Some(k) = (0..3).find(|&k| !on_outline[tri[k] as usize])
            && k > 0
        {
            tri.rotate_left(k);
        }
    }
    debug_assert_eq!(surface_triangles * 3, m.indices.len());
    for (ring, region) in loops.into_iter().zip(regions) {
        let mut p: Vec<Vec3> = ring.iter().map(|&v| m.positions[v as usize]).collect();
        smooth_loop(&mut p);
        for (&v, &q) in ring.iter().zip(&p) {
            m.positions[v as usize] = q;
            look[v as usize] = CutLook { raw: true, seared };
        }
        let n = p.len();
        let centre = p.iter().copied().sum::<Vec3>() / n as f32;
        // Outward: the surface's normals along the outline (the loop's own turn is the
        // other way round: seen from outside, a hole's outline runs clockwise).
        let mut normal: Vec3 = ring
            .iter()
            .map(|&v| m.normals.get(v as usize).copied().unwrap_or(Vec3::ZERO))
            .sum::<Vec3>()
            .normalize_or_zero();
        if normal == Vec3::ZERO {
            let mut newell = Vec3::ZERO;
            for i in 0..n {
                newell += p[i].cross(p[(i + 1) % n]);
            }
            normal = -newell.normalize_or_zero();
        }
        let radius = p.iter().map(|q| q.distance(centre)).sum::<f32>() / n as f32;
        let depth = BED_DEPTH_M.min(0.5 * radius);
        if depth <= 0.0 || normal == Vec3::ZERO {
            continue;
        }
        let base = m.positions.len() as u32;
        // Middle ring, bottom ring, then the floor's middle.
        for (band, (down, inset)) in [(0.5, 0.5 * WALL_INSET), (1.0, WALL_INSET)]
            .into_iter()
            .enumerate()
        {
            for q in &p {
                let inward = centre - *q;
                let at = *q + inward * inset - normal * depth * down;
                let towards_axis = (inward - normal * inward.dot(normal)).normalize_or_zero();
                m.positions.push(at);
                m.normals
                    .push((towards_axis + normal * (0.5 + band as f32)).normalize_or_zero());
                look.push(CutLook {
                    raw: true,
                    seared: false,
                });
            }
        }
        m.positions.push(centre - normal * depth);
        m.normals.push(normal);
        look.push(CutLook {
            raw: true,
            seared: false,
        });
        let n32 = n as u32;
        let outer = |i: usize| ring[i % n];
        let mid = |i: usize| base + (i % n) as u32;
        let low = |i: usize| base + n32 + (i % n) as u32;
        let floor = base + 2 * n32;
        // The first vertex of each triangle sets its flat attributes (seared or raw): the
        // upper band starts on the outline, the lower band and the floor below it.
        for i in 0..n {
            m.indices.extend_from_slice(&[
                outer(i + 1),
                outer(i),
                mid(i),
                outer(i + 1),
                mid(i),
                mid(i + 1),
            ]);
            m.indices.extend_from_slice(&[
                mid(i + 1),
                mid(i),
                low(i),
                mid(i + 1),
                low(i),
                low(i + 1),
            ]);
            m.indices.extend_from_slice(&[low(i + 1), low(i), floor]);
            m.regions.extend_from_slice(&[region; 5]);
        }
    }
    m.cut_edge = look.iter().map(|l| l.raw).collect();
    look
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat grid in the xy plane (normal +z), `cells` squares a side of `h` metres, each
    /// split in two, less the triangles whose middle lies within `r` of the grid's middle.
    fn holed_grid(cells: usize, h: f32, r: f32) -> ModelSnapshot {
        let side = cells + 1;
        let positions: Vec<Vec3> = (0..side * side)
            .map(|k| Vec3::new((k % side) as f32 * h, (k / side) as f32 * h, 0.0))
            .collect();
        let mid = Vec3::new(cells as f32 * h / 2.0, cells as f32 * h / 2.0, 0.0);
        let mut indices = Vec::new();
        for j in 0..cells {
            for i in 0..cells {
                let v = |di: usize, dj: usize| ((j + dj) * side + i + di) as u32;
                for t in [[v(0, 0), v(1, 0), v(1, 1)], [v(0, 0), v(1, 1), v(0, 1)]] {
                    let c = t.iter().map(|&k| positions[k as usize]).sum::<Vec3>() / 3.0;
                    if c.distance(mid) > r {
                        indices.extend_from_slice(&t);
                    }
                }
            }
        }
        let regions = vec![0; indices.len() / 3];
        let mut m = ModelSnapshot {
            name: "grid".into(),
            normals: vec![Vec3::Z; positions.len()],
            cut_edge: vec![false; positions.len()],
            positions,
            indices,
            regions,
            roles: Vec::new(),
            seared: Vec::new(),
        };
        // The boundary's vertices are split, as the soft body marks the vertices a cut
        // passes through.
        for v in holes(&m, |_| true).into_iter().flatten() {
            m.cut_edge[v as usize] = true;
        }
        m
    }

    /// The largest turn between successive edges of the loop, degrees.
    fn sharpest_turn(points: &[Vec3]) -> f32 {
        let n = points.len();
        (0..n)
            .map(|i| {
                let a = points[(i + 1) % n] - points[i];
                let b = points[(i + 2) % n] - points[(i + 1) % n];
                a.angle_between(b).to_degrees()
            })
            .fold(0.0, f32::max)
    }

    /// The loop's area (shoelace, in the xy plane), m^2.
    fn area(points: &[Vec3]) -> f32 {
        let n = points.len();
        (0..n)
            .map(|i| points[i].x * points[(i + 1) % n].y - points[(i + 1) % n].x * points[i].y)
            .sum::<f32>()
            .abs()
            / 2.0
    }

    #[test]
    fn a_ragged_hole_gets_a_smooth_outline_of_the_same_size_and_a_closed_bed() {
        let (h, r) = (0.001, 0.009);
        let mut m = holed_grid(30, h, r);
        let loops = holes(&m, |_| true);
        assert_eq!(loops.len(), 2, "the grid's rim and the hole");
        // The hole is the shorter loop.
        let hole = loops
            .iter()
            .min_by_key(|l| l.len())
            .expect("a hole")
            .clone();
        let before: Vec<Vec3> = hole.iter().map(|&v| m.positions[v as usize]).collect();
        assert!(sharpest_turn(&before) >= 89.0, "{}", sharpest_turn(&before));
        let area_before = area(&before);
        let look = close_cuts(&mut m, true);
        let after: Vec<Vec3> = hole.iter().map(|&v| m.positions[v as usize]).collect();
        let turn = sharpest_turn(&after);
        assert!(turn < 30.0, "sharpest turn {turn} degrees");
        let change = area(&after) / area_before - 1.0;
        eprintln!(
            "sharpest turn {:.0} -> {turn:.1} degrees, area {:+.2}%",
            sharpest_turn(&before),
            change * 100.0
        );
        assert!(
            change.abs() < 0.08,
            "area changed by {:.1}%",
            change * 100.0
        );
        // The grid's rim is smoothed too (it is a boundary); the hole is closed: every edge
        // of the hole's outline now has a triangle on each side.
        let outline: std::collections::HashSet<u32> = hole.iter().copied().collect();
        let after_loops = holes(&m, |_| true);
        assert!(
            after_loops
                .iter()
                .all(|l| l.iter().all(|v| !outline.contains(v))),
            "the hole is closed"
        );
        // The hole comes after the rim: its floor's middle is the last vertex, the bed's
        // depth below the surface, and its last triangle faces out; the outline is seared.
        let floor = m.positions[m.positions.len() - 1].z;
        assert!((floor + BED_DEPTH_M).abs() < 1e-6, "floor at {floor}");
        let last = m.indices.len() - 3;
        let t: Vec<Vec3> = m.indices[last..]
            .iter()
            .map(|&v| m.positions[v as usize])
            .collect();
        let facing = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
        assert!(facing.z > 0.99, "floor faces {facing}");
        assert!(hole.iter().all(|&v| look[v as usize].seared));
        assert!(look[m.positions.len() - 1].raw && !look[m.positions.len() - 1].seared);
        assert_eq!(m.regions.len() * 3, m.indices.len());
        assert_eq!(m.cut_edge.len(), m.positions.len());
    }

    #[test]
    fn a_closed_surface_has_no_holes_and_is_left_as_it_is() {
        let sphere = crate::mesh::icosphere(2);
        let mut m = ModelSnapshot {
            name: "ball".into(),
            normals: sphere.positions.iter().map(|v| v.normalize()).collect(),
            cut_edge: vec![false; sphere.positions.len()],
            positions: sphere.positions.iter().map(|v| *v * 0.01).collect(),
            indices: sphere.triangles.iter().flatten().copied().collect(),
            regions: vec![0; sphere.triangles.len()],
            roles: Vec::new(),
            seared: Vec::new(),
        };
        let before = m.clone();
        assert!(holes(&m, |_| true).is_empty());
        let look = close_cuts(&mut m, true);
        assert_eq!(m.positions, before.positions);
        assert_eq!(m.indices, before.indices);
        assert!(look.iter().all(|l| !l.raw && !l.seared));
    }
}
