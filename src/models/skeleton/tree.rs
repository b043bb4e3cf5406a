//! A vessel tree from centrelines: each vessel a polyline with a diameter, leaving its parent
//! at its first point. The tree is cut into straight tubes for the wall ([`super::vessel`]):
//! one per segment of a centreline, and a parent's segment cut again where a child leaves it
//! part-way, so each tube's blood (and contrast) flows on from one tube: the one it leaves.
//! Tubes come in the vessels' order (parents before children), each vessel's from its start.

use super::vessel::Branch;
use glam::DVec3;

/// A cut nearer than this to a centreline's point is made at the point, m.
pub const SNAP_M: f64 = 0.001;

/// One vessel of a tree: its name, its parent (an earlier vessel; none for the root, whose
/// first point is the inlet), its diameter (outer, m) and its centreline's points (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Centreline {
    pub name: String,
    pub parent: Option<usize>,
    pub diameter_m: f64,
    pub points: Vec<DVec3>,
}

impl Centreline {
    /// The centreline's length, m.
    pub fn length_m(&self) -> f64 {
        self.points.windows(2).map(|w| w[0].distance(w[1])).sum()
    }

    /// The point of the centreline nearest `p`: its segment, how far along that segment, and
    /// the distance (none for fewer than two points).
    pub fn nearest(&self, p: DVec3) -> Option<(usize, f64, f64)> {
        let (j, t, dist2) = nearest_segment(&self.points, p)?;
        let len = self.points[j].distance(self.points[j + 1]);
        Some((j, t.clamp(0.0, 1.0) * len, dist2.sqrt()))
    }
}

/// One straight tube of the tree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TubeSpec {
    pub start: DVec3,
    /// A unit direction.
    pub dir: DVec3,
    pub length_m: f64,
    /// The outer diameter, m.
    pub diameter_m: f64,
    /// The tube its blood comes from (none: the root's first).
    pub parent: Option<usize>,
    /// The vessel it is part of, and how far along that vessel's centreline it starts, m.
    pub vessel: usize,
    pub offset_m: f64,
}

/// The tree's tubes. Segments shorter than [`SNAP_M`] are skipped; a child with no parent
/// tube yet (which a checked tree never has) starts as a root would.
pub fn tubes(tree: &[Centreline]) -> Vec<TubeSpec> {
    let mut out: Vec<TubeSpec> = Vec::new();
    // Where each vessel's children leave it: (segment, distance along it).
    let mut leaves: Vec<Vec<(usize, f64)>> = vec![Vec::new(); tree.len()];
    for c in tree {
        if let (Some(p), Some(first)) = (c.parent, c.points.first())
            && let Some((j, t, _)) = tree.get(p).and_then(|v| v.nearest(*first))
        {
            leaves[p].push((j, t));
        }
    }
    // Each vessel's tubes, with how far along its centreline each ends.
    let mut ends: Vec<Vec<(usize, f64)>> = vec![Vec::new(); tree.len()];
    for (vi, v) in tree.iter().enumerate() {
        let mut parent = v.parent.and_then(|p| {
            let first = *v.points.first()?;
            let pv = tree.get(p)?;
            let (j, t, _) = pv.nearest(first)?;
            let s = pv.points[..=j]
                .windows(2)
                .map(|w| w[0].distance(w[1]))
                .sum::<f64>()
                + t;
            // The parent's tube that ends where the child leaves (or nearest it).
            ends.get(p)?
                .iter()
                .min_by(|a, b| (a.1 - s).abs().total_cmp(&(b.1 - s).abs()))
                .map(|e| e.0)
        });
        let mut offset = 0.0;
        for (j, w) in v.points.windows(2).enumerate() {
            let d = w[1] - w[0];
            let len = d.length();
            if len < SNAP_M {
                offset += len;
                continue;
            }
            let dir = d / len;
            let mut cuts: Vec<f64> = leaves[vi]
                .iter()
                .filter(|&&(s, t)| s == j && t > SNAP_M && t < len - SNAP_M)
                .map(|&(_, t)| t)
                .collect();
            cuts.sort_by(f64::total_cmp);
            cuts.dedup_by(|a, b| *a - *b < SNAP_M);
            cuts.push(len);
            let mut from = 0.0;
            for cut in cuts {
                let k = out.len();
                out.push(TubeSpec {
                    start: w[0] + dir * from,
                    dir,
                    length_m: cut - from,
                    diameter_m: v.diameter_m,
                    parent,
                    vessel: vi,
                    offset_m: offset + from,
                });
                ends[vi].push((k, offset + cut));
                parent = Some(k);
                from = cut;
            }
            offset += len;
        }
    }
    out
}

/// The segment of the polyline `points` nearest `x` (the first of equals), the parameter of the
/// nearest point's projection along it (unclamped: below 0 before its first point, above 1
/// past its second) and the squared distance to the segment.
pub fn nearest_segment(points: &[DVec3], x: DVec3) -> Option<(usize, f64, f64)> {
    let mut best: Option<(usize, f64, f64)> = None;
    for j in 0..points.len().saturating_sub(1) {
        let (a, b) = (points[j], points[j + 1]);
        let d = b - a;
        let len2 = d.length_squared();
        if len2 <= 0.0 {
            continue;
        }
        let t = (x - a).dot(d) / len2;
        let p = a + d * t.clamp(0.0, 1.0);
        let dist2 = p.distance_squared(x);
        if best.is_none_or(|(_, _, bd)| dist2 < bd) {
            best = Some((j, t, dist2));
        }
    }
    best
}

