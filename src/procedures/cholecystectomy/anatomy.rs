//! The cholecystectomy's anatomy, generated deterministically (the paper's Fig. 4: the liver
//! with its inferior border, the gallbladder in its bed under it, the cystic duct from the
//! gallbladder's neck to the common hepatic duct, which runs down from the liver's hilum and
//! continues as the common bile duct, the cystic artery from the hepatic artery to the neck,
//! the fat over Calot's triangle, and the fascia between gallbladder and liver).
//!
//! Frame and units: metres; +y up (towards the diaphragm), +x from the neck towards the
//! gallbladder's fundus, +z towards the abdominal wall (the laparoscope looks from +z).
//!
//! - Organs (liver, gallbladder, fat) are particles on a cubic lattice inside an ellipsoid,
//!   each standing for its cube of tissue: mass = density x spacing^3, so a body's mass is
//!   its density times its volume whatever the spacing. A particle is on the surface where a
//!   lattice neighbour lies outside.
//! - Ducts and the artery are chains of particles two radii apart along their centrelines;
//!   their far ends are pinned (they run on out of the field).
//! - The fat is kept clear of the ducts and the artery (they run through it).
//! - The fascia is a sheet of cloth over the junction of gallbladder and liver on the side
//!   the laparoscope sees, its edges tied to the nearest particles of each organ.
//! - Adhesion pairs bind the gallbladder's upper surface to the liver's surface above it, one
//!   every few surface particles (the strands of the paper's adhesive fascia).
//! - Calot's triangle: the cystic duct, the common hepatic duct and the inferior border of the
//!   liver, as the triangle (neck, junction, hilum).
//!
//! Sizes (documented in `assets/scenarios/cholecystectomy.toml`): a liver some 18 x 7 x 13 cm
//! (the right lobe's reach under the costal margin), a gallbladder 8 cm long and 3 cm across,
//! a cystic duct 3 mm across and 3 cm long, the common hepatic duct 5 mm, the common bile duct
//! 6 mm, the cystic artery 2 mm.

use crate::models::particles::Particles;
use glam::Vec3;

/// Body ids in [`Particles::body`].
pub mod body {
    pub const LIVER: u16 = 0;
    pub const GALLBLADDER: u16 = 1;
    pub const FAT: u16 = 2;
    pub const CYSTIC_DUCT: u16 = 3;
    pub const COMMON_HEPATIC_DUCT: u16 = 4;
    pub const COMMON_BILE_DUCT: u16 = 5;
    pub const CYSTIC_ARTERY: u16 = 6;
    pub const FASCIA: u16 = 7;
    /// The adhesion strands' interior particles.
    pub const ADHESION: u16 = 8;
    pub const NAMES: [&str; 9] = [
        "liver",
        "gallbladder",
        "fat",
        "cystic_duct",
        "common_hepatic_duct",
        "common_bile_duct",
        "cystic_artery",
        "fascia",
        "adhesion",
    ];
}

/// An ellipsoidal organ: centre and semi-axes, m; lattice spacing, m; density, kg/m^3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrganShape {
    pub centre_m: Vec3,
    pub semi_axes_m: Vec3,
    pub spacing_m: f32,
    pub density_kg_per_m3: f32,
}

impl OrganShape {
    fn inside(&self, p: Vec3) -> bool {
        ((p - self.centre_m) / self.semi_axes_m).length_squared() <= 1.0
    }
}

/// A vessel's centreline (straight segments through `points`, m) and radius, m.
#[derive(Debug, Clone, PartialEq)]
pub struct VesselShape {
    pub points: Vec<Vec3>,
    pub radius_m: f32,
    /// Density of the vessel's tissue and contents, kg/m^3.
    pub density_kg_per_m3: f32,
}

