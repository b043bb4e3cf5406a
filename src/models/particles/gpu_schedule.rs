//! A sweep's constraints in one dispatch (`gpu.rs`, `project_scheduled_*` in
//! `shaders/particles.wgsl`): the constraints of a sweep, in the order the CPU projects them
//! (set by set, colour by colour), put into levels, each as early as the constraints before it
//! that share a particle with it allow. One workgroup runs the levels in turn with a storage
//! barrier between them.
//!
//! Two constraints that share no particle (nor a multiplier, nor work space: each has its own)
//! give the same bytes in either order, and every pair that shares one keeps its order, so the
//! levels give the bytes of the colour-by-colour sweep, in as many barriers as the longest
//! chain of constraints that follow one another through shared particles instead of a
//! dispatch for each colour of each set (tested against it).

use super::gpu_sets::{ChainSet, Constraints};

/// What a scheduled constraint is (the shader's `KIND_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A stretch constraint (a tie or a cloth edge).
    Stretch = 0,
    /// A cloth hinge.
    Bend = 1,
    /// A chain (a vessel or a strand), solved a run at a time.
    Chain = 2,
    /// A contact pair.
    Contact = 3,
}

/// One constraint in a schedule, as the shader's two `vec4<u32>`: its kind, the bits of its
/// compliance (a contact's: the distance it keeps), its multiplier, the bits of a stretch's or
/// hinge's rest length or angle (a chain: its index); then the particles it moves (a stretch
/// and a contact two, a hinge four; a chain's are in its segments).
pub type Item = [u32; 8];

/// Makes a scheduled constraint.
pub fn item(kind: Kind, compliance: f32, lambda: u32, extra: u32, particles: [u32; 4]) -> Item {
    let [a, b, c, d] = particles;
    [kind as u32, compliance.to_bits(), lambda, extra, a, b, c, d]
}

/// Constraints in levels: the items level by level (`items[starts[l]..starts[l + 1]]` is
/// level `l`), each level in the order the items were given.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Schedule {
    pub items: Vec<Item>,
    pub starts: Vec<u32>,
}

/// Builds a [`Schedule`] one constraint at a time, in projection order.
#[derive(Debug, Default)]
pub struct Scheduler {
    /// Per particle, one past the latest level that touches it (0: none yet).
    after: Vec<u32>,
    /// Each item and its level.
    placed: Vec<(u32, Item)>,
    levels: u32,
}

impl Scheduler {
    /// A scheduler for a world of `particles` particles.
    pub fn new(particles: usize) -> Scheduler {
        Scheduler {
            after: vec![0; particles],
            placed: Vec::new(),
            levels: 0,
        }
    }

    /// Adds `item`, which reads and writes the particles `touches` (repeats allowed), after
    /// every item added before it that touches one of them. A particle outside the world is
    /// ignored here (the device never reads it either: the CPU's checks refuse such
    /// constraints first).
    pub fn push(&mut self, item: Item, touches: impl IntoIterator<Item = u32> + Clone) {
        let level = touches
            .clone()
            .into_iter()
            .filter_map(|p| self.after.get(p as usize))
            .copied()
            .max()
            .unwrap_or(0);
        for p in touches {
            if let Some(a) = self.after.get_mut(p as usize) {
                *a = level + 1;
            }
        }
        self.levels = self.levels.max(level + 1);
        self.placed.push((level, item));
    }

    /// The schedule: items grouped by level, each level in the order the items came.
    pub fn finish(self) -> Schedule {
        let levels = self.levels as usize;
        let mut counts = vec![0u32; levels + 1];
        for (l, _) in &self.placed {
            counts[*l as usize + 1] += 1;
        }
        for l in 0..levels {
            counts[l + 1] += counts[l];
        }
        let starts = counts.clone();
        let mut next = counts;
        let mut items = vec![[0u32; 8]; self.placed.len()];
        for (l, it) in self.placed {
            let at = &mut next[l as usize];
            items[*at as usize] = it;
            *at += 1;
        }
        Schedule { items, starts }
    }
}

