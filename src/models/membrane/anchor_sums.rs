//! Layer 0's loads summed by group, every step: what a model holding layer 0 takes from the
//! membrane without reading a node of it. The holder names its groups (the rectum's rod: one
//! per element of the rod, each node bound to an element at a place `u` along it) and reads,
//! after each step, five sums per group over the awake nodes: the loads, the loads weighted by
//! `u`, their moment about the group's point, the nodes' anchor stiffness, and that weighted
//! by `u`. From these the holder splits the loads onto its element's ends with the couple
//! they make about its axis, exactly as it would node by node (linear in the loads).
//!
//! The sums are taken at the start of the membrane's step, from the state it steps from, the
//! targets just set and the external forces of the step: the loads [`Membrane::anchor_loads`]
//! would give at that moment. On the CPU they are summed in f64 in tile order; on a device by
//! one workgroup a group in a fixed tree order (`anchor_sums` in `shaders/membrane.wgsl`), so
//! the bytes depend on the backend, not on the thread count or the run.

use super::{Membrane, MembraneError};
use glam::{DVec3, Vec3};

/// One group's sums over its awake layer-0 nodes, at the start of the last step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AnchorSum {
    /// The loads, N.
    pub force: DVec3,
    /// The loads, each times its node's weight `u`, N.
    pub weighted_force: DVec3,
    /// The loads' moment about the group's point: sum of `(target - point) x f`, N m (each
    /// load acts where its node's attachment holds it).
    pub moment: DVec3,
    /// The nodes' anchor stiffness ([`Membrane::anchor_stiffness`]), N/m.
    pub stiffness: f64,
    /// The anchor stiffness, each times its node's weight, N/m.
    pub weighted_stiffness: f64,
}

impl AnchorSum {
    /// Whether every sum is finite.
    pub fn is_finite(&self) -> bool {
        self.force.is_finite()
            && self.weighted_force.is_finite()
            && self.moment.is_finite()
            && self.stiffness.is_finite()
            && self.weighted_stiffness.is_finite()
    }
}

/// A member of a group.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Member {
    /// Layer 0's node, `row * cols + column`.
    pub cell: u32,
    /// Its weight in the group, in [0, 1].
    pub u: f32,
    /// Its anchor stiffness, N/m (cuts take links 1-2 only, so it never changes).
    pub k: f32,
    pub group: u32,
}

/// The groups of layer-0 nodes whose loads are summed.
#[derive(Debug, Clone)]
pub(super) struct AnchorGroups {
    /// Per layer-0 node (`row * cols + column`): its place in `members`, or [`NONE`].
    pub of_cell: Vec<u32>,
    /// The members, group by group, each group's by node.
    pub members: Vec<Member>,
    /// Each group's first member, and one past the last group's last.
    pub starts: Vec<u32>,
    /// Each group's point (the moments are taken about it), m.
    pub about: Vec<Vec3>,
}

/// No group.
const NONE: u32 = u32::MAX;

impl AnchorGroups {
    pub fn heap_bytes(&self) -> usize {
        self.of_cell.capacity() * 4
            + self.members.capacity() * std::mem::size_of::<Member>()
            + self.starts.capacity() * 4
            + self.about.capacity() * std::mem::size_of::<Vec3>()
    }
}

