//! What the particle solver's kernels take up (`gpu.rs`): each constraint set sorted by
//! colour, the chains solved a run at a time, and everything a sweep projects after the
//! clusters.

use crate::models::xpbd::{Bend, Stretch};

/// One constraint set sorted by colour (`colour.rs`): its constraints, their colours, and
/// its compliance.
#[derive(Debug, Clone, Copy)]
pub struct Set<'a, T> {
    pub items: &'a [T],
    pub colours: &'a [u32],
    pub compliance: f32,
}

impl<T> Set<'_, T> {
    pub fn empty() -> Self {
        Set {
            items: &[],
            colours: &[],
            compliance: 0.0,
        }
    }
}

/// A chain's segment as a device takes it.
#[derive(Debug, Clone, Copy)]
pub struct ChainSegment {
    pub c: Stretch,
    pub intact: bool,
    /// Weakened with its strand (a strand's breakable segments).
    pub breakable: bool,
}

/// One chain solved a run of intact segments at a time (`chain::solve_chain`).
#[derive(Debug, Clone)]
pub struct DeviceChain {
    /// Its segments and bending springs in its set's lists.
    pub segs: std::ops::Range<u32>,
    pub bends: std::ops::Range<u32>,
    /// A segment's compliance, and a breakable one's once `weakened`, m/N.
    pub compliance: f32,
    pub weak_compliance: f32,
    pub weakened: bool,
    /// A whole strand, solved at its equilibrium (`adhesion.rs`, `Whole`) instead of as a
    /// chain of particles.
    pub whole: bool,
    /// Solves of each run a sweep.
    pub solves: u32,
    /// The bending springs' compliance, m/N.
    pub bend_compliance: f32,
    /// Chains of one colour share no particle (`colour.rs`).
    pub colour: u32,
}

/// Chains in projection order (sorted by colour): the vessels (`chain.rs`) or a set of
/// strands (`adhesion.rs`).
#[derive(Debug, Clone, Default)]
pub struct ChainSet {
    pub chains: Vec<DeviceChain>,
    pub segs: Vec<ChainSegment>,
    /// Bending springs (skip-one stretch springs) and whether each is intact.
    pub bends: Vec<(Stretch, bool)>,
}

/// Everything a sweep projects after the clusters, in this order: the vessels, the ties, the
/// cloth's edges, its hinges, the two strand sets, the contacts between bodies (their
/// candidate pairs by colour, pushed apart closer than `contact_distance_m`).
#[derive(Debug, Clone)]
pub struct Constraints<'a> {
    pub vessels: ChainSet,
    pub ties: Set<'a, Stretch>,
    pub edges: Set<'a, Stretch>,
    pub hinges: Set<'a, Bend>,
    pub adhesion: ChainSet,
    pub bonds: ChainSet,
    pub pairs: Vec<(u32, u32)>,
    pub pair_colours: &'a [u32],
    pub contact_distance_m: f32,
}

impl Constraints<'_> {
    pub fn none() -> Self {
        Constraints {
            vessels: ChainSet::default(),
            ties: Set::empty(),
            edges: Set::empty(),
            hinges: Set::empty(),
            adhesion: ChainSet::default(),
            bonds: ChainSet::default(),
            pairs: Vec::new(),
            pair_colours: &[],
            contact_distance_m: 0.0,
        }
    }
}
