//! The rectum's anatomy, generated deterministically: the bowel as a tube along a medial axis
//! that follows the sacral curve, the pelvic soft tissue around it as a larger tube, and the
//! four-layer membrane between them built by the paper's generation steps (rectum paper,
//! "Multi-layer mass spring model", steps 1-3):
//!
//! 1. the medial axis is sampled uniformly by length, one sample per membrane row; at each
//!    sample the rectum's surface mesh is cut by the plane normal to the axis (the triangles
//!    near the sample only), and the cut outline is re-sampled uniformly by length into the
//!    row's nodes, starting on the axis frame's first direction: layer 1;
//! 2. the surrounding tissue's mesh is cut by the same planes and re-sampled the same way, so
//!    its nodes line up with layer 1's: layer 4;
//! 3. layers 2 and 3 are interpolated on the segment from each layer-1 node to its layer-4
//!    node: layer 2 a fixed depth out from layer 1 (the mesorectal fat under the visceral
//!    fascia), layer 3 a fixed depth in from layer 4; what remains between them is the short,
//!    variable gap of the dissection plane.
//!
//! The surface meshes come from [`crate::mesh::tube`] here; a user's meshes go through the
//! same cutting (any closed tube whose cross-sections are star-shaped about the axis).
//!
//! Sizes (documented in `assets/scenarios/rectum.toml`): the rectum is 12-15 cm long and its
//! diameter 3-4 cm empty (up to 6 cm at the distended ampulla), following the sacral curve;
//! the section modelled is 15 cm of a 2 cm radius tube, as in the paper's 600 x 400 grid
//! (0.25 mm between rows, 0.31 mm between columns on layer 1).

use crate::mesh::{TriMesh, TubeSpec, tube};
use crate::models::membrane::{LAYERS, MembraneShape};
use glam::Vec3;
use rayon::prelude::*;
use std::f32::consts::PI;

/// The anatomy's figures (the scenario's `[anatomy]` table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnatomyParams {
    /// Length of the rectum's section along its medial axis, m.
    pub length_m: f32,
    /// Radius of the rectum's outer surface (layer 1), m.
    pub rectum_radius_m: f32,
    /// Radius of curvature of the medial axis (the sacral curve), m.
    pub sacral_radius_m: f32,
    /// Radius of the surrounding tissue's inner surface (layer 4), m.
    pub pelvis_radius_m: f32,
    /// How far the surrounding tube's axis lies behind the rectum's (towards the sacrum), so
    /// the tissue between them is thicker behind, m.
    pub pelvis_offset_m: f32,
    /// Depth of layer 2 out from layer 1 (the link 1-2, fixed), m.
    pub fat_depth_m: f32,
    /// Depth of layer 3 in from layer 4 (the link 3-4, fixed), m.
    pub wall_depth_m: f32,
    /// Membrane rows (cross-sections along the axis).
    pub rows: u32,
    /// Membrane columns (nodes around each cross-section).
    pub cols: u32,
    /// Rings and segments of the generated surface meshes.
    pub mesh_rings: u32,
    pub mesh_segments: u32,
}

impl Default for AnatomyParams {
    fn default() -> Self {
        AnatomyParams {
            length_m: 0.15,
            rectum_radius_m: 0.02,
            sacral_radius_m: 0.12,
            pelvis_radius_m: 0.034,
            pelvis_offset_m: 0.0008,
            fat_depth_m: 0.010,
            wall_depth_m: 0.0025,
            rows: 600,
            cols: 400,
            mesh_rings: 151,
            mesh_segments: 96,
        }
    }
}

/// Why the anatomy could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnatomyError {
    #[error(
        "the {surface} surface has no outline at row {row} (the plane normal to the medial \
         axis there meets none of its triangles near the axis)"
    )]
    NoOutline { surface: &'static str, row: usize },
    #[error(
        "row {row}, column {col}: layers 2 and 3 would cross (the tissue between the rectum \
         and the pelvis is {gap_mm:.2} mm there; the fat and wall depths need more)"
    )]
    LayersCross { row: usize, col: usize, gap_mm: f32 },
    #[error("the medial axis needs at least 2 points")]
    ShortAxis,
}

