//! Contacts: particles of different bodies keep apart (the paper's eq 2, the inequality
//! `C = |x_i - x_j| - 2 r >= 0`), instruments push particles out of their generalized
//! cylinders, and a closed grasper holds the particles between its jaws. Each is a position
//! projection inside the step's iterations; what an instrument does to the particles, summed
//! over them, is its reaction (the force the tissue puts on it), in newtons.
//!
//! Between bodies, only the particles a body shows to the others take part (its surface).
//! Their candidate pairs (closer than `2 r + margin`) come from a uniform grid and are kept
//! until some member has moved more than half the margin since (a Verlet list), so the search
//! runs now and then, not every step: while an instrument drags tissue, every substep. The
//! grid lists the members by column of cells with the bodies each column holds, so that a
//! member with no other body's member in the columns round it is passed over (about 15 in 16
//! of the cholecystectomy's). Everything runs in a fixed order: the same bytes every time.

use super::{Particles, colour};
use crate::collision::{Instrument, PointBlocks, PointCloud, ToolContact};
use glam::Vec3;

/// Particles of different bodies that keep apart.
#[derive(Debug, Clone, Default)]
pub struct BodyContacts {
    members: Vec<u32>,
    radius_m: f32,
    margin_m: f32,
    /// The members' positions when the pairs were found.
    at_search: Vec<Vec3>,
    pairs: Vec<(u32, u32)>,
    /// Pairs that never push (sorted): bodies built touching on purpose.
    ignore: Vec<(u32, u32)>,
    /// Searches so far (for the profiler).
    pub searches: u64,
    /// Pairs in contact at the last projection.
    pub touching: usize,
    /// The pairs in projection order (indices into `pairs`, by colour: pairs of one colour
    /// share no particle, `colour.rs`), and each pair's colour.
    order: Vec<u32>,
    colours: Vec<u32>,
    /// The search's grid, kept to be filled again.
    grid: ColumnGrid,
}

/// Members by column of cells along z: a column's are `cells[start[col]..start[col + 1]]`,
/// sorted by their cell along z, then by member. A dense grid of cells would be mostly empty
/// cells round the organs' surfaces, each zeroed and summed at every search; columns are
/// fewer by the box's depth in cells. Each column also keeps which bodies' members it holds,
/// a bit each (bodies from 15 on share the last bit), and which the columns round it hold,
/// so that a column with one body round it, and a member with no other body's member round
/// it, are passed over.
#[derive(Debug, Clone, Default)]
struct ColumnGrid {
    start: Vec<u32>,
    bodies: Vec<u16>,
    /// The bodies of the 3 x 3 columns round each column (itself included), and of the
    /// 1 x 3 along y (on the way there).
    around: Vec<u16>,
    along: Vec<u16>,
    /// Each listed member's cell along z and its index.
    cells: Vec<(u32, u32)>,
    /// Each member's column (`u32::MAX` where it is not finite) and cell along z.
    column_of: Vec<(u32, u32)>,
    /// Each member's body.
    body_of: Vec<u16>,
}

fn body_bit(b: u16) -> u16 {
    1 << b.min(15)
}

/// The columns (x, y) of the 3 x 3 round column (`x`, `y`) inside a box of `dims` cells.
fn neighbourhood(x: u32, y: u32, dims: glam::UVec3) -> impl Iterator<Item = (u32, u32)> {
    let (x0, y0) = (x.saturating_sub(1), y.saturating_sub(1));
    let (x1, y1) = ((x + 1).min(dims.x - 1), (y + 1).min(dims.y - 1));
    (x0..=x1).flat_map(move |x| (y0..=y1).map(move |y| (x, y)))
}

