//! The constraints after the clusters going up to the device (`gpu.rs`): their buffers and
//! multipliers, and a sweep's dispatches: one per colour of each set, or one for all the sets
//! and one for the contacts where they are scheduled (`gpu_schedule.rs`).

use super::{
    BENDS, CHAINS, CLEAR, CONTACTS, ColourPass, ENTRIES, ParticlesGpu, Range, SCHEDULED, STRETCHES,
    Sweeps, bytes, groups,
};
use crate::gpu::RenderError;
use crate::gpu::compute::{self, bind};
use crate::models::particles::colour;
use crate::models::particles::gpu_schedule;
use crate::models::particles::gpu_sets::{ChainSet, Constraints};
use crate::models::xpbd::Stretch;

impl ParticlesGpu {
    /// Replaces the constraints after the clusters (after a cut or a tear): their buffers,
    /// their multipliers and a dispatch per colour of each set.
    pub fn set_constraints(&mut self, c: &Constraints) -> Result<(), RenderError> {
        let gpu = &self.gpu;
        let stretch_row = |s: &Stretch| [s.a, s.b, s.rest_m.to_bits(), 0];
        let stretches: Vec<[u32; 4]> = c
            .ties
            .items
            .iter()
            .chain(c.edges.items)
            .map(stretch_row)
            .collect();
        let bends: Vec<[u32; 4]> = c
            .hinges
            .items
            .iter()
            .flat_map(|h| [[h.a, h.b, h.c, h.d], [h.rest_rad.to_bits(), 0, 0, 0]])
            .collect();
        // The chain sets side by side: segments, bending springs, and three rows a chain.
        let chain_sets = [&c.vessels, &c.adhesion, &c.bonds];
        let segs_total: usize = chain_sets.iter().map(|k| k.segs.len()).sum();
        let chain_lambdas = stretches.len() + c.hinges.items.len();
        let bend_lambdas = chain_lambdas + segs_total;
        let (mut segs, mut chain_bends, mut info) = (Vec::new(), Vec::new(), Vec::new());
        let mut chain_first = Vec::new();
        for set in chain_sets {
            chain_first.push(info.len() / 3);
            let (s0, b0) = (segs.len() as u32, chain_bends.len() as u32);
            segs.extend(set.segs.iter().map(|g| {
                let flags = u32::from(g.intact) | (u32::from(g.breakable) << 1);
                [g.c.a, g.c.b, g.c.rest_m.to_bits(), flags]
            }));
            chain_bends.extend(
                set.bends
                    .iter()
                    .map(|(b, intact)| [b.a, b.b, b.rest_m.to_bits(), u32::from(*intact)]),
            );
            for ch in &set.chains {
                let (first, bend_first) = (s0 + ch.segs.start, b0 + ch.bends.start);
                info.push([first, s0 + ch.segs.end, bend_first, b0 + ch.bends.end]);
                info.push([
                    ch.compliance.to_bits(),
                    ch.weak_compliance.to_bits(),
                    u32::from(ch.weakened) | (u32::from(ch.whole) << 1),
                    ch.solves,
                ]);
                info.push([
                    ch.bend_compliance.to_bits(),
                    (chain_lambdas as u32) + first,
                    (bend_lambdas as u32) + bend_first,
                    0,
                ]);
            }
        }
        let lambdas = bend_lambdas + chain_bends.len();
        let storage = |label: &str, data: &[u8]| compute::storage(gpu, label, data);
        let lambda = storage("constraint multipliers", &vec![0u8; 4 * lambdas])?;
        let info_buf = storage("chains", bytes(&info))?;
        let segs_buf = storage("chain segments", bytes(&segs))?;
        let chain_bends_buf = storage("chain bending springs", bytes(&chain_bends))?;
        let rows = storage("chain rows", &vec![0u8; 32 * segs_total.max(1)])?;
        let mut passes = Vec::new();
        let scheduled = (self.sweeps == Sweeps::Scheduled)
            .then(|| gpu_schedule::sets(c, self.particles as usize))
            .filter(|s| s.fits_one_workgroup());
        self.levels[0] = scheduled.as_ref().map_or(0, |s| s.levels());
        self.set_buffers = vec![
            (17, lambda.clone()),
            (18, info_buf.clone()),
            (19, segs_buf.clone()),
            (20, chain_bends_buf.clone()),
            (21, rows.clone()),
        ];
        match &scheduled {
            Some(sch) if !sch.items.is_empty() => passes.push(self.scheduled_pass(sch)?),
            Some(_) => {}
            None => {
                // The stretches and bends buffers serve the colour passes alone (the
                // scheduled sweep carries its constraints in its items).
                let stretch_buf = storage("stretch constraints", bytes(&stretches))?;
                let bend_buf = storage("bending constraints", bytes(&bends))?;
                let mut add =
                    |entry: usize, first: usize, base: usize, colours: &[u32], comp: f32| {
                        for (_, a, b) in colour::ranges(colours) {
                            let range = Range {
                                first: (first + a) as u32,
                                end: (first + b) as u32,
                                lambda_base: (base + a) as u32,
                                compliance: comp,
                            };
                            let uniform =
                                compute::uniform(gpu, "constraint colour", bytes(&[range]));
                            let mut buffers = vec![(0, &self.params), (1, &self.x), (14, &uniform)];
                            match entry {
                                STRETCHES => buffers.push((15, &stretch_buf)),
                                BENDS => buffers.push((16, &bend_buf)),
                                _ => buffers.extend([
                                    (18, &info_buf),
                                    (19, &segs_buf),
                                    (20, &chain_bends_buf),
                                    (21, &rows),
                                ]),
                            }
                            buffers.push((17, &lambda));
                            passes.push(ColourPass {
                                entry,
                                bind: bind(gpu, &self.pipelines[entry], ENTRIES[entry], &buffers),
                                groups: groups((b - a) as u32),
                            });
                        }
                    };
                let chain_colours =
                    |set: &ChainSet| set.chains.iter().map(|k| k.colour).collect::<Vec<_>>();
                let ties = c.ties.items.len();
                add(CHAINS, chain_first[0], 0, &chain_colours(&c.vessels), 0.0);
                add(STRETCHES, 0, 0, c.ties.colours, c.ties.compliance);
                add(STRETCHES, ties, ties, c.edges.colours, c.edges.compliance);
                let hinge_base = stretches.len();
                add(BENDS, 0, hinge_base, c.hinges.colours, c.hinges.compliance);
                add(CHAINS, chain_first[1], 0, &chain_colours(&c.adhesion), 0.0);
                add(CHAINS, chain_first[2], 0, &chain_colours(&c.bonds), 0.0);
            }
        }
        self.binds[CLEAR] = Some(bind(
            gpu,
            &self.pipelines[CLEAR],
            ENTRIES[CLEAR],
            &[(0, &self.params), (17, &lambda)],
        ));
        self.passes = passes;
        self.lambdas = lambdas as u32;
        self.counts = [
            stretches.len(),
            c.hinges.items.len(),
            segs_total,
            chain_bends.len(),
            0,
        ]
        .map(|n| n as u64);
        gpu.check()?;
        self.set_pairs(&c.pairs, c.pair_colours, c.contact_distance_m)
    }