/// A frame along the medial axis: the point, its unit tangent and two unit normals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisFrame {
    pub point: Vec3,
    pub tangent: Vec3,
    /// Column 0 of every row lies in this direction from the axis (anterior).
    pub normal: Vec3,
    pub binormal: Vec3,
}

/// The generated anatomy.
#[derive(Debug, Clone)]
pub struct Anatomy {
    pub params: AnatomyParams,
    /// The medial axis, one frame per membrane row.
    pub axis: Vec<AxisFrame>,
    /// The rectum's surface mesh.
    pub rectum: TriMesh,
    /// The surrounding tissue's inner surface mesh.
    pub pelvis: TriMesh,
    /// The membrane's nodes at rest.
    pub membrane: MembraneShape,
}

/// The medial axis: an arc of radius `sacral_radius_m` in the x-y plane, from the origin
/// along +x, bending towards -y (posterior, the sacrum's side; anterior is +y).
pub fn medial_axis(p: &AnatomyParams, samples: usize) -> Vec<Vec3> {
    let n = samples.max(2);
    let r = p.sacral_radius_m;
    let sweep = p.length_m / r;
    (0..n)
        .map(|k| {
            let a = sweep * k as f32 / (n - 1) as f32;
            Vec3::new(r * a.sin(), -(r * (1.0 - a.cos())), 0.0)
        })
        .collect()
}

/// Frames along a polyline, `n` of them evenly spaced by length, carried by parallel
/// transport (no twist) from a first normal of +y (anterior) made perpendicular.
pub fn frames(path: &[Vec3], n: usize) -> Result<Vec<AxisFrame>, AnatomyError> {
    if path.len() < 2 {
        return Err(AnatomyError::ShortAxis);
    }
    let points = resample(path, n.max(2));
    let tangent_at = |i: usize| {
        let (a, b) = if i + 1 < points.len() {
            (points[i], points[i + 1])
        } else {
            (points[i - 1], points[i])
        };
        (b - a).normalize_or_zero()
    };
    let mut normal = Vec3::Y;
    let mut out = Vec::with_capacity(points.len());
    for (i, &point) in points.iter().enumerate() {
        let tangent = tangent_at(i);
        let mut nn = normal - tangent * normal.dot(tangent);
        if nn.length_squared() < 1e-12 {
            nn = tangent.any_orthonormal_vector();
        }
        normal = nn.normalize();
        out.push(AxisFrame {
            point,
            tangent,
            normal,
            binormal: tangent.cross(normal),
        });
    }
    Ok(out)
}

/// `n` points evenly spaced by arc length along a polyline.
fn resample(path: &[Vec3], n: usize) -> Vec<Vec3> {
    let mut cum = vec![0.0f32];
    for w in path.windows(2) {
        cum.push(cum[cum.len() - 1] + (w[1] - w[0]).length());
    }
    let total = cum[cum.len() - 1];
    (0..n)
        .map(|i| {
            let s = total * i as f32 / (n - 1) as f32;
            let k = cum.partition_point(|&c| c <= s).clamp(1, path.len() - 1) - 1;
            let len = (cum[k + 1] - cum[k]).max(f32::EPSILON);
            path[k].lerp(path[k + 1], ((s - cum[k]) / len).clamp(0.0, 1.0))
        })
        .collect()
}

/// Step 1 of the paper for one surface: at each frame, the outline where the plane normal to
/// the axis cuts the triangles of `mesh` within `reach` of the axis point, re-sampled
/// uniformly by length into `cols` points, the first on the frame's normal direction.
pub fn cross_sections(
    mesh: &TriMesh,
    axis: &[AxisFrame],
    cols: usize,
    reach: f32,
    surface: &'static str,
) -> Result<Vec<Vec<Vec3>>, AnatomyError> {
    let centroid: Vec<Vec3> = mesh
        .triangles
        .iter()
        .map(|t| t.iter().map(|&v| mesh.positions[v as usize]).sum::<Vec3>() / 3.0)
        .collect();
    axis.par_iter()
        .enumerate()
        .map(|(row, f)| {
            let outline = outline(mesh, &centroid, f, reach);
            if outline.len() < 3 {
                return Err(AnatomyError::NoOutline { surface, row });
            }
            Ok(resample_closed(&outline, f, cols))
        })
        .collect()
}