impl ColumnGrid {
    /// The members at `at` (those not finite left out) in the columns of a box of `dims`
    /// cells, each in cell `cell_of`, of body `body_of`.
    fn fill(
        &mut self,
        at: &[Vec3],
        dims: glam::UVec3,
        cell_of: impl Fn(Vec3) -> glam::UVec3,
        body_of: impl Fn(usize) -> u16,
    ) {
        let columns = dims.x as usize * dims.y as usize;
        self.start.clear();
        self.start.resize(columns + 1, 0);
        self.bodies.clear();
        self.bodies.resize(columns, 0);
        self.column_of.clear();
        self.body_of.clear();
        for (k, a) in at.iter().enumerate() {
            let b = body_of(k);
            self.body_of.push(b);
            if !a.is_finite() {
                self.column_of.push((u32::MAX, 0));
                continue;
            }
            let c = cell_of(*a);
            let col = c.x * dims.y + c.y;
            self.column_of.push((col, c.z));
            self.start[col as usize + 1] += 1;
            self.bodies[col as usize] |= body_bit(b);
        }
        for c in 0..columns {
            self.start[c + 1] += self.start[c];
        }
        self.cells.clear();
        self.cells.resize(self.start[columns] as usize, (0, 0));
        let mut fill = self.start.clone();
        for (k, &(col, z)) in self.column_of.iter().enumerate() {
            if let Some(f) = fill.get_mut(col as usize) {
                self.cells[*f as usize] = (z, k as u32);
                *f += 1;
            }
        }
        for c in 0..columns {
            self.cells[self.start[c] as usize..self.start[c + 1] as usize].sort_unstable();
        }
        // The bodies round each column: along y, then along x (column `x * ny + y`).
        let ny = dims.y as usize;
        let bodies = &self.bodies;
        self.along.clear();
        self.along.extend((0..columns).map(|c| {
            let y = c % ny;
            let below = if y > 0 { bodies[c - 1] } else { 0 };
            let above = if y + 1 < ny { bodies[c + 1] } else { 0 };
            below | bodies[c] | above
        }));
        let along = &self.along;
        self.around.clear();
        self.around.extend((0..columns).map(|c| {
            let before = if c >= ny { along[c - ny] } else { 0 };
            let after = along.get(c + ny).copied().unwrap_or(0);
            before | along[c] | after
        }));
    }

    fn heap_bytes(&self) -> usize {
        self.start.capacity() * 4
            + (self.bodies.capacity()
                + self.around.capacity()
                + self.along.capacity()
                + self.body_of.capacity())
                * 2
            + (self.cells.capacity() + self.column_of.capacity()) * 8
    }

    /// Whether a member of a body other than `own` lies in the columns round `col`.
    fn other_body_round(&self, col: u32, own: u16) -> bool {
        // A body from 15 on cannot tell its bit from another's: it always looks.
        let own = if own < 15 { body_bit(own) } else { 0 };
        self.around[col as usize] & !own != 0
    }

    /// The members of column `col` in the cells along z from `z - 1` to `z + 1`.
    fn near(&self, col: u32, z: u32) -> impl Iterator<Item = u32> + '_ {
        let column =
            &self.cells[self.start[col as usize] as usize..self.start[col as usize + 1] as usize];
        let first = column.partition_point(|&(cz, _)| cz + 1 < z);
        column[first..]
            .iter()
            .take_while(move |&&(cz, _)| cz <= z + 1)
            .map(|&(_, m)| m)
    }
}

impl BodyContacts {
    /// Contacts among `members` (particle indices), each a sphere of `radius_m`; candidate
    /// pairs are kept while nothing has moved more than `margin_m / 2`. The members are kept
    /// sorted, each once.
    pub fn new(mut members: Vec<u32>, radius_m: f32, margin_m: f32) -> BodyContacts {
        members.sort_unstable();
        members.dedup();
        BodyContacts {
            members,
            radius_m: radius_m.max(0.0),
            margin_m: margin_m.max(0.0),
            ..BodyContacts::default()
        }
    }

    /// From now on, the pairs closer than two radii now never push: bodies that are built
    /// touching (a duct growing out of its organ, a tie) stay as built. Returns how many.
    pub fn ignore_present_overlaps(&mut self, p: &Particles) -> usize {
        let margin = self.margin_m;
        self.margin_m = 0.0;
        self.ignore.clear();
        self.search_at(&p.body, |i| p.x[i]);
        self.ignore = std::mem::take(&mut self.pairs);
        self.order.clear();
        self.colours.clear();
        self.margin_m = margin;
        self.at_search.clear();
        self.ignore.len()
    }

    /// The particles tested.
    pub fn members(&self) -> usize {
        self.members.len()
    }

    /// The particles tested, in order.
    pub fn member_indices(&self) -> &[u32] {
        &self.members
    }

    /// Candidate pairs now.
    pub fn pairs(&self) -> &[(u32, u32)] {
        &self.pairs
    }

    /// Searches again for candidate pairs if a member has moved more than half the margin
    /// since the last search (or there was none).
    pub fn refresh(&mut self, p: &Particles) {
        self.refresh_by(&p.body, |i| p.x[i]);
    }

