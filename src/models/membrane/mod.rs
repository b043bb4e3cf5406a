//! The rectum paper's multi-layer mass-spring membrane (eqs 1-6): four layers of `rows x cols`
//! nodes on a structured grid, `rows` along the bowel and `cols` around it (a closed ring
//! when `periodic`). Layer 0 lies on the rectum's surface, layer 3 on the surrounding tissue,
//! layers 1 and 2 between them; the paper numbers them 1 to 4. Springs join each node to its
//! neighbours in its layer (around and along) and to the node of the same row and column in
//! the next layer (links 0-1, 1-2 and 2-3). Links 1-2 are the dissection plane: cutting one
//! removes it and puts the tissue it held under the residual strain of eq 5, `sigma_r = E
//! eps_r`: the in-layer springs between released nodes have their rest length shortened by
//! `eps_r`, so a freed sheet shrinks by that much (the superposition the paper cites: the
//! residual stress equals a force on the cut surface).
//!
//! Forces (eqs 3-4): each spring pulls with `k (|d| - L0)` along `d` plus a damping force along
//! it, `c_s (v_j - v_i) . d / |d|` with `c_s = beta k` (stiffness-proportional, `beta` per row
//! and family for a damping ratio); each node feels point damping `-D v` (eq 4's `f`) and gravity.
//! Masses come from each layer's density and thickness over each node's share of the area;
//! spring stiffness from its layer's modulus: `k = E t w / L0` for a spring of rest length
//! `L0` spanning a strip `w` wide (a sheet of thickness `t`), and `E A / L0` for a link over
//! the column's area. Layer 0 is held to targets its owner sets each step (the rod's skin)
//! and layer 3 to where it lay at rest, by stiff springs per unit area.
//!
//! Integrators (see [`Integrator`]): symplectic Euler and classical Runge-Kutta (the paper's),
//! each stable only below about `0.7 dx / c` ([`Membrane::explicit_step_limit`]); at the
//! paper's resolution with physical masses that is a fraction of a millisecond (see
//! `docs/rectum.md`). f32 state in row blocks (each row of each layer one contiguous run of
//! positions and velocities); rows are stepped in fixed chunks in parallel (rayon), the same
//! bytes on any number of threads.

mod active;
mod anchor_sums;
mod anchors;
mod block;
#[cfg(test)]
mod block_tests;
mod chain;
#[cfg(test)]
mod chain_tests;
mod checkpoint;
#[cfg(test)]
mod checkpoint_tests;
mod cuts;
mod device;
mod forces;
#[cfg(test)]
mod frame_tests;
pub mod gpu;
#[cfg(test)]
mod gpu_tests;
mod integrate;
mod model;
#[cfg(test)]
mod sums_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tile_tests;

use glam::Vec3;

pub use active::{AHEAD_M, ActivityParams, DrawnGrid, TILE_COLS, TILE_ROWS};
pub use anchor_sums::AnchorSum;
pub use chain::{ChainBinding, frames as chain_frames};

/// Layers in the membrane.
pub const LAYERS: usize = 4;

/// How the membrane's state advances. Both are explicit: stable below
/// [`Membrane::explicit_step_limit`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// v += dt F / m; x += dt v.
    Symplectic,
    /// Classical fourth-order Runge-Kutta on (x, v), as the paper.
    RungeKutta4,
}

impl Integrator {
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Symplectic => "symplectic",
            Integrator::RungeKutta4 => "runge_kutta_4",
        }
    }
}

/// One layer's material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LayerMaterial {
    /// Young's modulus of the sheet, Pa.
    pub youngs_modulus_pa: f32,
    /// Thickness of the sheet the layer stands for, m.
    pub thickness_m: f32,
    pub density_kg_per_m3: f32,
}

/// The membrane's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneParams {
    pub layers: [LayerMaterial; LAYERS],
    /// Modulus of the tissue the links stand for (between layers), Pa.
    pub link_modulus_pa: [f32; LAYERS - 1],
    /// Eq 4's point damping D as a rate, 1/s (force -D m v).
    pub damping_per_s: f32,
    /// Damping along each spring within a layer, as a fraction of critical for the grid's
    /// highest mode at its row's mean node mass.
    pub spring_damping_ratio: f32,
    /// Damping along each link between layers, as a fraction of critical for a layer
    /// bouncing on its link.
    pub link_damping_ratio: f32,
    /// Stiffness per unit area holding layer 0 to its targets and layer 3 to its rest, Pa/m.
    pub attach_pa_per_m: f32,
    /// Eq 5's residual strain of the tissue freed by a cut.
    pub residual_strain: f32,
    pub gravity: Vec3,
    pub integrator: Integrator,
}