impl Schedule {
    /// Its levels (the barriers one workgroup runs through).
    pub fn levels(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// The buffer the shader reads: a row `(levels, the first item's row, 0, 0)`, the level
    /// starts four a row, then each item in two rows.
    pub fn rows(&self) -> Vec<[u32; 4]> {
        let head = 1 + self.starts.len().div_ceil(4);
        let mut out = vec![[0u32; 4]; head];
        out[0] = [self.levels() as u32, head as u32, 0, 0];
        for (k, &st) in self.starts.iter().enumerate() {
            out[1 + k / 4][k % 4] = st;
        }
        for it in &self.items {
            out.push([it[0], it[1], it[2], it[3]]);
            out.push([it[4], it[5], it[6], it[7]]);
        }
        out
    }

    /// The most items of one level.
    pub fn widest(&self) -> usize {
        self.starts
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }

    /// Whether one workgroup should run it: no level wider than [`MOST_PER_LEVEL`] (a wider
    /// one is better spread over workgroups, a dispatch per colour).
    pub fn fits_one_workgroup(&self) -> bool {
        self.widest() <= MOST_PER_LEVEL
    }
}

/// The sets of a sweep after the clusters in the order the CPU projects them (the vessels, the
/// ties, the cloth's edges, its hinges, the strands, the bonds: each set colour by colour), as
/// `gpu.rs` lays them out: the stretches are the ties then the edges (a stretch's multiplier
/// at its index), the hinges' multipliers after them, the chains numbered across the three
/// chain sets in that order (each holds its multipliers).
pub fn sets(c: &Constraints, particles: usize) -> Schedule {
    let mut s = Scheduler::new(particles);
    let mut chain_at = 0u32;
    let mut chains = |s: &mut Scheduler, set: &ChainSet| {
        for ch in &set.chains {
            let segs = set.segs[ch.segs.start as usize..ch.segs.end as usize]
                .iter()
                .flat_map(|g| [g.c.a, g.c.b]);
            let bends = set.bends[ch.bends.start as usize..ch.bends.end as usize]
                .iter()
                .flat_map(|(b, _)| [b.a, b.b]);
            s.push(
                item(Kind::Chain, 0.0, 0, chain_at, [0; 4]),
                segs.chain(bends),
            );
            chain_at += 1;
        }
    };
    chains(&mut s, &c.vessels);
    // The ties then the edges, a stretch's multiplier at its index among them.
    let stretches = [&c.ties, &c.edges];
    let mut k = 0u32;
    for set in stretches {
        for t in set.items {
            let it = item(
                Kind::Stretch,
                set.compliance,
                k,
                t.rest_m.to_bits(),
                [t.a, t.b, 0, 0],
            );
            s.push(it, [t.a, t.b]);
            k += 1;
        }
    }
    let hinge_base = k;
    for (k, h) in c.hinges.items.iter().enumerate() {
        let k = k as u32;
        let (ids, rest) = ([h.a, h.b, h.c, h.d], h.rest_rad.to_bits());
        s.push(
            item(Kind::Bend, c.hinges.compliance, hinge_base + k, rest, ids),
            ids,
        );
    }
    chains(&mut s, &c.adhesion);
    chains(&mut s, &c.bonds);
    s.finish()
}

/// The contact pairs of a sweep (sorted by colour), pushed apart closer than `distance_m`.
pub fn contacts(pairs: &[(u32, u32)], distance_m: f32, particles: usize) -> Schedule {
    let mut s = Scheduler::new(particles);
    for &(i, j) in pairs {
        s.push(item(Kind::Contact, distance_m, 0, 0, [i, j, 0, 0]), [i, j]);
    }
    s.finish()
}

/// Invocations of the workgroup that runs a schedule (the shader's `SCHEDULE_GROUP`).
pub const SCHEDULE_GROUP: usize = 256;
/// The widest level one workgroup runs: eight rounds of its invocations.
pub const MOST_PER_LEVEL: usize = 8 * SCHEDULE_GROUP;

#[cfg(test)]
mod tests {
    use super::*;

    /// Items touching the given particles, in order; returns each item's level.
    fn levels_of(particles: usize, touches: &[&[u32]]) -> (Schedule, Vec<u32>) {
        let mut s = Scheduler::new(particles);
        for (k, t) in touches.iter().enumerate() {
            s.push(
                item(Kind::Stretch, 0.0, k as u32, 0, [0; 4]),
                t.iter().copied(),
            );
        }
        let sched = s.finish();
        let mut level = vec![0; touches.len()];
        for l in 0..sched.levels() {
            for it in &sched.items[sched.starts[l] as usize..sched.starts[l + 1] as usize] {
                level[it[2] as usize] = l as u32;
            }
        }
        (sched, level)
    }

    #[test]
    fn a_chain_of_springs_takes_two_levels_and_keeps_every_shared_particles_order() {
        // Springs 0-1, 1-2, ..., 8-9 in this order: each shares a particle with the one
        // before it, so each waits for it: 9 levels.
        let springs: Vec<[u32; 2]> = (0..9).map(|i| [i, i + 1]).collect();
        let touches: Vec<&[u32]> = springs.iter().map(|s| &s[..]).collect();
        let (sched, level) = levels_of(10, &touches);
        assert_eq!(sched.levels(), 9);
        assert_eq!(level, (0..9).collect::<Vec<u32>>());
        // Coloured (even springs first, then odd ones), as the CPU sweeps them: two levels.
        let coloured: Vec<&[u32]> = springs
            .iter()
            .step_by(2)
            .chain(springs.iter().skip(1).step_by(2))
            .map(|s| &s[..])
            .collect();
        let (sched, level) = levels_of(10, &coloured);
        assert_eq!(sched.levels(), 2);
        assert_eq!(level, vec![0, 0, 0, 0, 0, 1, 1, 1, 1]);
        assert_eq!(sched.widest(), 5);
    }