    /// [`BodyContacts::refresh`] with particle `i` at `at(i)` (bodies `body`): a device's
    /// substep searches from the positions its prediction will give, formed on the CPU member
    /// by member as the test and the search read them (no copy of every particle's).
    pub fn refresh_by(&mut self, body: &[u16], at: impl Fn(usize) -> Vec3) {
        let half = 0.5 * self.margin_m;
        let moved = self.at_search.len() != self.members.len()
            || self
                .members
                .iter()
                .zip(&self.at_search)
                .any(|(&i, a)| at(i as usize).distance_squared(*a) > half * half);
        if moved {
            self.search_at(body, at);
            let colours =
                colour::greedy(&self.pairs.iter().map(|&(i, j)| [i, j]).collect::<Vec<_>>());
            let order = colour::order(&colours);
            self.order = order.iter().map(|&k| k as u32).collect();
            self.colours = order.iter().map(|&k| colours[k]).collect();
        }
    }

    /// The pairs in projection order (by colour), and their colours.
    pub fn pairs_by_colour(&self) -> (Vec<(u32, u32)>, &[u32]) {
        let pairs = self.order.iter().map(|&k| self.pairs[k as usize]).collect();
        (pairs, &self.colours)
    }

    /// Two radii: pairs closer than this push apart, m.
    pub fn contact_distance_m(&self) -> f32 {
        2.0 * self.radius_m
    }

    /// The candidate pairs among the members, each particle `i` at `at(i)` (kept as where
    /// the search found them).
    fn search_at(&mut self, body: &[u16], at: impl Fn(usize) -> Vec3) {
        self.at_search.clear();
        self.at_search
            .extend(self.members.iter().map(|&i| at(i as usize)));
        self.searches += 1;
        self.pairs.clear();
        let reach = 2.0 * self.radius_m + self.margin_m;
        let cell = reach.max(1e-6);
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for a in self.at_search.iter().filter(|a| a.is_finite()) {
            lo = lo.min(*a);
            hi = hi.max(*a);
        }
        if !lo.is_finite() {
            return;
        }
        // Columns of cells along z over the members' box (at most about 64 a member: a
        // surface's members fill a thin shell of their box, and the fallback is quadratic in
        // a slab).
        let span = ((hi - lo) / cell).floor();
        let dims = span.min(Vec3::splat(1e6)).as_uvec3() + 1;
        let columns = dims.x as usize * dims.y as usize;
        if columns > 64 * self.members.len() + 4096 || span.max_element() >= 1e6 {
            self.search_sorted(body, reach);
            return;
        }
        // `a - lo` is never negative, so the conversion's truncation is the floor (without
        // SSE4.1, which a portable build may not assume, `floor` is a call a component).
        let cell_of = |a: Vec3| ((a - lo) / cell).as_uvec3().min(dims - 1);
        let mut grid = std::mem::take(&mut self.grid);
        grid.fill(&self.at_search, dims, cell_of, |k| {
            body[self.members[k] as usize]
        });
        let r2 = reach * reach;
        let mut found = std::mem::take(&mut self.pairs);
        // Only the members that another body's members may lie beside need looking at:
        // about one in sixteen of the cholecystectomy's. A column with one body round it
        // (not one of the bodies from 15 on, which share a bit) holds none of them.
        let one_body = |seen: u16| seen.count_ones() < 2 && seen & body_bit(15) == 0;
        for col in 0..columns as u32 {
            if one_body(grid.around[col as usize]) {
                continue;
            }
            let (x, y) = (col / dims.y, col % dims.y);
            let listed = grid.start[col as usize] as usize..grid.start[col as usize + 1] as usize;
            for &(z, k) in &grid.cells[listed] {
                if !grid.other_body_round(col, grid.body_of[k as usize]) {
                    continue;
                }
                for (cx, cy) in neighbourhood(x, y, dims) {
                    // Only members after `k` make a pair with it (members are sorted by
                    // particle), each pair found once.
                    for m in grid.near(cx * dims.y + cy, z).filter(|&m| m > k) {
                        found.extend(pair(self, body, k as usize, m as usize, r2));
                    }
                }
            }
        }
        found.sort_unstable();
        self.pairs = found;
        self.grid = grid;
    }

    /// The fallback for a sparse box: members sorted along x, pairs within `reach` in x.
    fn search_sorted(&mut self, body: &[u16], reach: f32) {
        let mut order: Vec<u32> = (0..self.members.len() as u32)
            .filter(|&k| self.at_search[k as usize].is_finite())
            .collect();
        order.sort_by(|&a, &b| {
            self.at_search[a as usize]
                .x
                .total_cmp(&self.at_search[b as usize].x)
                .then(a.cmp(&b))
        });
        let r2 = reach * reach;
        let mut found = Vec::new();
        for (n, &a) in order.iter().enumerate() {
            let xa = self.at_search[a as usize].x;
            for &b in &order[n + 1..] {
                if self.at_search[b as usize].x - xa > reach {
                    break;
                }
                found.extend(pair(self, body, a as usize, b as usize, r2));
                found.extend(pair(self, body, b as usize, a as usize, r2));
            }
        }
        found.sort_unstable();
        found.dedup();
        self.pairs = found;
    }