/// Where the membrane's nodes start: `positions[l][i * cols + j]` for layer `l`, row `i`,
/// column `j`.
#[derive(Debug, Clone)]
pub struct MembraneShape {
    pub rows: usize,
    pub cols: usize,
    /// Whether column `cols - 1` joins column 0 (a tube) or the sheet has two free edges.
    pub periodic: bool,
    pub positions: [Vec<Vec3>; LAYERS],
}

impl MembraneShape {
    /// A flat sheet (for tests and reference cases): rows along x and columns along z,
    /// `spacing` apart, layer `l` at `l gap` below layer 0; not a ring.
    pub fn sheet(rows: usize, cols: usize, spacing: f32, gap: f32) -> MembraneShape {
        let positions = std::array::from_fn(|l| {
            (0..rows * cols)
                .map(|k| {
                    let (i, j) = (k / cols, k % cols);
                    Vec3::new(i as f32 * spacing, -(l as f32) * gap, j as f32 * spacing)
                })
                .collect()
        });
        MembraneShape {
            rows,
            cols,
            periodic: false,
            positions,
        }
    }
}

/// Why a membrane could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MembraneError {
    #[error("a membrane needs at least 2 rows and 3 columns, got {rows} x {cols}")]
    TooSmall { rows: usize, cols: usize },
    #[error("layer {layer} has {found} positions, expected {expected} (rows x cols)")]
    WrongCount {
        layer: usize,
        found: usize,
        expected: usize,
    },
    #[error("layer {layer}, node {node}: position {value} is not finite")]
    NotFinite {
        layer: usize,
        node: usize,
        value: Vec3,
    },
    #[error(
        "two neighbouring nodes coincide (layer {layer}, node {node}): no spring can join them"
    )]
    Coincident { layer: usize, node: usize },
    #[error("{what} must be finite and > 0, got {value}")]
    BadParameter { what: &'static str, value: f32 },
    #[error("anchor group member {member}: {why}")]
    BadGroup { member: usize, why: String },
    #[error("layer-0 node {node}'s binding to the chain: {why}")]
    BadBinding { node: usize, why: String },
    #[error("the chain's pose: {0}")]
    BadPose(String),
}

/// The state in row blocks: for layer `l` and row `i` (block `b = l * rows + i`), the row's
/// positions x, y, z then velocities x, y, z, `cols` values each, at `(b * 6 + c) * cols + j`.
/// A row is one contiguous run, so a pass over the grid reads a few long streams.
#[derive(Debug, Clone, Default)]
pub(crate) struct State {
    pub data: Vec<f32>,
}

/// Fields of a row block of [`Membrane::rows_data`]: stiffness and rest length of the spring
/// to the next column, to the next row and to the next layer, then 1 / mass, then the shear
/// tether's stiffness and place (layers 1 and 2).
pub(crate) mod field {
    pub const K: [usize; 3] = [0, 2, 4];
    pub const REST: [usize; 3] = [1, 3, 5];
    pub const INV_MASS: usize = 6;
    /// Layers 1 and 2: stiffness of the shear tether to the column line, and where on it.
    pub const SHEAR_K: usize = 7;
    pub const SHEAR_W: usize = 8;
    pub const COUNT: usize = 9;
}

/// Spring families: index into [`field::K`] and [`field::REST`].
pub(crate) const AROUND: usize = 0;
pub(crate) const ALONG: usize = 1;
pub(crate) const LINK: usize = 2;