    /// Replaces the contacts' candidate pairs (sorted by colour, `colours` theirs) alone,
    /// after a search: their buffer and a dispatch per colour, pushed apart closer than
    /// `distance_m`. The other sets' buffers stay as they are.
    pub fn set_pairs(
        &mut self,
        pairs: &[(u32, u32)],
        colours: &[u32],
        distance_m: f32,
    ) -> Result<(), RenderError> {
        let gpu = &self.gpu;
        let rows: Vec<[u32; 2]> = pairs.iter().map(|&(i, j)| [i, j]).collect();
        let scheduled = (self.sweeps == Sweeps::Scheduled)
            .then(|| gpu_schedule::contacts(pairs, distance_m, self.particles as usize))
            .filter(|s| s.fits_one_workgroup());
        self.levels[1] = scheduled.as_ref().map_or(0, |s| s.levels());
        self.counts[4] = pairs.len() as u64;
        if let Some(sch) = scheduled {
            self.contact_passes.clear();
            if !sch.items.is_empty() {
                let pass = self.scheduled_pass(&sch)?;
                self.contact_passes.push(pass);
            }
            return self.gpu.check();
        }
        let pairs_buf = compute::storage(gpu, "contact pairs", bytes(&rows))?;
        self.contact_passes = colour::ranges(colours)
            .into_iter()
            .map(|(_, a, b)| {
                let range = Range {
                    first: a as u32,
                    end: b as u32,
                    lambda_base: 0,
                    compliance: distance_m,
                };
                let uniform = compute::uniform(gpu, "contact colour", bytes(&[range]));
                // The contacts' kernel reads no substep parameters and no multipliers.
                let buffers = [(1, &self.x), (14, &uniform), (22, &pairs_buf)];
                ColourPass {
                    entry: CONTACTS,
                    bind: bind(gpu, &self.pipelines[CONTACTS], ENTRIES[CONTACTS], &buffers),
                    groups: groups((b - a) as u32),
                }
            })
            .collect();
        gpu.check()
    }

    /// One workgroup running `schedule` (the sets' or the contacts') level by level.
    fn scheduled_pass(&self, schedule: &gpu_schedule::Schedule) -> Result<ColourPass, RenderError> {
        let rows = compute::storage(&self.gpu, "scheduled constraints", bytes(&schedule.rows()))?;
        let mut buffers = vec![(0, &self.params), (1, &self.x), (29, &rows)];
        buffers.extend(self.set_buffers.iter().map(|(k, b)| (*k, b)));
        Ok(ColourPass {
            entry: SCHEDULED,
            bind: bind(
                &self.gpu,
                &self.pipelines[SCHEDULED],
                ENTRIES[SCHEDULED],
                &buffers,
            ),
            groups: (1, 1),
        })
    }
}