    #[test]
    fn no_level_shares_a_particle_and_conflicting_items_keep_their_order() {
        // A pseudo-random mix of two- and four-particle constraints over 40 particles.
        let mut seed = 12345u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) % 40
        };
        let touches: Vec<Vec<u32>> = (0..300)
            .map(|k| {
                (0..if k % 3 == 0 { 4 } else { 2 })
                    .map(|_| next())
                    .collect()
            })
            .collect();
        let refs: Vec<&[u32]> = touches.iter().map(|t| &t[..]).collect();
        let (sched, level) = levels_of(40, &refs);
        assert_eq!(sched.items.len(), 300);
        for l in 0..sched.levels() {
            let mut seen = [false; 40];
            let its = &sched.items[sched.starts[l] as usize..sched.starts[l + 1] as usize];
            assert!(!its.is_empty(), "level {l} is empty");
            for it in its {
                let mut mine = touches[it[2] as usize].clone();
                mine.sort_unstable();
                mine.dedup();
                for p in mine {
                    assert!(!seen[p as usize], "level {l} touches particle {p} twice");
                    seen[p as usize] = true;
                }
            }
            // Each level keeps the order the items came in.
            assert!(its.windows(2).all(|w| w[0][2] < w[1][2]));
        }
        for a in 0..300 {
            for b in a + 1..300 {
                if touches[a].iter().any(|p| touches[b].contains(p)) {
                    assert!(level[a] < level[b], "items {a} and {b} swapped");
                }
            }
        }
        // Each item as early as it can go: right after its latest conflicting predecessor.
        for b in 0..300 {
            let earliest = (0..b)
                .filter(|&a| touches[a].iter().any(|p| touches[b].contains(p)))
                .map(|a| level[a] + 1)
                .max()
                .unwrap_or(0);
            assert_eq!(level[b], earliest, "item {b}");
        }
    }

    #[test]
    fn a_level_too_wide_for_one_workgroup_is_left_to_the_colour_dispatches() {
        // Disjoint springs all land in level 0: one too many for one workgroup.
        let build = |n: u32| {
            let mut s = Scheduler::new(2 * n as usize);
            for k in 0..n {
                s.push(item(Kind::Stretch, 0.0, k, 0, [0; 4]), [2 * k, 2 * k + 1]);
            }
            s.finish()
        };
        let fits = build(MOST_PER_LEVEL as u32);
        assert_eq!((fits.levels(), fits.widest()), (1, MOST_PER_LEVEL));
        assert!(fits.fits_one_workgroup());
        assert!(!build(MOST_PER_LEVEL as u32 + 1).fits_one_workgroup());
    }

    #[test]
    fn the_kinds_and_the_workgroup_are_the_shaders() {
        let shader = crate::models::particles::gpu::SHADER;
        for (name, kind) in [
            ("KIND_STRETCH", Kind::Stretch),
            ("KIND_BEND", Kind::Bend),
            ("KIND_CHAIN", Kind::Chain),
        ] {
            let decl = format!("const {name}: u32 = {}u;", kind as u32);
            assert!(shader.contains(&decl), "the shader lacks `{decl}`");
        }
        let group = format!("const SCHEDULE_GROUP: u32 = {SCHEDULE_GROUP}u;");
        assert!(shader.contains(&group), "the shader lacks `{group}`");
        let size = format!("@workgroup_size({SCHEDULE_GROUP})\nfn project_scheduled(");
        assert!(shader.contains(&size), "the shader lacks `{size}`");
        // The rows the shader reads: a head, the starts four a row, two rows an item.
        let mut s = Scheduler::new(4);
        s.push(item(Kind::Contact, 0.5, 0, 0, [1, 2, 0, 0]), [1, 2]);
        s.push(item(Kind::Contact, 0.5, 0, 0, [2, 3, 0, 0]), [2, 3]);
        let rows = s.finish().rows();
        assert_eq!(rows[0], [2, 2, 0, 0]);
        assert_eq!(rows[1], [0, 1, 2, 0]);
        assert_eq!(rows[2], [3, 0.5f32.to_bits(), 0, 0]);
        assert_eq!(rows[3], [1, 2, 0, 0]);
        assert_eq!(rows.len(), 6);
    }

    #[test]
    fn an_empty_schedule_has_no_level_and_one_start() {
        let s = Scheduler::new(5).finish();
        assert_eq!(s.levels(), 0);
        assert_eq!(s.starts, vec![0]);
        assert!(s.fits_one_workgroup());
    }
}