/// The membrane.
#[derive(Debug, Clone)]
pub struct Membrane {
    pub params: MembraneParams,
    rows: usize,
    cols: usize,
    periodic: bool,
    state: State,
    mass: Vec<f32>,
    /// Per row block, [`field::COUNT`] runs of `cols`: the springs that start at each node
    /// (around: to the next column; along: to the next row; link: to the same place in the
    /// next layer) and the node's 1 / mass. Stiffness 0 marks a missing or cut spring.
    rows_data: Vec<f32>,
    /// Damping of each spring family per row block, as a time: `c = beta k` (stiffness-
    /// proportional; see [`Membrane::set_spring_damping`]).
    beta: Vec<[f32; 3]>,
    /// Counts the changes to `rows_data` and `beta` (a cut, a damping set, a checkpoint
    /// loaded): a CPU block keeps the parameters it gathered while this stays the same.
    springs_version: u64,
    /// Attachments of layers 0 (slot 0, to targets the owner sets) and 3 (slot 1, to its
    /// rest): per slot and row, four runs of `cols`: stiffness N/m, then the target x, y, z.
    attach: Vec<f32>,
    /// Nodes freed by a cut (their in-layer springs carry the residual strain).
    released: Vec<bool>,
    /// External forces for the next step (node, force), N.
    external: Vec<(u32, Vec3)>,
    scratch: integrate::Scratch,
    /// The largest stable explicit step, s (see [`Membrane::explicit_step_limit`]).
    step_limit: f32,
    /// The active set, when on.
    activity: Option<active::Activity>,
    /// Run the kernels on the baseline vector unit even where a wider one exists (tests
    /// compare the two).
    baseline_vectors: bool,
    /// As a model of a world (see `model.rs`): the share of the explicit limit each substep
    /// takes, the substeps and awake share of the last step, the last good state.
    substep_safety: f32,
    last_substeps: usize,
    last_share: f32,
    saved: Option<Box<checkpoint::Saved>>,
    /// The tiles that changed since the last checkpoint (`checkpoint.rs`).
    changed: checkpoint::Changed,
    /// The GPU the substeps run on, if any (`device.rs`).
    device: device::Slot,
    /// Layer 0's nodes in groups whose loads are summed each step, and the last sums
    /// (`anchor_sums.rs`); scratch for the loads.
    anchor_groups: Option<Box<anchor_sums::AnchorGroups>>,
    anchor_sums: Vec<AnchorSum>,
    load_scratch: Vec<(u32, u32, Vec3)>,
    /// Layer 0's nodes bound to a chain whose pose places their targets (`chain.rs`).
    chain: Option<Box<chain::Chain>>,
}