/// The anatomy's figures (the scenario's `[anatomy]` table).
#[derive(Debug, Clone, PartialEq)]
pub struct AnatomyParams {
    pub liver: OrganShape,
    /// Liver particles above this height (it hangs from the diaphragm) or behind this depth
    /// (its bare area, on the posterior wall) are pinned, m.
    pub liver_pinned_above_m: f32,
    pub liver_pinned_behind_m: f32,
    pub gallbladder: OrganShape,
    pub fat: OrganShape,
    pub cystic_duct: VesselShape,
    pub common_hepatic_duct: VesselShape,
    pub common_bile_duct: VesselShape,
    pub cystic_artery: VesselShape,
    /// The fascia's nodes along the gallbladder and across to the liver.
    pub fascia_nodes: [u32; 2],
    /// Its thickness (m) and density (kg/m^3): its nodes' masses.
    pub fascia_thickness_m: f32,
    pub fascia_density_kg_per_m3: f32,
    /// Every how many of the gallbladder's upper surface particles an adhesion strand starts.
    pub adhesion_every: u32,
    /// Every how many of the fat's surface particles a strand binds it to the nearest other
    /// organ or vessel particle within `fat_bond_reach_m`.
    pub fat_bond_every: u32,
    pub fat_bond_reach_m: f32,
    /// Closed surfaces (a user's OBJ or glTF, metres, in this frame) that replace the
    /// liver's, the gallbladder's and the fat's ellipsoids: the lattice fills what they
    /// enclose, and the organ's centre and semi-axes become its box's.
    pub surfaces: [Option<crate::mesh::TriMesh>; 3],
}

impl Default for AnatomyParams {
    fn default() -> Self {
        let neck = Vec3::new(-0.043, -0.001, 0.0);
        let junction = Vec3::new(-0.066, -0.026, 0.0);
        let hilum = Vec3::new(-0.066, 0.021, 0.0);
        AnatomyParams {
            liver: OrganShape {
                centre_m: Vec3::new(0.0, 0.05, 0.0),
                semi_axes_m: Vec3::new(0.09, 0.035, 0.065),
                spacing_m: 0.0035,
                density_kg_per_m3: 1060.0,
            },
            liver_pinned_above_m: 0.072,
            liver_pinned_behind_m: -0.045,
            gallbladder: OrganShape {
                centre_m: Vec3::new(0.0, -0.001, 0.0),
                semi_axes_m: Vec3::new(0.04, 0.014, 0.016),
                spacing_m: 0.0025,
                density_kg_per_m3: 1030.0,
            },
            fat: OrganShape {
                centre_m: Vec3::new(-0.057, -0.002, 0.002),
                semi_axes_m: Vec3::new(0.014, 0.016, 0.009),
                spacing_m: 0.0025,
                density_kg_per_m3: 920.0,
            },
            cystic_duct: VesselShape {
                points: vec![neck, Vec3::new(-0.055, -0.012, 0.003), junction],
                radius_m: 0.0015,
                density_kg_per_m3: 1040.0,
            },
            common_hepatic_duct: VesselShape {
                points: vec![hilum, junction],
                radius_m: 0.0025,
                density_kg_per_m3: 1040.0,
            },
            common_bile_duct: VesselShape {
                points: vec![junction, Vec3::new(-0.064, -0.075, -0.004)],
                radius_m: 0.003,
                density_kg_per_m3: 1040.0,
            },
            cystic_artery: VesselShape {
                points: vec![
                    Vec3::new(-0.062, 0.017, 0.007),
                    Vec3::new(-0.037, 0.007, 0.007),
                ],
                radius_m: 0.001,
                density_kg_per_m3: 1060.0,
            },
            fascia_nodes: [24, 5],
            fascia_thickness_m: 0.0005,
            fascia_density_kg_per_m3: 1000.0,
            adhesion_every: 2,
            fat_bond_every: 1,
            fat_bond_reach_m: 0.008,
            surfaces: [None, None, None],
        }
    }
}