/// The tree's tubes ([`tubes`]) and its named vessels.
pub fn tubes_and_branches(tree: &[Centreline]) -> (Vec<TubeSpec>, Vec<Branch>) {
    let branches = tree
        .iter()
        .map(|c| Branch {
            name: c.name.clone(),
            parent: c.parent,
            length_m: c.length_m(),
        })
        .collect();
    (tubes(tree), branches)
}

/// The turn between two directions, degrees.
pub fn turn_deg(a: DVec3, b: DVec3) -> f64 {
    a.normalize_or_zero()
        .dot(b.normalize_or_zero())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(name: &str, parent: Option<usize>, d: f64, points: &[[f64; 3]]) -> Centreline {
        Centreline {
            name: name.into(),
            parent,
            diameter_m: d,
            points: points.iter().map(|p| DVec3::from_array(*p)).collect(),
        }
    }

    #[test]
    fn a_side_branch_cuts_its_parent_where_it_leaves() {
        // An aorta of two segments, a renal leaving the first 30 mm along it, an iliac
        // leaving the end.
        let tree = [
            line(
                "aorta",
                None,
                0.02,
                &[[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.09, 0.0, 0.0]],
            ),
            line(
                "renal",
                Some(0),
                0.008,
                &[[0.03, 0.0, 0.0], [0.03, 0.04, 0.0]],
            ),
            line(
                "iliac",
                Some(0),
                0.012,
                &[[0.09, 0.0, 0.0], [0.12, -0.02, 0.0]],
            ),
        ];
        let t = tubes(&tree);
        assert_eq!(t.len(), 5, "{t:#?}");
        // The aorta: 0-30 mm, 30-50 mm, 50-90 mm.
        let lengths: Vec<f64> = t[..3].iter().map(|s| s.length_m).collect();
        for (l, want) in lengths.iter().zip([0.03, 0.02, 0.04]) {
            assert!((l - want).abs() < 1e-12, "{lengths:?}");
        }
        assert_eq!(
            t.iter().map(|s| s.parent).collect::<Vec<_>>(),
            [None, Some(0), Some(1), Some(0), Some(2)]
        );
        assert_eq!(
            t.iter().map(|s| s.vessel).collect::<Vec<_>>(),
            [0, 0, 0, 1, 2]
        );
        assert!((t[2].offset_m - 0.05).abs() < 1e-12);
        assert!((t[3].diameter_m - 0.008).abs() < 1e-15);
        assert!((t[3].dir - DVec3::Y).length() < 1e-12);
        assert!((tree[0].length_m() - 0.09).abs() < 1e-12);
    }

    #[test]
    fn nearest_points_and_turns() {
        let v = line("v", None, 0.02, &[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]);
        let (j, t, d) = v.nearest(DVec3::new(0.04, 0.003, 0.0)).unwrap_or_default();
        assert_eq!(j, 0);
        assert!((t - 0.04).abs() < 1e-12 && (d - 0.003).abs() < 1e-12);
        assert!((turn_deg(DVec3::X, DVec3::new(1.0, 1.0, 0.0)) - 45.0).abs() < 1e-9);
    }

    /// A vessel built from a tree: each tube's balls at its own wall's mid-radius; a point
    /// in the side branch is located in it, along it from its start, astray for a task
    /// that targets the other vessel, and its path from the inlet runs through the cut.
    #[test]
    fn a_vessel_from_a_tree_knows_its_vessels() {
        use crate::models::skeleton::vessel::{Vessel, VesselParams};
        let tree = [
            line("aorta", None, 0.02, &[[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]),
            line(
                "renal",
                Some(0),
                0.01,
                &[[0.04, 0.0, 0.0], [0.04, 0.05, 0.0]],
            ),
            line(
                "iliac",
                Some(0),
                0.014,
                &[[0.1, 0.0, 0.0], [0.14, -0.02, 0.0]],
            ),
        ];
        let p = VesselParams::default();
        let (specs, branches) = tubes_and_branches(&tree);
        let v = Vessel::of_tubes(&p, &specs, branches);
        assert_eq!(v.tubes.len(), 4);
        for t in &v.tubes {
            let d = tree[t.vessel].diameter_m;
            assert!((t.mid_radius_m - 0.5 * (d - p.wall_m)).abs() < 1e-15);
            for &b in t.sections.iter().flatten() {
                let r = t.from_axis(v.balls.x[b as usize]);
                assert!((r - t.mid_radius_m).abs() < 1e-9, "{r} {}", t.mid_radius_m);
            }
        }
        // 30 mm up the renal, 1 mm off its axis.
        let p = DVec3::new(0.041, 0.03, 0.0);
        let (k, along) = v.locate(p).unwrap_or((usize::MAX, 0.0));
        assert_eq!((k, v.tubes[k].vessel), (2, 1));
        assert!((along - 0.03).abs() < 1e-12);
        assert!((v.along_branch(1, p).unwrap_or_default() - 0.03).abs() < 1e-12);
        assert_eq!(v.along_branch(2, p), None);
        assert_eq!(v.astray(2, p, 0.01), Some(1));
        assert_eq!(v.astray(1, p, 0.01), None);
        assert_eq!(v.astray(2, p, 0.04), None);
        assert!((v.path_m(p) - 0.07).abs() < 1e-12, "{}", v.path_m(p));
        assert!(v.leads_to(0, 2) && v.leads_to(2, 2) && !v.leads_to(1, 2));
        // In the aorta past the renal: on from the cut, 60 mm into the aorta.
        let q = DVec3::new(0.06, 0.0, 0.001);
        assert_eq!(v.locate(q).map(|l| l.0), Some(1));
        assert!((v.along_branch(0, q).unwrap_or_default() - 0.06).abs() < 1e-12);
        assert!((v.path_m(q) - 0.06).abs() < 1e-12);
        assert_eq!(v.locate(DVec3::new(0.06, 0.02, 0.0)), None);
    }
}