impl Membrane {
    /// Builds the membrane at rest in `shape`.
    pub fn new(shape: MembraneShape, params: MembraneParams) -> Result<Membrane, MembraneError> {
        let (rows, cols) = (shape.rows, shape.cols);
        if rows < 2 || cols < 3 {
            return Err(MembraneError::TooSmall { rows, cols });
        }
        let per = rows * cols;
        for (l, p) in shape.positions.iter().enumerate() {
            if p.len() != per {
                return Err(MembraneError::WrongCount {
                    layer: l,
                    found: p.len(),
                    expected: per,
                });
            }
            if let Some((node, value)) = p.iter().enumerate().find(|(_, q)| !q.is_finite()) {
                return Err(MembraneError::NotFinite {
                    layer: l,
                    node,
                    value: *value,
                });
            }
        }
        check_params(&params)?;
        let n = LAYERS * per;
        let at = |l: usize, i: usize, j: usize| shape.positions[l][i * cols + j];
        let next_j = |j: usize| {
            if j + 1 < cols {
                Some(j + 1)
            } else {
                shape.periodic.then_some(0)
            }
        };
        let mut data = vec![0.0; 6 * n];
        for l in 0..LAYERS {
            for i in 0..rows {
                for j in 0..cols {
                    let p = at(l, i, j);
                    for c in 0..3 {
                        data[((l * rows + i) * 6 + c) * cols + j] = p[c];
                    }
                }
            }
        }
        let mut m = Membrane {
            params,
            rows,
            cols,
            periodic: shape.periodic,
            state: State { data },
            mass: vec![0.0; n],
            rows_data: vec![0.0; field::COUNT * n],
            beta: vec![[0.0; 3]; LAYERS * rows],
            springs_version: 0,
            attach: vec![0.0; 2 * 4 * per],
            released: vec![false; n],
            external: Vec::new(),
            scratch: integrate::Scratch::default(),
            step_limit: f32::INFINITY,
            activity: None,
            baseline_vectors: false,
            substep_safety: model::SUBSTEP_SAFETY,
            last_substeps: 0,
            last_share: 1.0,
            saved: None,
            device: device::Slot::default(),
            changed: checkpoint::Changed::everything(),
            anchor_groups: None,
            anchor_sums: Vec::new(),
            load_scratch: Vec::new(),
            chain: None,
        };
        // Each node's share of its layer's area: a quarter of each cell around it, the cell
        // spanned by its neighbours along and around (half a spring each way).
        let mut area = vec![0.0f32; n];
        for l in 0..LAYERS {
            let mat = params.layers[l];
            for i in 0..rows {
                for j in 0..cols {
                    let node = m.node(l, i, j);
                    let p = at(l, i, j);
                    let along = |di: isize| {
                        let ii = i as isize + di;
                        (0..rows as isize)
                            .contains(&ii)
                            .then(|| (at(l, ii as usize, j) - p).length())
                    };
                    let around = |dj: isize| {
                        let jj = j as isize + dj;
                        let jj = if shape.periodic {
                            Some(jj.rem_euclid(cols as isize) as usize)
                        } else {
                            (0..cols as isize).contains(&jj).then_some(jj as usize)
                        };
                        jj.map(|jj| (at(l, i, jj) - p).length())
                    };
                    let half = |a: Option<f32>, b: Option<f32>| {
                        0.5 * (a.unwrap_or(0.0) + b.unwrap_or(0.0))
                    };
                    let a = half(along(-1), along(1)) * half(around(-1), around(1));
                    area[node] = a;
                    m.mass[node] = mat.density_kg_per_m3 * mat.thickness_m * a;
                    // Springs to the next column and the next row: E t w / L0, the strip w
                    // wide being the node's extent across the spring.
                    let et = mat.youngs_modulus_pa * mat.thickness_m;
                    if let Some(jn) = next_j(j) {
                        let l0 = (at(l, i, jn) - p).length();
                        if l0 <= 0.0 {
                            return Err(MembraneError::Coincident { layer: l, node });
                        }
                        let w = half(along(-1), along(1));
                        *m.spring_mut(field::K[AROUND], node) = et * w / l0;
                        *m.spring_mut(field::REST[AROUND], node) = l0;
                    }
                    if i + 1 < rows {
                        let l0 = (at(l, i + 1, j) - p).length();
                        if l0 <= 0.0 {
                            return Err(MembraneError::Coincident { layer: l, node });
                        }
                        let w = half(around(-1), around(1));
                        *m.spring_mut(field::K[ALONG], node) = et * w / l0;
                        *m.spring_mut(field::REST[ALONG], node) = l0;
                    }
                }
            }
        }
        for l in 0..LAYERS - 1 {
            for i in 0..rows {
                for j in 0..cols {
                    let node = m.node(l, i, j);
                    let l0 = (at(l + 1, i, j) - at(l, i, j)).length();
                    if l0 <= 0.0 {
                        return Err(MembraneError::Coincident { layer: l, node });
                    }
                    let a = 0.5 * (area[node] + area[node + per]);
                    *m.spring_mut(field::K[LINK], node) = params.link_modulus_pa[l] * a / l0;
                    *m.spring_mut(field::REST[LINK], node) = l0;
                }
            }
        }
        for node in 0..n {
            *m.spring_mut(field::INV_MASS, node) = 1.0 / m.mass[node];
        }
        // Shear of the tissue between the layers: the links are springs along their length
        // only, so a middle layer could slide sideways over the others at no cost. A node of
        // layers 1 and 2 is tethered, sideways only, to its place on the line from its
        // column's layer-0 node to its layer-3 node (where it was built): moved sideways by
        // `u`, the tissue on either side shears by `u / L` over the node's area, so the
        // tether's stiffness is `G A (1 / L_below + 1 / L_above)`, `G = E / 3` (nearly
        // incompressible).
        for l in 1..LAYERS - 1 {
            for i in 0..rows {
                for j in 0..cols {
                    let node = m.node(l, i, j);
                    let (p0, p, p3) = (at(0, i, j), at(l, i, j), at(LAYERS - 1, i, j));
                    let span = (p3 - p0).length().max(f32::EPSILON);
                    let below = (p - at(l - 1, i, j)).length().max(f32::EPSILON);
                    let above = (at(l + 1, i, j) - p).length().max(f32::EPSILON);
                    let g = |e: f32| e / 3.0;
                    let k = area[node]
                        * (g(params.link_modulus_pa[l - 1]) / below
                            + g(params.link_modulus_pa[l]) / above);
                    *m.spring_mut(field::SHEAR_K, node) = k;
                    *m.spring_mut(field::SHEAR_W, node) =
                        ((p - p0).dot(p3 - p0) / (span * span)).clamp(0.0, 1.0);
                }
            }
        }
        // Attachments: layer 0 to its targets (its rest until the owner moves them), layer 3
        // to its rest.
        for (slot, l) in [(0usize, 0usize), (1, LAYERS - 1)] {
            for i in 0..rows {
                for j in 0..cols {
                    let node = m.node(l, i, j);
                    let p = at(l, i, j);
                    let row = (slot * rows + i) * 4;
                    m.attach[row * cols + j] = params.attach_pa_per_m * area[node];
                    for c in 0..3 {
                        m.attach[(row + 1 + c) * cols + j] = p[c];
                    }
                }
            }
        }
        m.set_spring_damping();
        m.step_limit = m.explicit_step_limit();
        Ok(m)
    }