    /// Pushes apart every candidate pair closer than two radii, each by its inverse masses,
    /// colour by colour.
    pub fn project(&mut self, p: &mut Particles) {
        let d0 = 2.0 * self.radius_m;
        let mut touching = 0;
        for &k in &self.order {
            let (i, j) = self.pairs[k as usize];
            let (i, j) = (i as usize, j as usize);
            let (wi, wj) = (p.w[i], p.w[j]);
            let ws = wi + wj;
            if ws <= 0.0 {
                continue;
            }
            let d = p.x[i] - p.x[j];
            let len = d.length();
            if len >= d0 || len <= 1e-12 {
                continue;
            }
            touching += 1;
            let push = d * ((d0 - len) / (len * ws));
            p.x[i] += push * wi;
            p.x[j] -= push * wj;
        }
        self.touching = touching;
    }

    /// The pairs closer than two radii where the particles are now (after a device's
    /// substep, whose projection counted none on the CPU).
    pub fn count_touching(&mut self, p: &Particles) {
        let d0 = 2.0 * self.radius_m;
        self.touching = self
            .pairs
            .iter()
            .filter(|&&(i, j)| {
                let (wi, wj) = (p.w[i as usize], p.w[j as usize]);
                let len = p.x[i as usize].distance(p.x[j as usize]);
                wi + wj > 0.0 && len < d0 && len > 1e-12
            })
            .count();
    }

    pub fn heap_bytes(&self) -> usize {
        self.members.len() * 4
            + self.at_search.len() * 12
            + (self.pairs.len() + self.ignore.len()) * 8
            + self.grid.heap_bytes()
    }
}

/// Members `k` and `m` (positions in `members`) as a pair, once (`i < j`), if they belong to
/// different bodies and lay within the reach at the search.
fn pair(c: &BodyContacts, body: &[u16], k: usize, m: usize, r2: f32) -> Option<(u32, u32)> {
    let (i, j) = (c.members[k], c.members[m]);
    let same = i >= j || body[i as usize] == body[j as usize];
    if same || c.at_search[k].distance_squared(c.at_search[m]) > r2 {
        return None;
    }
    c.ignore.binary_search(&(i, j)).is_err().then_some((i, j))
}

/// How much further than its reach an instrument looks for particles when it lists those it
/// may push in a substep, m. A particle must move this far within the substep's sweeps to be
/// missed by them (four metres a second at 0.5 ms substeps); it is then found at the next.
pub const PUSH_LIST_MARGIN_M: f32 = 0.002;

/// An instrument's generalized cylinders against every particle (culled by blocks of
/// consecutive particles), grown by the particles' radius. The particles within
/// [`PUSH_LIST_MARGIN_M`] of the grown instrument are listed at a substep's first sweep; the
/// later sweeps test only them.
#[derive(Debug, Clone)]
pub struct ToolPush {
    radius_m: f32,
    blocks: PointBlocks,
    contacts: Vec<ToolContact>,
    /// The particles the instrument may push this substep, and whether they are listed yet.
    near: Vec<u32>,
    listed: bool,
    /// What the particles were pushed by this step, summed as forces on them, N.
    pushed_n: Vec3,
}

impl ToolPush {
    pub fn new(p: &Particles, radius_m: f32) -> ToolPush {
        ToolPush {
            radius_m: radius_m.max(0.0),
            blocks: PointBlocks::new(PointCloud::from_points(&p.x)),
            contacts: Vec::new(),
            near: Vec::new(),
            listed: false,
            pushed_n: Vec3::ZERO,
        }
    }

    /// The particles' radius the instrument is grown by, m.
    pub fn radius_m(&self) -> f32 {
        self.radius_m
    }

    /// Starts a step (the reaction's sum back to zero, the particles near the instrument to be
    /// listed again).
    pub fn begin_step(&mut self) {
        self.pushed_n = Vec3::ZERO;
        self.listed = false;
    }