/// An organ's particles: `range` in [`Anatomy::particles`], those on its surface, and the
/// lattice spacing, m.
#[derive(Debug, Clone, PartialEq)]
pub struct Organ {
    pub body: u16,
    pub range: std::ops::Range<u32>,
    pub surface: Vec<u32>,
    pub spacing_m: f32,
}

/// A vessel's chain of particles, from its first centreline point to its last, and radius.
#[derive(Debug, Clone, PartialEq)]
pub struct Vessel {
    pub body: u16,
    pub chain: Vec<u32>,
    pub radius_m: f32,
}

/// Why the anatomy could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnatomyError {
    #[error("anatomy.{field}: {message}")]
    Bad {
        field: &'static str,
        message: String,
    },
}

/// The generated anatomy.
#[derive(Debug, Clone)]
pub struct Anatomy {
    pub particles: Particles,
    /// Liver, gallbladder, fat.
    pub organs: Vec<Organ>,
    /// Cystic duct, common hepatic duct, common bile duct, cystic artery.
    pub vessels: Vec<Vessel>,
    /// The fascia's nodes (row-major, along then across) and its triangles.
    pub fascia: Vec<u32>,
    pub fascia_triangles: Vec<[u32; 3]>,
    /// The fascia's thickness, m (its edges' stiffness is its modulus times this).
    pub fascia_thickness_m: f32,
    /// Permanent stiff ties (rest length their present distance): vessel ends into their
    /// organs, the fascia's edges to the organs.
    pub ties: Vec<(u32, u32)>,
    /// Adhesion pairs: a gallbladder particle and a liver particle.
    pub adhesion_pairs: Vec<(u32, u32)>,
    /// The fat's loose connective tissue: a fat surface particle and the nearest particle of
    /// another organ or a vessel.
    pub fat_pairs: Vec<(u32, u32)>,
    /// Calot's triangle: the cystic duct's start at the neck, the junction with the common
    /// hepatic duct, the hilum (the inferior border of the liver), m.
    pub calot: [Vec3; 3],
}