    /// Index of `f` (a [`field`]) of `node` in `rows_data`.
    fn spring_at(&self, f: usize, node: usize) -> usize {
        let (b, j) = (node / self.cols, node % self.cols);
        (b * field::COUNT + f) * self.cols + j
    }

    fn spring(&self, f: usize, node: usize) -> f32 {
        self.rows_data[self.spring_at(f, node)]
    }

    fn spring_mut(&mut self, f: usize, node: usize) -> &mut f32 {
        let at = self.spring_at(f, node);
        self.springs_version = self.springs_version.wrapping_add(1);
        &mut self.rows_data[at]
    }

    /// Index of component `c` (0-2 position, 3-5 velocity) of `node` in the state.
    pub(crate) fn state_at(&self, c: usize, node: usize) -> usize {
        let (b, j) = (node / self.cols, node % self.cols);
        (b * 6 + c) * self.cols + j
    }

    /// Spring damping, stiffness-proportional per family and row block: `c = beta k`, from
    /// the row's mean stiffness of each family and its nodes' mean mass `m`. In a layer, the
    /// grid's highest mode (neighbours moving against each other) has `omega^2 = 4 (k_a +
    /// k_b) / m` (`k_a`, `k_b`: the springs around and along) and is damped at `beta omega /
    /// 2`, so `beta = zeta sqrt(m / (k_a + k_b))` damps it at `zeta` of critical (the modes a
    /// trainee sees, centimetres long, are slower and their point damping `D` rules them).
    /// A link's `beta = 2 zeta_link sqrt(m / k_link)` damps a layer bouncing on its link at
    /// `zeta_link` of critical. A sheet's `beta` grows with the spacing at one `zeta` (`m`
    /// with the area, `k` not): the tissue's viscosity is `beta E`, so a grid `s` times
    /// coarser keeps the finer grid's tissue with `zeta / s`; a link's does not change.
    fn set_spring_damping(&mut self) {
        let (z, zl) = (
            self.params.spring_damping_ratio,
            self.params.link_damping_ratio,
        );
        let cols = self.cols;
        for b in 0..LAYERS * self.rows {
            let nodes = b * cols..(b + 1) * cols;
            let mass = self.mass[nodes.clone()].iter().sum::<f32>() / cols as f32;
            let mean = |fam: usize| {
                let (sum, count) = nodes
                    .clone()
                    .map(|node| self.spring(field::K[fam], node))
                    .filter(|&k| k > 0.0)
                    .fold((0.0f32, 0usize), |(s, c), k| (s + k, c + 1));
                if count > 0 { sum / count as f32 } else { 0.0 }
            };
            let in_layer = mean(AROUND) + mean(ALONG);
            let sheet = if in_layer > 0.0 {
                z * (mass / in_layer).sqrt()
            } else {
                0.0
            };
            let link = mean(LINK);
            self.springs_version = self.springs_version.wrapping_add(1);
            self.beta[b] = [
                sheet,
                sheet,
                if link > 0.0 {
                    2.0 * zl * (mass / link).sqrt()
                } else {
                    0.0
                },
            ];
        }
    }

    pub fn rows(&self) -> usize {
        self.rows
    }

    pub fn cols(&self) -> usize {
        self.cols
    }

    pub fn periodic(&self) -> bool {
        self.periodic
    }

    /// Nodes in all.
    pub fn len(&self) -> usize {
        self.mass.len()
    }

    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// Springs in all (around, along, links), cut ones not counted.
    pub fn springs(&self) -> usize {
        (0..self.len())
            .map(|node| {
                field::K
                    .iter()
                    .filter(|&&f| self.spring(f, node) > 0.0)
                    .count()
            })
            .sum()
    }

