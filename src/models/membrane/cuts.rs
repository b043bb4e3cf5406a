//! Cutting the dissection plane: the links between layers 1 and 2 taken out, the nodes they
//! held released, and the in-layer springs between released nodes shortened by the residual
//! strain (eq 5).

use super::{ALONG, AROUND, LAYERS, LINK, Membrane, field};
use glam::Vec3;

impl Membrane {
    /// Cuts the dissection-plane links (between layers 1 and 2) whose midpoints lie within
    /// `radius_m` of `center` (on the awake tiles only, with the active set on); the nodes
    /// they held are released, and the in-layer springs between released nodes shrink by the
    /// residual strain (eq 5). Returns how many links were cut.
    pub fn cut_plane(&mut self, center: Vec3, radius_m: f32) -> u32 {
        let mut cut = Vec::new();
        self.cut_plane_into(center, radius_m, &mut cut)
    }

    /// [`Membrane::cut_plane`], also putting the grid cell `i * cols + j` of every link cut
    /// into `cut` (cleared first, ascending).
    pub fn cut_plane_into(&mut self, center: Vec3, radius_m: f32, cut: &mut Vec<u32>) -> u32 {
        let per = self.rows * self.cols;
        let plane = 1;
        cut.clear();
        // With the active set on, only the awake tiles whose boxes come within the radius
        // of the centre are searched (a link's midpoint lies in its tile's box): a tool that
        // cuts has woken the tissue around it, and a sleeping tile's nodes do not step.
        let cols = self.cols;
        let candidates: Vec<usize> = if self.activity.as_ref().is_some_and(|a| !a.all_awake) {
            let reach = radius_m.abs() * (1.0 + 1e-4) + 1e-6;
            let mut tiles = Vec::new();
            self.awake_tiles_near(center, center, reach, &mut tiles);
            tiles
                .into_iter()
                .flat_map(|t| {
                    let ([r0, r1], [c0, c1]) = self.tile_span(t);
                    (r0..r1).flat_map(move |i| (c0..c1).map(move |j| i * cols + j))
                })
                .collect()
        } else {
            (0..per).collect()
        };
        for t in candidates {
            let a = plane * per + t;
            if self.spring(field::K[LINK], a) <= 0.0 {
                continue;
            }
            let mid = (self.position(a) + self.position(a + per)) * 0.5;
            if mid.distance_squared(center) <= radius_m * radius_m {
                cut.push(t as u32);
            }
        }
        if !cut.is_empty() {
            self.device.springs_changed();
        }
        // The tiles whose springs the cut and the releases below change (the node's, and
        // those of the nodes before it in its row and its column) go up again, state and
        // all: the CPU's copy of them is brought up to date first (`device_lazy.rs`).
        let touched: Vec<usize> = cut
            .iter()
            .flat_map(|&t| {
                let (i, j) = (t as usize / cols, t as usize % cols);
                let before_j = if j > 0 {
                    Some(j - 1)
                } else {
                    self.periodic.then_some(cols - 1)
                };
                let mut cells = vec![(i, j)];
                cells.extend(before_j.map(|jp| (i, jp)));
                cells.extend(i.checked_sub(1).map(|ip| (ip, j)));
                cells.into_iter().map(|(i, j)| self.tile_of(i, j))
            })
            .collect();
        self.catch_up_tiles(&touched);
        for &tile in &touched {
            self.device.tile_springs_changed(tile);
            self.springs_changed_in(tile);
        }
        for &t in cut.iter() {
            let t = t as usize;
            *self.spring_mut(field::K[LINK], plane * per + t) = 0.0;
            for l in [plane, plane + 1] {
                self.release(l * per + t);
            }
        }
        cut.len() as u32
    }

    /// Frees `node`: each in-layer spring to a node already freed takes the residual strain.
    pub(crate) fn release(&mut self, node: usize) {
        if self.released[node] {
            return;
        }
        self.released[node] = true;
        let shrink = 1.0 - self.params.residual_strain;
        let (l, i, j) = self.coords(node);
        // The springs around and along that start or end here.
        if let Some(jn) = self.next_col(j) {
            let other = self.node(l, i, jn);
            if self.released[other] {
                *self.spring_mut(field::REST[AROUND], node) *= shrink;
            }
        }
        let prev_j = if j > 0 {
            Some(j - 1)
        } else {
            self.periodic.then_some(self.cols - 1)
        };
        if let Some(jp) = prev_j {
            let other = self.node(l, i, jp);
            if self.released[other] {
                *self.spring_mut(field::REST[AROUND], other) *= shrink;
            }
        }
        if i + 1 < self.rows && self.released[node + self.cols] {
            *self.spring_mut(field::REST[ALONG], node) *= shrink;
        }
        if i > 0 && self.released[node - self.cols] {
            *self.spring_mut(field::REST[ALONG], node - self.cols) *= shrink;
        }
    }

    /// Whether the link between layer `l` and `l + 1` at row `i`, column `j` is there.
    pub fn link_alive(&self, l: usize, i: usize, j: usize) -> bool {
        l + 1 < LAYERS
            && i < self.rows
            && j < self.cols
            && self.spring(field::K[LINK], self.node(l, i, j)) > 0.0
    }
}