impl Anatomy {
    pub fn generate(a: &AnatomyParams) -> Result<Anatomy, AnatomyError> {
        check(a)?;
        // Organs given as surfaces: their boxes stand for their ellipsoids in the figures
        // the generator derives (where the adhesions start, how far the fat keeps off).
        let mut boxed = a.clone();
        let mut solids: [Option<crate::mesh::Solid>; 3] = [None, None, None];
        for (k, (field, shape)) in [
            ("liver", &mut boxed.liver),
            ("gallbladder", &mut boxed.gallbladder),
            ("fat", &mut boxed.fat),
        ]
        .into_iter()
        .enumerate()
        {
            let Some(mesh) = &a.surfaces[k] else {
                continue;
            };
            let solid = crate::mesh::Solid::new(mesh.clone()).ok_or(AnatomyError::Bad {
                field,
                message: "the surface has no triangles or a point that is not finite".to_string(),
            })?;
            let (lo, hi) = solid.bounds();
            shape.centre_m = 0.5 * (lo + hi);
            shape.semi_axes_m = 0.5 * (hi - lo);
            if shape.spacing_m >= shape.semi_axes_m.min_element() {
                return Err(AnatomyError::Bad {
                    field,
                    message: format!(
                        "the surface is thinner than two lattice spacings ({} m) somewhere \
                         along an axis",
                        2.0 * shape.spacing_m
                    ),
                });
            }
            solids[k] = Some(solid);
        }
        let a = &boxed;
        let inside = [&a.liver, &a.gallbladder, &a.fat].map(|shape| Inside {
            shape,
            solid: None,
            rows: Default::default(),
        });
        let [liver_in, gallbladder_in, fat_in] = {
            let mut ins = inside;
            for (k, s) in solids.iter().enumerate() {
                ins[k].solid = s.as_ref();
            }
            ins
        };
        let mut p = Particles::new();
        let vessels_shapes = [
            (body::CYSTIC_DUCT, &a.cystic_duct),
            (body::COMMON_HEPATIC_DUCT, &a.common_hepatic_duct),
            (body::COMMON_BILE_DUCT, &a.common_bile_duct),
            (body::CYSTIC_ARTERY, &a.cystic_artery),
        ];
        // The fat keeps clear of every vessel by its own half spacing.
        let clear_of_vessels = |x: Vec3| {
            vessels_shapes.iter().all(|(_, v)| {
                distance_to_polyline(x, &v.points) > v.radius_m + 0.5 * a.fat.spacing_m
            })
        };
        let organs = vec![
            fill(&mut p, body::LIVER, &a.liver, |x| liver_in.contains(x)),
            fill(&mut p, body::GALLBLADDER, &a.gallbladder, |x| {
                gallbladder_in.contains(x)
            }),
            fill(&mut p, body::FAT, &a.fat, |x| {
                fat_in.contains(x)
                    && clear_of_vessels(x)
                    && !liver_in.contains(x + Vec3::Y * a.fat.spacing_m)
                    && !gallbladder_in.contains(x)
            }),
        ];
        for i in organs[0].range.clone() {
            let x = p.x[i as usize];
            if x.y > a.liver_pinned_above_m || x.z < a.liver_pinned_behind_m {
                p.pin(i as usize);
            }
        }
        // The junction's particle is the common hepatic duct's last: the cystic duct stops
        // short of it and the common bile duct starts after it.
        let mut vessels = Vec::new();
        for (b, v) in vessels_shapes {
            let skip = match b {
                body::CYSTIC_DUCT => [false, true],
                body::COMMON_BILE_DUCT => [true, false],
                _ => [false, false],
            };
            vessels.push(chain(&mut p, b, v, skip));
        }
        let mut ties = Vec::new();
        // The cystic duct starts at the gallbladder's neck; the artery ends on it; the common
        // hepatic duct comes out of the liver; the far ends run on out of the field.
        let nearest_in = |p: &Particles, o: &Organ, x: Vec3| {
            nearest_of(p, o.surface.iter().copied(), x).unwrap_or(o.range.start)
        };
        let (gb, liver) = (&organs[1], &organs[0]);
        let cd = &vessels[0];
        let first = |v: &Vessel| v.chain.first().copied().unwrap_or(0);
        let last = |v: &Vessel| v.chain.last().copied().unwrap_or(0);
        ties.push((first(cd), nearest_in(&p, gb, p.x[first(cd) as usize])));
        let art = &vessels[3];
        ties.push((last(art), nearest_in(&p, gb, p.x[last(art) as usize])));
        p.pin(first(art) as usize);
        p.pin(first(&vessels[1]) as usize);
        p.pin(last(&vessels[2]) as usize);
        // The cystic duct and the common bile duct meet the common hepatic duct at the
        // junction: their end particles tied to its last.
        ties.push((last(cd), last(&vessels[1])));
        ties.push((first(&vessels[2]), last(&vessels[1])));
        let (fascia, fascia_triangles, fascia_ties) = fascia_sheet(&mut p, a, gb, liver);
        ties.extend(fascia_ties);
        let adhesion_pairs = adhesions(&p, a, gb, liver);
        let fat_pairs = fat_bonds(&p, a, &organs, &vessels);
        let calot = [
            a.cystic_duct.points[0],
            *a.cystic_duct.points.last().unwrap_or(&Vec3::ZERO),
            a.common_hepatic_duct.points[0],
        ];
        Ok(Anatomy {
            particles: p,
            organs,
            vessels,
            fascia,
            fascia_triangles,
            fascia_thickness_m: a.fascia_thickness_m,
            ties,
            adhesion_pairs,
            fat_pairs,
            calot,
        })
    }

    /// Particles in shape-matching bodies (liver, gallbladder, fat).
    pub fn organ_particles(&self) -> usize {
        self.organs.iter().map(|o| o.range.len()).sum()
    }
}