    /// The node at layer `l`, row `i`, column `j`.
    pub fn node(&self, l: usize, i: usize, j: usize) -> usize {
        (l * self.rows + i) * self.cols + j
    }

    pub fn coords(&self, node: usize) -> (usize, usize, usize) {
        let per = self.rows * self.cols;
        (node / per, (node % per) / self.cols, node % self.cols)
    }

    fn next_col(&self, j: usize) -> Option<usize> {
        if j + 1 < self.cols {
            Some(j + 1)
        } else {
            self.periodic.then_some(0)
        }
    }

    /// Where node `node` is, m. On a device, an awake tile's nodes are current on the CPU
    /// once [`Membrane::awake_tiles_near`] (or its kin) returned the tile, or after
    /// [`Membrane::catch_up`] (see `device_lazy.rs`).
    pub fn position(&self, node: usize) -> Vec3 {
        #[cfg(test)]
        self.assert_current(node);
        let d = &self.state.data;
        Vec3::from_array(std::array::from_fn(|c| d[self.state_at(c, node)]))
    }

    /// How fast node `node` moves, m/s (current as [`Membrane::position`] is).
    pub fn velocity(&self, node: usize) -> Vec3 {
        #[cfg(test)]
        self.assert_current(node);
        let d = &self.state.data;
        Vec3::from_array(std::array::from_fn(|c| d[self.state_at(3 + c, node)]))
    }

    pub fn mass(&self, node: usize) -> f32 {
        self.mass[node]
    }

    /// Total mass, kg.
    pub fn total_mass(&self) -> f32 {
        self.mass.iter().sum()
    }

    /// Sets where layer 0's node at row `i`, column `j` is held (the rod's skin there).
    pub fn set_target(&mut self, i: usize, j: usize, p: Vec3) {
        if i < self.rows && j < self.cols && p.is_finite() {
            let row = i * 4;
            for c in 0..3 {
                self.attach[(row + 1 + c) * self.cols + j] = p[c];
            }
        }
    }

    /// Lets layer `l` go free of its attachment (layer 0 from the rod, layer 3 from the wall).
    pub fn detach_layer(&mut self, l: usize) {
        self.catch_up();
        let slot = match l {
            0 => 0,
            x if x == LAYERS - 1 => 1,
            _ => return,
        };
        for i in 0..self.rows {
            let row = (slot * self.rows + i) * 4;
            self.attach[row * self.cols..(row + 1) * self.cols].fill(0.0);
        }
        self.device.stale();
        self.all_changed();
    }

    /// Adds a force on `node` for the next step, N.
    pub fn add_force(&mut self, node: usize, f: Vec3) {
        if node < self.len() && f.is_finite() {
            self.external.push((node as u32, f));
        }
    }

    /// One step of `dt_s` with the configured integrator, every node (the active set, if on,
    /// is not consulted: see [`Membrane::advance`]).
    pub fn step(&mut self, dt_s: f32) {
        self.catch_up();
        self.all_changed();
        integrate::step(self, dt_s);
        self.external.clear();
    }

    /// Advances `dt_s` in as many equal explicit steps as stability needs (each at most
    /// `safety` times the explicit limit, `safety` in (0, 1]); with the active set on, only
    /// the awake tiles step. The external forces act over all of them. Returns the number of
    /// steps taken.
    pub fn advance(&mut self, dt_s: f32, safety: f32) -> usize {
        let dt = if dt_s.is_finite() && dt_s > 0.0 {
            dt_s
        } else {
            1e-3
        };
        let safety = if safety.is_finite() {
            safety.clamp(0.05, 1.0)
        } else {
            0.9
        };
        let n = self.substeps_for(dt, safety);
        let all = self.activity.as_ref().is_none_or(|a| a.all_awake);
        if all {
            self.all_changed();
            // Every tile steps here or goes up from here: its targets on the CPU.
            let a = self.activity.take();
            let tiles: Vec<usize> = (0..a.as_ref().map_or(1, |a| a.awake.len())).collect();
            chain::place(self, a.as_ref(), &tiles);
            self.activity = a;
            if self.anchor_groups.is_some() {
                forces::sort_external(&mut self.external);
                let whole = [([0, self.rows], [0, self.cols])];
                anchor_sums::on_cpu(self, &whole);
            }
            let on_device = self.params.integrator == Integrator::Symplectic
                && device::whole_substeps(self, dt, n);
            for _ in 0..if on_device { 0 } else { n } {
                integrate::step(self, dt / n as f32);
            }
            if let Some(a) = &mut self.activity {
                a.awake_share += 1.0;
                a.steps += 1;
            }
            // Every tile moved: the instruments' broad phase needs their boxes.
            self.refresh_boxes();
        } else {
            forces::sort_external(&mut self.external);
            active::step(self, dt, n);
        }
        self.external.clear();
        n
    }

