//! What the renderer draws of the myotomy: the esophagus's divided surface (the incision's
//! polygons, Fig. 7 of the paper) where the contacts have moved it, its whole surface's
//! displacement solved from the precomputed responses at frame rate. The polygons the hook
//! passed over are drawn flat (a lower resolution of shading, so the cut stands out), and the
//! cut's own edges sink into the wall as deep as they were cut.

use super::anatomy::Esophagus;
use crate::models::bem::incision::Incision;
use crate::models::bem::palpation::Palpation;
use crate::sim::{ModelSnapshot, SurfaceRole};
use glam::{DVec3, Vec3};

/// The surface's regions: the wall, and the polygons the hook passed over.
const WALL: u8 = 0;
const PASSED: u8 = 1;

/// The drawing's fixed data and scratch.
pub struct Drawing {
    /// The elements around each original vertex.
    around: Vec<Vec<u32>>,
    /// Each element's displacement now, m (scratch).
    element_u: Vec<DVec3>,
}

impl Drawing {
    pub fn new(e: &Esophagus) -> Drawing {
        let mut around = vec![Vec::new(); e.surface.vertices.len()];
        for (t, tri) in e.surface.triangles.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t as u32);
            }
        }
        Drawing {
            around,
            element_u: Vec::new(),
        }
    }

    /// The surface now, as one model.
    pub fn models(
        &mut self,
        e: &Esophagus,
        palpation: &Palpation,
        incision: &Incision,
        cut_depth: &[f64],
    ) -> Vec<ModelSnapshot> {
        palpation
            .contacts
            .displacements(&e.problem.conditions, &mut self.element_u);
        // Original vertices move with the mean of their elements.
        let mut u: Vec<Option<DVec3>> = self
            .around
            .iter()
            .map(|els| {
                let sum: DVec3 = els
                    .iter()
                    .map(|&t| self.element_u.get(t as usize).copied().unwrap_or_default())
                    .sum();
                Some(sum / els.len().max(1) as f64)
            })
            .collect();
        u.resize(incision.vertices.len(), None);
        // A vertex the incision added moves as its original triangle does there
        // (barycentric in the original corners' displacements).
        for (t, tri) in incision.triangles.iter().enumerate() {
            let o = e.surface.triangles[incision.origin(t)];
            for &v in tri {
                if u[v as usize].is_some() {
                    continue;
                }
                let corners = o.map(|c| e.surface.vertices[c as usize]);
                let l = barycentric(corners, incision.vertices[v as usize]);
                let moved: DVec3 = (0..3)
                    .map(|k| u[o[k] as usize].unwrap_or_default() * l[k])
                    .sum();
                u[v as usize] = Some(moved);
            }
        }
        let positions: Vec<DVec3> = incision
            .vertices
            .iter()
            .enumerate()
            .map(|(v, &x)| {
                let mut p = x + u[v].unwrap_or_default();
                let d = cut_depth.get(v).copied().unwrap_or(0.0);
                if d > 0.0 {
                    // Into the wall, along the tube's radius.
                    p -= DVec3::new(x.x, x.y, 0.0).normalize_or_zero() * d;
                }
                p
            })
            .collect();
        let mut normals = vec![DVec3::ZERO; positions.len()];
        for (t, tri) in incision.triangles.iter().enumerate() {
            if incision.passed(t) {
                continue;
            }
            let [a, b, c] = tri.map(|i| positions[i as usize]);
            let n = (b - a).cross(c - a);
            for &i in tri {
                normals[i as usize] += n;
            }
        }
        let mut m = ModelSnapshot {
            seared: Vec::new(),
            name: "esophagus".to_string(),
            positions: positions.iter().map(|p| p.as_vec3()).collect(),
            normals: normals
                .iter()
                .map(|n| n.normalize_or(DVec3::Y).as_vec3())
                .collect(),
            indices: Vec::with_capacity(3 * incision.triangles.len()),
            regions: Vec::with_capacity(incision.triangles.len()),
            roles: vec![SurfaceRole::Tissue, SurfaceRole::Membrane],
            cut_edge: cut_depth
                .iter()
                .map(|&d| d > 0.0)
                .chain(std::iter::repeat(false))
                .take(positions.len())
                .collect(),
        };
        for (t, tri) in incision.triangles.iter().enumerate() {
            if incision.passed(t) {
                // Flat: its own corners with its face's normal.
                let [a, b, c] = tri.map(|i| positions[i as usize]);
                let n = (b - a).cross(c - a).normalize_or(DVec3::Y).as_vec3();
                let base = m.positions.len() as u32;
                for &i in tri {
                    m.positions.push(positions[i as usize].as_vec3());
                    m.normals.push(n);
                    m.cut_edge
                        .push(cut_depth.get(i as usize).is_some_and(|&d| d > 0.0));
                }
                m.indices.extend([base, base + 1, base + 2]);
                m.regions.push(PASSED);
            } else {
                m.indices.extend(tri);
                m.regions.push(WALL);
            }
        }
        debug_assert!(m.positions.iter().all(|p: &Vec3| p.is_finite()));
        vec![m]
    }
}

/// `p`'s barycentric coordinates in the triangle (projected onto its plane).
fn barycentric([a, b, c]: [DVec3; 3], p: DVec3) -> [f64; 3] {
    let n = (b - a).cross(c - a);
    let n2 = n.length_squared();
    if n2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    [
        (c - b).cross(p - b).dot(n) / n2,
        (a - c).cross(p - c).dot(n) / n2,
        (b - a).cross(p - a).dot(n) / n2,
    ]
}