fn check(a: &AnatomyParams) -> Result<(), AnatomyError> {
    let bad = |field: &'static str, message: &str| {
        Err(AnatomyError::Bad {
            field,
            message: message.to_string(),
        })
    };
    for (field, o) in [
        ("liver", &a.liver),
        ("gallbladder", &a.gallbladder),
        ("fat", &a.fat),
    ] {
        if !(o.semi_axes_m.min_element() > 0.0 && o.semi_axes_m.is_finite()) {
            return bad(field, "semi-axes must be positive lengths in metres");
        }
        if !(o.spacing_m > 0.0 && o.spacing_m < o.semi_axes_m.min_element()) {
            return bad(
                field,
                "spacing must be positive and below the smallest semi-axis",
            );
        }
        if !(o.density_kg_per_m3 > 0.0 && o.density_kg_per_m3.is_finite()) {
            return bad(field, "density must be a positive number of kg/m^3");
        }
        if !o.centre_m.is_finite() {
            return bad(field, "centre must be finite");
        }
    }
    for (field, v) in [
        ("cystic_duct", &a.cystic_duct),
        ("common_hepatic_duct", &a.common_hepatic_duct),
        ("common_bile_duct", &a.common_bile_duct),
        ("cystic_artery", &a.cystic_artery),
    ] {
        if v.points.len() < 2 || !v.points.iter().all(|p| p.is_finite()) {
            return bad(field, "needs at least two finite centreline points");
        }
        if !(v.radius_m > 0.0 && v.radius_m.is_finite()) {
            return bad(field, "radius must be a positive length in metres");
        }
    }
    if a.fascia_nodes.iter().any(|&n| n < 2) {
        return bad("fascia_nodes", "needs at least 2 nodes each way");
    }
    if a.adhesion_every == 0 {
        return bad("adhesion_every", "must be at least 1");
    }
    if a.fat_bond_every == 0 {
        return bad("fat_bond_every", "must be at least 1");
    }
    if !(a.fat_bond_reach_m > 0.0 && a.fat_bond_reach_m.is_finite()) {
        return bad("fat_bond_reach_m", "must be a positive length in metres");
    }
    Ok(())
}

/// An organ's inside: its ellipsoid, or the closed surface given for it (the crossings of
/// each lattice row found once).
struct Inside<'a> {
    shape: &'a OrganShape,
    solid: Option<&'a crate::mesh::Solid>,
    rows: std::cell::RefCell<std::collections::HashMap<(u32, u32), Vec<f32>>>,
}

impl Inside<'_> {
    fn contains(&self, x: Vec3) -> bool {
        let Some(solid) = self.solid else {
            return self.shape.inside(x);
        };
        let (lo, hi) = solid.bounds();
        if !(x.cmpge(lo).all() && x.cmple(hi).all()) {
            return false;
        }
        let mut rows = self.rows.borrow_mut();
        let row = rows
            .entry((x.y.to_bits(), x.z.to_bits()))
            .or_insert_with(|| solid.row(x.y, x.z));
        crate::mesh::Solid::inside_row(row, x.x)
    }
}

/// Lattice particles of `shape`'s box where `inside` holds, body `b`.
fn fill(p: &mut Particles, b: u16, shape: &OrganShape, inside: impl Fn(Vec3) -> bool) -> Organ {
    let h = shape.spacing_m;
    let n = (shape.semi_axes_m / h).floor().as_ivec3();
    let at = |i: i32, j: i32, k: i32| shape.centre_m + Vec3::new(i as f32, j as f32, k as f32) * h;
    let mass = shape.density_kg_per_m3 * h * h * h;
    let start = p.len() as u32;
    let mut surface = Vec::new();
    for i in -n.x..=n.x {
        for j in -n.y..=n.y {
            for k in -n.z..=n.z {
                let x = at(i, j, k);
                if !inside(x) {
                    continue;
                }
                let id = p.add(x, mass, b);
                let outer = [
                    (1, 0, 0),
                    (-1, 0, 0),
                    (0, 1, 0),
                    (0, -1, 0),
                    (0, 0, 1),
                    (0, 0, -1),
                ]
                .iter()
                .any(|&(di, dj, dk)| !inside(at(i + di, j + dj, k + dk)));
                if outer {
                    surface.push(id);
                }
            }
        }
    }
    Organ {
        body: b,
        range: start..p.len() as u32,
        surface,
        spacing_m: h,
    }
}