/// The cut outline at a frame as (angle about the axis from the normal, point), sorted by
/// angle; points where the plane passes through a vertex or along an edge appear once.
fn outline(mesh: &TriMesh, centroid: &[Vec3], f: &AxisFrame, reach: f32) -> Vec<(f32, Vec3)> {
    let mut pts: Vec<(f32, Vec3)> = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if centroid[t].distance_squared(f.point) > reach * reach {
            continue;
        }
        let v = tri.map(|i| mesh.positions[i as usize]);
        let d = v.map(|p| (p - f.point).dot(f.tangent));
        for e in 0..3 {
            let (a, b) = (e, (e + 1) % 3);
            // Half-open rule: an edge counts its first end when it lies on the plane, so a
            // vertex on the plane is found once per edge leaving it (deduplicated below).
            let crosses = (d[a] <= 0.0) != (d[b] <= 0.0);
            if !crosses {
                continue;
            }
            let s = d[a] / (d[a] - d[b]);
            let q = v[a].lerp(v[b], s);
            let r = q - f.point;
            let angle = r
                .dot(f.binormal)
                .atan2(r.dot(f.normal))
                .rem_euclid(2.0 * PI);
            pts.push((angle, q));
        }
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-6 && a.1.distance_squared(b.1) < 1e-14);
    pts
}

/// `cols` points evenly spaced by length around a closed outline sorted by angle, the first
/// where the outline crosses angle 0.
fn resample_closed(outline: &[(f32, Vec3)], f: &AxisFrame, cols: usize) -> Vec<Vec3> {
    // The point at angle 0, between the last and the first by angle.
    let (last, first) = (outline[outline.len() - 1], outline[0]);
    let span = first.0 + 2.0 * PI - last.0;
    let s = if span > 0.0 {
        (2.0 * PI - last.0) / span
    } else {
        0.0
    };
    let start = last.1.lerp(first.1, s);
    // The closed loop from `start` through every point back to `start`.
    let mut ring = Vec::with_capacity(outline.len() + 2);
    ring.push(start);
    ring.extend(outline.iter().map(|p| p.1));
    ring.push(start);
    let mut cum = vec![0.0f32];
    for w in ring.windows(2) {
        cum.push(cum[cum.len() - 1] + (w[1] - w[0]).length());
    }
    let total = cum[cum.len() - 1];
    let mut k = 0;
    (0..cols)
        .map(|c| {
            let s = total * c as f32 / cols as f32;
            while k + 2 < cum.len() && cum[k + 1] <= s {
                k += 1;
            }
            let len = (cum[k + 1] - cum[k]).max(f32::EPSILON);
            let p = ring[k].lerp(ring[k + 1], ((s - cum[k]) / len).clamp(0.0, 1.0));
            // Keep the point in the row's plane (the outline's points are, up to rounding).
            p - f.tangent * (p - f.point).dot(f.tangent)
        })
        .collect()
}

impl Anatomy {
    /// Generates the anatomy: the two surface meshes, then the membrane from them.
    pub fn generate(params: AnatomyParams) -> Result<Anatomy, AnatomyError> {
        let p = params;
        let fine_axis = medial_axis(&p, 1024);
        let rectum = tube(&TubeSpec {
            path: fine_axis.clone(),
            radius_m: p.rectum_radius_m,
            segments: p.mesh_segments,
            rings: p.mesh_rings,
        });
        // The surrounding tube: the same curve moved back (towards -y), a little longer so
        // its ends do not cut the first and last rows' planes.
        let back = Vec3::new(0.0, -p.pelvis_offset_m, 0.0);
        let mut pelvis_axis: Vec<Vec3> = fine_axis.iter().map(|&q| q + back).collect();
        extend_ends(&mut pelvis_axis, p.pelvis_radius_m);
        let pelvis = tube(&TubeSpec {
            path: pelvis_axis,
            radius_m: p.pelvis_radius_m,
            segments: p.mesh_segments,
            rings: p.mesh_rings,
        });
        Self::from_meshes(p, &fine_axis, rectum, pelvis)
    }

