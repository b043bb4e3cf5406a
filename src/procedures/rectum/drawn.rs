//! What the renderer draws of the membrane: the fasciae (layers 1 and 2) with the dissection
//! showing, and the pelvic side (layer 3) with its vulnerable structures, as triangle grids
//! decimated to at most [`DRAWN_LAYER_VERTICES`] vertices a layer. The grids' triangles and
//! regions never change, so they are laid out once; a snapshot places the vertices (every
//! drawn node once, [`Membrane::place_drawn`]), marks the cut links and takes the normals.

use super::regions::{self, RegionKind};
use super::scene::RectumScene;
use crate::models::membrane::{DrawnGrid, LAYERS, Membrane};
use crate::sim::{ModelSnapshot, SurfaceRole};
use std::sync::Arc;

/// Most vertices a drawn membrane layer has (the grid is decimated to stay under it).
const DRAWN_LAYER_VERTICES: usize = 20_000;

/// The pelvic side (layer 3) is not drawn this far round either side of the front, degrees:
/// over the target's arc (40 degrees), short of the ureters (45-75).
const PELVIS_OPEN_FRONT_DEG: f32 = 44.0;

/// The layers drawn: the fasciae, then the pelvic side.
const FASCIAE: [usize; 2] = [1, 2];
const PELVIS: usize = LAYERS - 1;

/// One drawn surface's fixed parts.
struct Surface {
    name: &'static str,
    roles: [SurfaceRole; 2],
    indices: Vec<u32>,
    regions: Vec<u8>,
}

/// The drawn grids of one membrane: the rows and columns kept, and each surface's triangles.
pub struct Drawn {
    rows: Vec<usize>,
    cols: Vec<usize>,
    /// The drawn nodes of the three layers, with what places the sleeping ones.
    grid: DrawnGrid,
    /// Shared with the snapshots built off the simulation thread ([`Drawn::meshes_later`]).
    fascia: Arc<Surface>,
    pelvis: Arc<Surface>,
}

impl Drawn {
    /// The grids of `scene`'s membrane (the laparoscope looks down into the pelvis from its
    /// inlet, onto the mesorectum, so the pelvic side is drawn open over the front).
    pub fn new(scene: &RectumScene) -> Self {
        let m = scene.membrane();
        let (rows, cols) = (m.rows(), m.cols());
        let d = ((rows * cols) as f64 / DRAWN_LAYER_VERTICES as f64)
            .sqrt()
            .ceil()
            .max(1.0) as usize;
        let ri: Vec<usize> = (0..rows)
            .step_by(d)
            .chain((!(rows - 1).is_multiple_of(d)).then_some(rows - 1))
            .collect();
        let cj: Vec<usize> = (0..cols).step_by(d).collect();
        let grid = |layers: &[usize], open_front_deg: f32, region: fn(regions::RegionId) -> u8| {
            grid_triangles(scene, layers, [&ri, &cj], open_front_deg, region)
        };
        let (indices, regions) = grid(&FASCIAE, 0.0, |id| match id {
            regions::TARGET => 1,
            _ => 0,
        });
        let fascia = Surface {
            name: "fascia",
            roles: [SurfaceRole::Membrane, SurfaceRole::Target],
            indices,
            regions,
        };
        let (indices, regions) = grid(&[PELVIS], PELVIS_OPEN_FRONT_DEG, |id| {
            regions::region(id).map_or(0, |x| match x.kind {
                RegionKind::Vulnerable => 1,
                RegionKind::Target => 0,
            })
        });
        let pelvis = Surface {
            name: "pelvis",
            roles: [SurfaceRole::Fat, SurfaceRole::Duct],
            indices,
            regions,
        };
        Drawn {
            grid: DrawnGrid::new(&[FASCIAE[0], FASCIAE[1], PELVIS], &ri, &cj),
            rows: ri,
            cols: cj,
            fascia: Arc::new(fascia),
            pelvis: Arc::new(pelvis),
        }
    }

    /// The fasciae and the pelvic side as `m` is now (where it steps on a device, as the
    /// device left it: see [`Membrane::place_drawn`]), the vertices placed and the cut links
    /// marked now (a vertex on a cut link of the dissection plane is marked cut), the
    /// surfaces (their normals) built later on any thread.
    pub fn meshes_later(
        &mut self,
        m: &mut Membrane,
    ) -> impl FnOnce() -> [ModelSnapshot; 2] + Send + 'static {
        let mut positions = {
            let _span = tracing::debug_span!("rectum_snapshot_grid").entered();
            m.place_drawn(&mut self.grid)
        };
        let per_layer = self.rows.len() * self.cols.len();
        let pelvis = positions.split_off(FASCIAE.len() * per_layer);
        let mut cut = Vec::with_capacity(per_layer);
        for &i in &self.rows {
            cut.extend(self.cols.iter().map(|&j| !m.link_alive(1, i, j)));
        }
        let fascia_cut = [cut.as_slice(), cut.as_slice()].concat();
        let pelvis_cut = vec![false; pelvis.len()];
        let (fs, ps) = (self.fascia.clone(), self.pelvis.clone());
        move || {
            let (fascia, pelvis) = rayon::join(
                || surface(&fs, positions, fascia_cut),
                || surface(&ps, pelvis, pelvis_cut),
            );
            [fascia, pelvis]
        }
    }
}

/// A drawn surface with its vertices `positions` and their cut marks.
fn surface(s: &Surface, positions: Vec<glam::Vec3>, cut_edge: Vec<bool>) -> ModelSnapshot {
    let _span = tracing::debug_span!("rectum_snapshot_surface").entered();
    ModelSnapshot {
        name: s.name.to_string(),
        normals: crate::mesh::vertex_normals(&positions, &s.indices),
        positions,
        cut_edge,
        indices: s.indices.clone(),
        regions: s.regions.clone(),
        roles: s.roles.to_vec(),
        seared: Vec::new(),
    }
}

/// The triangles of layers `layers` as grids over rows and columns `[ri, cj]` (closed around
/// the ring), one layer's vertices after another's, leaving out the front's
/// `open_front_deg` either side, with each triangle's region from `region` of the scene's
/// region id at its first corner.
fn grid_triangles(
    scene: &RectumScene,
    layers: &[usize],
    [ri, cj]: [&[usize]; 2],
    open_front_deg: f32,
    region: fn(regions::RegionId) -> u8,
) -> (Vec<u32>, Vec<u8>) {
    let m = scene.membrane();
    let cols = m.cols();
    let (nr, nc) = (ri.len(), cj.len());
    let (mut indices, mut out) = (Vec::new(), Vec::new());
    let last_c = if m.periodic() { nc } else { nc - 1 };
    // Column j lies `360 j / cols` degrees round from the front (column 0).
    let from_front = |j: usize| {
        let deg = 360.0 * j as f32 / cols as f32;
        deg.min(360.0 - deg)
    };
    for (k, &l) in layers.iter().enumerate() {
        let base = (k * nr * nc) as u32;
        for a in 0..nr - 1 {
            for b in 0..last_c {
                let b1 = (b + 1) % nc;
                if from_front(cj[b]) < open_front_deg && from_front(cj[b1]) < open_front_deg {
                    continue;
                }
                let v = |r: usize, c: usize| base + (r * nc + c) as u32;
                indices.extend([
                    v(a, b),
                    v(a + 1, b),
                    v(a, b1),
                    v(a, b1),
                    v(a + 1, b),
                    v(a + 1, b1),
                ]);
                let r = region(scene.region_of(m.node(l, ri[a], cj[b])));
                out.extend([r, r]);
            }
        }
    }
    (indices, out)
}