/// A chain of particles about two radii apart along the centreline from its first point to
/// its last (the last gap evened out over the chain), each a cylinder of the vessel as long
/// as the spacing. `skip` leaves out the first and/or the last (where another vessel's
/// particle stands at a junction).
fn chain(p: &mut Particles, b: u16, v: &VesselShape, skip: [bool; 2]) -> Vessel {
    let lengths: Vec<f32> = v.points.windows(2).map(|s| s[0].distance(s[1])).collect();
    let total: f32 = lengths.iter().sum();
    let gaps = ((total / (2.0 * v.radius_m)).round() as usize).max(1);
    let step = total / gaps as f32;
    let mass = v.density_kg_per_m3 * std::f32::consts::PI * v.radius_m * v.radius_m * step;
    let at = |s: f32| {
        let mut left = s;
        for (seg, &len) in v.points.windows(2).zip(&lengths) {
            if left <= len || len == 0.0 {
                return seg[0].lerp(seg[1], (left / len.max(1e-12)).min(1.0));
            }
            left -= len;
        }
        *v.points.last().unwrap_or(&Vec3::ZERO)
    };
    let from = usize::from(skip[0]);
    let to = gaps - usize::from(skip[1]);
    let ids = (from..=to)
        .map(|k| p.add(at(step * k as f32), mass, b))
        .collect();
    Vessel {
        body: b,
        chain: ids,
        radius_m: v.radius_m,
    }
}