    /// Builds the membrane from the two surfaces and the rectum's medial axis (the paper's
    /// steps 1-3), for generated meshes or a user's.
    pub fn from_meshes(
        params: AnatomyParams,
        medial_axis: &[Vec3],
        rectum: TriMesh,
        pelvis: TriMesh,
    ) -> Result<Anatomy, AnatomyError> {
        let p = params;
        let (rows, cols) = (p.rows as usize, p.cols as usize);
        // One plane per row, each in the middle of its row's share of the axis: the first
        // and last half a row in from the ends, off the end caps.
        let total: f32 = medial_axis.windows(2).map(|w| (w[1] - w[0]).length()).sum();
        let step = total / rows as f32;
        let axis = frames(&trim(medial_axis, 0.5 * step), rows)?;
        let reach_rectum = 2.0 * p.rectum_radius_m + step;
        let reach_pelvis = 2.0 * (p.pelvis_radius_m + p.pelvis_offset_m) + step;
        let l1 = cross_sections(&rectum, &axis, cols, reach_rectum, "rectum")?;
        let l4 = cross_sections(&pelvis, &axis, cols, reach_pelvis, "pelvis")?;
        let mut positions: [Vec<Vec3>; LAYERS] =
            std::array::from_fn(|_| Vec::with_capacity(rows * cols));
        for i in 0..rows {
            for j in 0..cols {
                let (a, d) = (l1[i][j], l4[i][j]);
                let gap = (d - a).length();
                let u = (d - a) / gap.max(f32::EPSILON);
                if gap <= p.fat_depth_m + p.wall_depth_m {
                    return Err(AnatomyError::LayersCross {
                        row: i,
                        col: j,
                        gap_mm: gap * 1e3,
                    });
                }
                positions[0].push(a);
                positions[1].push(a + u * p.fat_depth_m);
                positions[2].push(d - u * p.wall_depth_m);
                positions[3].push(d);
            }
        }
        Ok(Anatomy {
            params: p,
            axis,
            rectum,
            pelvis,
            membrane: MembraneShape {
                rows,
                cols,
                periodic: true,
                positions,
            },
        })
    }

    /// The dissection plane's gap (between layers 2 and 3) at row `i`, column `j`, m.
    pub fn plane_gap(&self, i: usize, j: usize) -> f32 {
        let k = i * self.membrane.cols + j;
        self.membrane.positions[1][k].distance(self.membrane.positions[2][k])
    }
}

/// The polyline with `by` cut off each end (by arc length).
fn trim(path: &[Vec3], by: f32) -> Vec<Vec3> {
    let total: f32 = path.windows(2).map(|w| (w[1] - w[0]).length()).sum();
    if total <= 2.0 * by {
        return Vec::new();
    }
    let n = path.len().max(2) * 2;
    let even = resample(path, n);
    let step = total / (n - 1) as f32;
    // Points strictly inside, then the exact ends.
    let start = along(&even, by);
    let end = along(&even, total - by);
    let mut out = vec![start];
    out.extend(
        even.iter()
            .enumerate()
            .filter(|(k, _)| {
                let s = *k as f32 * step;
                s > by && s < total - by
            })
            .map(|(_, &q)| q),
    );
    out.push(end);
    out
}

/// The point `s` along a polyline.
fn along(path: &[Vec3], s: f32) -> Vec3 {
    let mut run = 0.0;
    for w in path.windows(2) {
        let len = (w[1] - w[0]).length();
        if run + len >= s {
            return w[0].lerp(w[1], ((s - run) / len.max(f32::EPSILON)).clamp(0.0, 1.0));
        }
        run += len;
    }
    path[path.len() - 1]
}

/// Extends a polyline straight on at both ends by `by`.
fn extend_ends(path: &mut Vec<Vec3>, by: f32) {
    if path.len() < 2 {
        return;
    }
    let n = path.len();
    let head = (path[0] - path[1]).normalize_or_zero() * by;
    let tail = (path[n - 1] - path[n - 2]).normalize_or_zero() * by;
    let first = path[0] + head;
    path.insert(0, first);
    let last = path[path.len() - 1] + tail;
    path.push(last);
}