impl Membrane {
    /// Sums layer 0's loads by group at every step from now on: `members` are `(row,
    /// column, group, u)`, each layer-0 node in one group at most with a weight `u` in [0, 1];
    /// `about` holds each group's point, m. An error names the first bad member and what is
    /// wrong with it; the membrane is then left as it was.
    pub fn group_anchor_loads(
        &mut self,
        members: &[(usize, usize, usize, f32)],
        about: &[Vec3],
    ) -> Result<(), MembraneError> {
        let (rows, cols) = (self.rows, self.cols);
        let bad = |member: usize, why: String| Err(MembraneError::BadGroup { member, why });
        if let Some(g) = about.iter().position(|p| !p.is_finite()) {
            return bad(0, format!("group {g}'s point {} is not finite", about[g]));
        }
        let mut of_cell = vec![NONE; rows * cols];
        let mut list = Vec::with_capacity(members.len());
        for (n, &(i, j, g, u)) in members.iter().enumerate() {
            if i >= rows || j >= cols {
                return bad(n, format!("node ({i}, {j}) lies outside {rows} x {cols}"));
            }
            if g >= about.len() {
                return bad(
                    n,
                    format!("group {g} has no point (there are {})", about.len()),
                );
            }
            if !(0.0..=1.0).contains(&u) {
                return bad(n, format!("weight {u} is not in [0, 1]"));
            }
            let cell = i * cols + j;
            if of_cell[cell] != NONE {
                return bad(n, format!("node ({i}, {j}) is in a group already"));
            }
            of_cell[cell] = 0;
            list.push(Member {
                cell: cell as u32,
                u,
                k: self.anchor_stiffness(i, j),
                group: g as u32,
            });
        }
        list.sort_by_key(|m| (m.group, m.cell));
        let mut starts = vec![0u32; about.len() + 1];
        for m in &list {
            starts[m.group as usize + 1] += 1;
        }
        for g in 0..about.len() {
            starts[g + 1] += starts[g];
        }
        for (k, m) in list.iter().enumerate() {
            of_cell[m.cell as usize] = k as u32;
        }
        self.anchor_groups = Some(Box::new(AnchorGroups {
            of_cell,
            members: list,
            starts,
            about: about.to_vec(),
        }));
        self.anchor_sums = vec![AnchorSum::default(); about.len()];
        self.device.groups_changed();
        Ok(())
    }

    /// Each group's sums at the start of the last step (all zero before the first, and
    /// none without groups).
    pub fn anchor_sums(&self) -> &[AnchorSum] {
        &self.anchor_sums
    }
}

/// The sums over the layer-0 nodes of `runs` (rows, columns: the awake tiles, side by side
/// in a row of tiles as one run) on the CPU, into `m.anchor_sums`; nothing without groups.
/// The external forces must be sorted by node.
pub(super) fn on_cpu(m: &mut Membrane, runs: &[([usize; 2], [usize; 2])]) {
    if m.anchor_groups.is_none() {
        return;
    }
    let mut loads = std::mem::take(&mut m.load_scratch);
    m.loads_over_runs(runs, &mut loads);
    from_loads(m, &loads);
    m.load_scratch = loads;
}

/// Whether the membrane sums layer 0's loads by group.
pub(super) fn wanted(m: &Membrane) -> bool {
    m.anchor_groups.is_some()
}

/// The sums of `loads` (row, column, load: [`Membrane::loads_over_runs`]'s, in its order)
/// into `m.anchor_sums`; nothing without groups.
pub(super) fn from_loads(m: &mut Membrane, loads: &[(u32, u32, Vec3)]) {
    let Some(groups) = m.anchor_groups.take() else {
        return;
    };
    let cols = m.cols;
    let mut sums = vec![AnchorSum::default(); groups.about.len()];
    for &(i, j, f) in loads {
        let (i, j) = (i as usize, j as usize);
        let Some(member) = groups.members.get(groups.of_cell[i * cols + j] as usize) else {
            continue;
        };
        if !f.is_finite() {
            continue;
        }
        let g = member.group as usize;
        let (Some(s), Some(about)) = (sums.get_mut(g), groups.about.get(g)) else {
            continue;
        };
        let target = Vec3::from_array(std::array::from_fn(|c| {
            m.attach[(i * 4 + 1 + c) * cols + j]
        }));
        let (f, u, k) = (f.as_dvec3(), f64::from(member.u), f64::from(member.k));
        s.force += f;
        s.weighted_force += u * f;
        s.moment += (target.as_dvec3() - about.as_dvec3()).cross(f);
        s.stiffness += k;
        s.weighted_stiffness += u * k;
    }
    m.anchor_sums = sums;
    m.anchor_groups = Some(groups);
}

/// Every group's sums zero (no node awake).
pub(super) fn none_awake(m: &mut Membrane) {
    m.anchor_sums.fill(AnchorSum::default());
}