    /// Moves every free particle inside `tool` (grown by the particle radius) out along the
    /// test's direction by its depth. Returns the particles touched.
    pub fn project(&mut self, tool: &Instrument, p: &mut Particles, dt_s: f32) -> usize {
        if !self.listed {
            self.blocks.refresh(PointCloud::from_points(&p.x));
            let wide = tool.inflated(self.radius_m + PUSH_LIST_MARGIN_M);
            if wide
                .contacts(
                    PointCloud::from_points(&p.x),
                    &self.blocks,
                    &mut self.contacts,
                )
                .is_err()
            {
                return 0;
            }
            self.near.clear();
            self.near.extend(self.contacts.iter().map(|c| c.vertex));
            self.listed = true;
        }
        let grown = tool.inflated(self.radius_m);
        grown.contacts_among(&p.x, &self.near, &mut self.contacts);
        let inv_dt2 = 1.0 / (dt_s * dt_s);
        let mut n = 0;
        for c in &self.contacts {
            let i = c.vertex as usize;
            if p.w[i] <= 0.0 {
                continue;
            }
            let dx = c.dir * c.depth_m;
            p.x[i] += dx;
            self.pushed_n += dx * (inv_dt2 / p.w[i]);
            n += 1;
        }
        n
    }

    /// The tissue's force on the instrument this step, N (minus what it did to the
    /// particles).
    pub fn reaction_n(&self) -> Vec3 {
        -self.pushed_n
    }
}

/// A closed grasper: the particles within reach of its jaw when it closed, each held by an
/// XPBD spring to where it sat in the jaw's frame.
#[derive(Debug, Clone, Default)]
pub struct Grasp {
    /// Held particles and their offsets from the jaw when taken, m.
    held: Vec<(u32, Vec3)>,
    lambda: Vec<Vec3>,
    stiffness_n_per_m: f32,
}

impl Grasp {
    /// Takes hold of the free particles within `reach_m` of `jaw` (at most `most`, the
    /// nearest, ties to the lower index), each by a spring of `stiffness_n_per_m`. Returns
    /// how many.
    pub fn take(
        p: &Particles,
        jaw: Vec3,
        reach_m: f32,
        most: usize,
        stiffness_n_per_m: f32,
    ) -> Grasp {
        let mut near: Vec<(f32, u32)> =
            p.x.iter()
                .enumerate()
                .filter(|(i, _)| p.w[*i] > 0.0)
                .map(|(i, x)| (x.distance(jaw), i as u32))
                .filter(|(d, _)| *d <= reach_m)
                .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        near.truncate(most);
        let held: Vec<(u32, Vec3)> = near
            .iter()
            .map(|&(_, i)| (i, p.x[i as usize] - jaw))
            .collect();
        Grasp {
            lambda: vec![Vec3::ZERO; held.len()],
            held,
            stiffness_n_per_m: stiffness_n_per_m.max(0.0),
        }
    }

    pub fn len(&self) -> usize {
        self.held.len()
    }

    pub fn is_empty(&self) -> bool {
        self.held.is_empty()
    }

    /// The held particles and their offsets from the jaw, m.
    pub fn held(&self) -> &[(u32, Vec3)] {
        &self.held
    }

    /// The springs' stiffness, N/m.
    pub fn stiffness_n_per_m(&self) -> f32 {
        self.stiffness_n_per_m
    }

    /// The held particles.
    pub fn particles(&self) -> impl Iterator<Item = u32> + '_ {
        self.held.iter().map(|h| h.0)
    }

    pub fn begin_step(&mut self) {
        self.lambda.fill(Vec3::ZERO);
    }

    /// Pulls each held particle towards its place by the jaw now at `jaw`.
    pub fn project(&mut self, p: &mut Particles, jaw: Vec3, dt_s: f32) {
        if self.stiffness_n_per_m <= 0.0 {
            return;
        }
        let alpha = 1.0 / (self.stiffness_n_per_m * dt_s * dt_s);
        for ((i, off), l) in self.held.iter().zip(&mut self.lambda) {
            let i = *i as usize;
            let w = p.w[i];
            if w <= 0.0 {
                continue;
            }
            let c = p.x[i] - (jaw + *off);
            let dl = (-c - alpha * *l) / (w + alpha);
            *l += dl;
            p.x[i] += dl * w;
        }
    }

    /// The tissue's force on the grasper this step, N: the springs' multipliers over `dt^2`
    /// (the springs pull the particles by `lambda / dt^2`; the grasper feels the opposite).
    pub fn reaction_n(&self, dt_s: f32) -> Vec3 {
        -self.lambda.iter().copied().sum::<Vec3>() / (dt_s * dt_s)
    }
}

#[cfg(test)]
#[path = "contacts_tests.rs"]
mod tests;
