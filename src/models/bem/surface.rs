//! Closed triangulated surfaces for the boundary-element models, and their flat elements.
//!
//! [`Sector`] generates the boundary of a thick-walled tube, or of a sector of one, in
//! cylindrical coordinates `(r, theta, z)`: the inner and outer walls, the two end annuli and,
//! for a sector, its two radial faces. Vertices are shared between faces, so the surface is
//! watertight (every edge belongs to exactly two triangles), and every triangle is wound so
//! that its normal points out of the solid.

use glam::DVec3;
use std::collections::HashMap;

/// Which part of a [`Sector`]'s boundary a triangle lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Face {
    /// The lumen's wall, `r = inner`.
    Inner,
    /// The outer wall, `r = outer`.
    Outer,
    /// The end at `z = 0` (0) or `z = length` (1).
    End(u8),
    /// The radial face at `theta = 0` (0) or `theta = span` (1) of a sector.
    Side(u8),
}

/// A closed surface: vertices, m, and triangles wound outwards, with the face each lies on.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    pub vertices: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    pub faces: Vec<Face>,
}

/// A flat triangular element: its corners, centroid (the collocation point), unit outward
/// normal, area and longest edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Element {
    pub corners: [DVec3; 3],
    pub centroid: DVec3,
    pub normal: DVec3,
    pub area_m2: f64,
    pub size_m: f64,
}

impl Element {
    pub fn new(corners: [DVec3; 3]) -> Element {
        let [a, b, c] = corners;
        let cross = (b - a).cross(c - a);
        let twice = cross.length();
        let size = (b - a).length().max((c - b).length()).max((a - c).length());
        Element {
            corners,
            centroid: (a + b + c) / 3.0,
            normal: if twice > 0.0 { cross / twice } else { DVec3::Z },
            area_m2: 0.5 * twice,
            size_m: size,
        }
    }
}

impl Surface {
    /// Its triangles as elements.
    pub fn elements(&self) -> Vec<Element> {
        self.triangles
            .iter()
            .map(|t| Element::new(t.map(|i| self.vertices[i as usize])))
            .collect()
    }

    /// The number of triangles each undirected edge belongs to, and whether every directed
    /// edge appears once (consistent winding): a closed, consistently wound surface has
    /// every edge in exactly two triangles, once each way.
    pub fn is_watertight(&self) -> bool {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        directed
            .iter()
            .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
    }

    /// The enclosed volume, m^3 (divergence theorem; positive when wound outwards).
    pub fn volume_m3(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }
}

/// A thick-walled tube, or a sector of one, along `z` from 0 to `length_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sector {
    pub inner_m: f64,
    pub outer_m: f64,
    pub length_m: f64,
    /// The angle it spans, radians: `2 pi` (or more) for a whole tube.
    pub span_rad: f64,
    /// Divisions around, through the wall and along.
    pub around: usize,
    pub through: usize,
    pub along: usize,
}

impl Sector {
    fn whole(&self) -> bool {
        self.span_rad >= std::f64::consts::TAU - 1e-12
    }

    /// Its boundary, triangulated.
    pub fn surface(&self) -> Surface {
        let (na, nr, nz) = (self.around.max(3), self.through.max(1), self.along.max(1));
        let whole = self.whole();
        let span = if whole {
            std::f64::consts::TAU
        } else {
            self.span_rad
        };
        let mut index: HashMap<(usize, usize, usize), u32> = HashMap::new();
        let mut vertices = Vec::new();
        let mut vertex = |a: usize, r: usize, z: usize| -> u32 {
            let a = if whole { a % na } else { a };
            *index.entry((a, r, z)).or_insert_with(|| {
                let theta = span * a as f64 / na as f64;
                let radius = self.inner_m + (self.outer_m - self.inner_m) * r as f64 / nr as f64;
                let height = self.length_m * z as f64 / nz as f64;
                vertices.push(DVec3::new(
                    radius * theta.cos(),
                    radius * theta.sin(),
                    height,
                ));
                (vertices.len() - 1) as u32
            })
        };
        let mut quads: Vec<([u32; 4], Face, DVec3)> = Vec::new();
        // Walls: (around, along) grids at r = 0 and r = nr.
        for (r, face) in [(0, Face::Inner), (nr, Face::Outer)] {
            for a in 0..na {
                for z in 0..nz {
                    let q = [
                        vertex(a, r, z),
                        vertex(a + 1, r, z),
                        vertex(a + 1, r, z + 1),
                        vertex(a, r, z + 1),
                    ];
                    let mid = span * (a as f64 + 0.5) / na as f64;
                    let radial = DVec3::new(mid.cos(), mid.sin(), 0.0);
                    let out = if face == Face::Inner { -radial } else { radial };
                    quads.push((q, face, out));
                }
            }
        }
        // Ends: (around, through) grids at z = 0 and z = nz.
        for (z, end) in [(0, 0u8), (nz, 1u8)] {
            for a in 0..na {
                for r in 0..nr {
                    let q = [
                        vertex(a, r, z),
                        vertex(a + 1, r, z),
                        vertex(a + 1, r + 1, z),
                        vertex(a, r + 1, z),
                    ];
                    let out = if end == 0 { -DVec3::Z } else { DVec3::Z };
                    quads.push((q, Face::End(end), out));
                }
            }
        }
        // A sector's radial faces: (through, along) grids at a = 0 and a = na.
        if !whole {
            for (a, side) in [(0, 0u8), (na, 1u8)] {
                let theta = span * a as f64 / na as f64;
                let tangent = DVec3::new(-theta.sin(), theta.cos(), 0.0);
                let out = if side == 0 { -tangent } else { tangent };
                for r in 0..nr {
                    for z in 0..nz {
                        let q = [
                            vertex(a, r, z),
                            vertex(a, r + 1, z),
                            vertex(a, r + 1, z + 1),
                            vertex(a, r, z + 1),
                        ];
                        quads.push((q, Face::Side(side), out));
                    }
                }
            }
        }
        let mut triangles = Vec::with_capacity(2 * quads.len());
        let mut faces = Vec::with_capacity(2 * quads.len());
        for (q, face, out) in quads {
            for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                let wound = if (b - a).cross(c - a).dot(out) >= 0.0 {
                    t
                } else {
                    [t[0], t[2], t[1]]
                };
                triangles.push(wound);
                faces.push(face);
            }
        }
        Surface {
            vertices,
            triangles,
            faces,
        }
    }
}