    /// The equal explicit substeps a step of `dt_s` takes at `safety` of the explicit limit
    /// (at least 1, at most 100,000).
    pub fn substeps_for(&self, dt_s: f32, safety: f32) -> usize {
        let limit = safety * self.step_limit;
        if limit.is_finite() && limit > 0.0 {
            ((dt_s / limit).ceil() as usize).clamp(1, 100_000)
        } else {
            1
        }
    }

    /// Runs `op` on the widest vector unit the CPU has (AVX2 on x86-64 where present), or on
    /// the baseline one when asked to.
    fn vectorized<Op: pulp::WithSimd>(&self, op: Op) -> Op::Output {
        if self.baseline_vectors {
            op.with_simd(pulp::Scalar::new())
        } else {
            pulp::Arch::new().dispatch(op)
        }
    }

    /// The largest stable explicit step, as computed when built, s.
    pub fn step_limit(&self) -> f32 {
        self.step_limit
    }

    /// Heap bytes of the state, the springs' data and the active set's buffers.
    pub fn heap_bytes(&self) -> usize {
        let f = std::mem::size_of::<f32>();
        let a = self.activity.as_ref().map_or(0, |a| a.heap_bytes());
        (self.state.data.capacity() + self.rows_data.capacity() + self.attach.capacity()) * f
            + self.mass.capacity() * f
            + self.released.capacity()
            + a
            + self.anchor_groups.as_ref().map_or(0, |g| g.heap_bytes())
    }

    /// Kinetic energy, J.
    pub fn kinetic_energy(&self) -> f64 {
        let s = self.current_state();
        (0..self.len())
            .map(|n| {
                let v = Vec3::from_array(std::array::from_fn(|c| s[self.state_at(3 + c, n)]));
                0.5 * f64::from(self.mass[n]) * f64::from(v.length_squared())
            })
            .sum()
    }

    /// The stiffness holding `node` to its target or rest, N/m (0 off layers 0 and 3).
    fn attach_stiffness(&self, node: usize) -> f32 {
        let (l, i, j) = self.coords(node);
        let slot = match l {
            0 => 0,
            x if x == LAYERS - 1 => 1,
            _ => return 0.0,
        };
        self.attach[(slot * self.rows + i) * 4 * self.cols + j]
    }

    /// Whether every position and velocity is finite.
    pub fn is_finite(&self) -> bool {
        self.current_state().iter().all(|v| v.is_finite())
    }

    /// A digest of the state's bits (as the device has it, where it steps).
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        for v in self.current_state().iter() {
            h.write(v.to_bits());
        }
        h.0
    }
}

fn check_params(p: &MembraneParams) -> Result<(), MembraneError> {
    let positive = |what: &'static str, v: f32| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(MembraneError::BadParameter { what, value: v })
        }
    };
    for m in &p.layers {
        positive("a layer's Young's modulus", m.youngs_modulus_pa)?;
        positive("a layer's thickness", m.thickness_m)?;
        positive("a layer's density", m.density_kg_per_m3)?;
    }
    let non_negative = |what: &'static str, v: f32| {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(MembraneError::BadParameter { what, value: v })
        }
    };
    for e in p.link_modulus_pa {
        non_negative("a link modulus", e)?;
    }
    non_negative("damping", p.damping_per_s)?;
    non_negative("spring damping ratio", p.spring_damping_ratio)?;
    non_negative("link damping ratio", p.link_damping_ratio)?;
    non_negative("attachment stiffness", p.attach_pa_per_m)?;
    if !(0.0..0.9).contains(&p.residual_strain) {
        return Err(MembraneError::BadParameter {
            what: "residual strain (0 to 0.9)",
            value: p.residual_strain,
        });
    }
    Ok(())
}