fn distance_to_polyline(x: Vec3, pts: &[Vec3]) -> f32 {
    pts.windows(2)
        .map(|s| {
            let (a, b) = (s[0], s[1]);
            let ab = b - a;
            let t = ((x - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
            x.distance(a + ab * t)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The fascia's nodes, triangles and edge ties.
type Sheet = (Vec<u32>, Vec<[u32; 3]>, Vec<(u32, u32)>);

/// The fascia: a sheet from a line along the gallbladder's upper front (60 degrees up from
/// its equator, towards +z) to the liver's surface above it, its two long edges tied to the
/// nearest surface particle of each organ.
fn fascia_sheet(p: &mut Particles, a: &AnatomyParams, gb: &Organ, liver: &Organ) -> Sheet {
    let [along, across] = a.fascia_nodes.map(|n| n as usize);
    let g = &a.gallbladder;
    let (sin, cos) = 60f32.to_radians().sin_cos();
    let mut ids = Vec::with_capacity(along * across);
    let span = 0.8 * g.semi_axes_m.x;
    let mut rows: Vec<(Vec3, Vec3)> = Vec::with_capacity(along);
    for i in 0..along {
        let x = -span + 2.0 * span * i as f32 / (along - 1) as f32;
        let r = (1.0 - (x / g.semi_axes_m.x).powi(2)).max(0.0).sqrt();
        let on_gb = g.centre_m + Vec3::new(x, g.semi_axes_m.y * r * sin, g.semi_axes_m.z * r * cos);
        // Straight up to the liver's lower surface.
        let l = &a.liver;
        let d = (on_gb - l.centre_m) / l.semi_axes_m;
        let under = (1.0 - d.x * d.x - d.z * d.z).max(0.0).sqrt();
        let on_liver = Vec3::new(on_gb.x, l.centre_m.y - l.semi_axes_m.y * under, on_gb.z);
        rows.push((on_gb, on_liver));
    }
    // Node masses: the sheet's area per node times thickness and density.
    let width: f32 = rows.windows(2).map(|w| w[0].0.distance(w[1].0)).sum();
    let height: f32 = rows.iter().map(|r| r.0.distance(r.1)).sum::<f32>() / along as f32;
    let mass = width * height * a.fascia_thickness_m * a.fascia_density_kg_per_m3
        / (along * across) as f32;
    for (from, to) in &rows {
        for j in 0..across {
            let t = j as f32 / (across - 1) as f32;
            ids.push(p.add(from.lerp(*to, t), mass, body::FASCIA));
        }
    }
    let mut tris = Vec::new();
    for i in 0..along - 1 {
        for j in 0..across - 1 {
            let (a0, a1) = (ids[i * across + j], ids[i * across + j + 1]);
            let (b0, b1) = (ids[(i + 1) * across + j], ids[(i + 1) * across + j + 1]);
            tris.push([a0, b0, a1]);
            tris.push([a1, b0, b1]);
        }
    }
    let nearest =
        |o: &Organ, x: Vec3| nearest_of(p, o.surface.iter().copied(), x).unwrap_or(o.range.start);
    let mut ties = Vec::new();
    for i in 0..along {
        let (lo, hi) = (ids[i * across], ids[i * across + across - 1]);
        ties.push((lo, nearest(gb, p.x[lo as usize])));
        ties.push((hi, nearest(liver, p.x[hi as usize])));
    }
    (ids, tris, ties)
}

/// Every `adhesion_every`-th particle of the gallbladder's upper surface (above its centre,
/// under the liver) with the liver's surface particle nearest above it.
fn adhesions(p: &Particles, a: &AnatomyParams, gb: &Organ, liver: &Organ) -> Vec<(u32, u32)> {
    let top: Vec<u32> = gb
        .surface
        .iter()
        .copied()
        .filter(|&i| {
            p.x[i as usize].y > a.gallbladder.centre_m.y + 0.5 * a.gallbladder.semi_axes_m.y
        })
        .collect();
    let lower: Vec<u32> = liver
        .surface
        .iter()
        .copied()
        .filter(|&i| p.x[i as usize].y < a.liver.centre_m.y)
        .collect();
    top.iter()
        .step_by(a.adhesion_every as usize)
        .filter_map(|&g| {
            let x = p.x[g as usize];
            let above = lower.iter().copied().filter(|&l| p.x[l as usize].y > x.y);
            nearest_of(p, above, x).map(|l| (g, l))
        })
        .collect()
}

/// Every `fat_bond_every`-th fat surface particle with the nearest particle of the liver's or
/// gallbladder's surface or of a vessel, if within `fat_bond_reach_m`.
fn fat_bonds(
    p: &Particles,
    a: &AnatomyParams,
    organs: &[Organ],
    vessels: &[Vessel],
) -> Vec<(u32, u32)> {
    let others: Vec<u32> = organs[..2]
        .iter()
        .flat_map(|o| o.surface.iter().copied())
        .chain(vessels.iter().flat_map(|v| v.chain.iter().copied()))
        .collect();
    let reach2 = a.fat_bond_reach_m * a.fat_bond_reach_m;
    organs[2]
        .surface
        .iter()
        .step_by(a.fat_bond_every as usize)
        .filter_map(|&f| {
            let x = p.x[f as usize];
            let apart = others.iter().copied().filter(|&o| p.x[o as usize] != x);
            nearest_of(p, apart, x)
                .filter(|&o| p.x[o as usize].distance_squared(x) <= reach2)
                .map(|o| (f, o))
        })
        .collect()
}

/// The particle of `among` nearest `x` (ties to the lower index).
fn nearest_of(p: &Particles, among: impl Iterator<Item = u32>, x: Vec3) -> Option<u32> {
    among.min_by(|&i, &j| {
        p.x[i as usize]
            .distance_squared(x)
            .total_cmp(&p.x[j as usize].distance_squared(x))
            .then(i.cmp(&j))
    })
}

#[cfg(test)]
#[path = "anatomy_tests.rs"]
mod tests;
