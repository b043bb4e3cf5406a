//! The particle solver's GPU path against its CPU path, on the adapter there is (lavapipe in
//! CI).

use super::*;
use crate::models::particles::shape::{ShapeMatching, frequency_for, lattice_clusters};
use glam::Quat;

const DT: f32 = 1e-3;

fn gpu() -> Gpu {
    Gpu::headless(false).expect("a Vulkan adapter (lavapipe in CI)")
}

/// A small block of liver-like particles (6 x 8 x 6, 3.5 mm apart) in clusters, its top layer
/// pinned unless `free`.
fn block(free: bool) -> (Particles, ShapeMatching) {
    let h = 0.0035f32;
    let rho = 1060.0;
    let mut p = Particles::new();
    for a in 0..6 {
        for b in 0..8 {
            for c in 0..6 {
                p.add(
                    Vec3::new(a as f32, -(b as f32), c as f32) * h,
                    rho * h * h * h,
                    0,
                );
            }
        }
    }
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let r = 2.5 * h;
    let specs = lattice_clusters(&p.x, &all, h, 3, r, frequency_for(5000.0, rho, r));
    let s = ShapeMatching::new(&p, specs).expect("clusters");
    if !free {
        for i in 0..p.len() {
            if p.x[i].y == 0.0 {
                p.pin(i);
            }
        }
    }
    (p, s)
}

fn stepping(floor: Option<f32>) -> Stepping {
    Stepping {
        dt_s: DT,
        substeps: 2,
        iterations: 2,
        gravity_m_per_s2: Vec3::new(0.0, -9.81, 0.0),
        damping_per_s: 5.0,
        floor_y_m: floor,
    }
}

/// The CPU's steps of `how` (as the solver takes them: substeps of sweeps, the floor after
/// each sweep).
fn cpu_steps(p: &mut Particles, s: &mut ShapeMatching, how: &Stepping, steps: usize) {
    let dt = how.dt_s / how.substeps as f32;
    for _ in 0..steps * how.substeps as usize {
        p.predict(dt, how.gravity_m_per_s2);
        s.begin_step();
        for _ in 0..how.iterations {
            s.project(p, dt);
            if let Some(y) = how.floor_y_m {
                for (x, w) in p.x.iter_mut().zip(&p.w) {
                    if *w > 0.0 && x.y < y {
                        x.y = y;
                    }
                }
            }
        }
        p.finish(dt, how.damping_per_s);
    }
}

fn largest_gap(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max)
}

/// The farthest a particle whose bits are in `bits` lies from its place in `start`, m.
fn largest_move(bits: &[[u32; 3]], start: &[Vec3]) -> f32 {
    let x: Vec<Vec3> = bits
        .iter()
        .map(|b| Vec3::from_array(b.map(f32::from_bits)))
        .collect();
    largest_gap(&x, start)
}

#[test]
fn a_sagging_block_on_the_gpu_follows_the_cpu() {
    let gpu = gpu();
    let how = stepping(None);
    let (mut cpu, mut s_cpu) = block(false);
    let start = cpu.x.clone();
    let (mut dev, s_dev) = block(false);
    let mut k = ParticlesGpu::new(&gpu, &dev, &s_dev, &Constraints::none())
        .expect("the device takes the block");
    cpu_steps(&mut cpu, &mut s_cpu, &how, 300);
    k.advance(&mut dev, &how, 150).expect("steps");
    k.advance(&mut dev, &how, 150).expect("steps");
    k.download(&mut dev).expect("read back");
    let sag = largest_gap(&cpu.x, &start);
    let gap = largest_gap(&cpu.x, &dev.x);
    // The block sags by about 0.1 mm; the two paths round differently (the device may fuse
    // multiply-adds) but run the same algorithm: within 1 % of the sag.
    assert!(sag > 2e-5, "the block sagged {sag} m");
    assert!(gap < 0.01 * sag, "GPU vs CPU: {gap} m apart, sag {sag} m");
    let vgap = largest_gap(&cpu.v, &dev.v);
    let vmax = cpu.v.iter().map(|v| v.length()).fold(0.0, f32::max);
    assert!(vgap <= 0.01 * vmax + 1e-6, "velocities {vgap} m/s apart");
}

#[test]
fn a_turned_body_finds_its_rotation_on_the_gpu_from_a_cold_start() {
    // The free block turned by 70 degrees about a slanted axis: each cluster's first
    // projection looks for that turn (30 iterations from the identity), and the GPU must find
    // what the CPU finds (within f32's resolution of an angle between quaternions, 7e-4 rad).
    // Most clusters find the turn exactly; a few small corner clusters stop short (here 0.17
    // rad at most), as on the CPU, and the next steps' warm starts finish it.
    let gpu = gpu();
    let (mut p, mut s_cpu) = block(true);
    let (_, s_dev0) = block(true);
    let turn = Quat::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 70f32.to_radians());
    let centre = p.x.iter().copied().sum::<Vec3>() / p.len() as f32;
    for x in &mut p.x {
        *x = centre + turn * (*x - centre);
    }
    let mut dev = p.clone();
    let how = Stepping {
        substeps: 1,
        iterations: 1,
        gravity_m_per_s2: Vec3::ZERO,
        damping_per_s: 0.0,
        ..stepping(None)
    };
    cpu_steps(&mut p, &mut s_cpu, &how, 1);
    let mut s_dev = s_dev0;
    let mut k = ParticlesGpu::new(&gpu, &dev, &s_dev, &Constraints::none())
        .expect("the device takes the block");
    k.advance(&mut dev, &how, 1).expect("a step");
    k.download_all(&mut dev, &mut s_dev).expect("read back");
    let mut off_turn = Vec::new();
    for c in 0..s_cpu.clusters() {
        let (a, b) = (s_cpu.rotation(c), s_dev.rotation(c));
        assert!(
            a.angle_between(b) < 2e-3,
            "cluster {c}: GPU and CPU rotations {} rad apart",
            a.angle_between(b)
        );
        off_turn.push(a.angle_between(turn));
        let g = s_dev.goal(c, 0);
        assert!(
            g.distance(s_cpu.goal(c, 0)) < 1e-6,
            "cluster {c}'s first goal"
        );
    }
    off_turn.sort_by(f32::total_cmp);
    let median = off_turn[off_turn.len() / 2];
    assert!(
        median < 2e-3,
        "the clusters' median is {median} rad off the turn"
    );
    // A rigid turn is a rest shape: nobody moves.
    assert!(largest_gap(&p.x, &dev.x) < 1e-6);
}

#[test]
fn the_floor_holds_on_both_paths() {
    let gpu = gpu();
    let (mut cpu, mut s_cpu) = block(true);
    let floor = -0.03;
    let how = stepping(Some(floor));
    let mut dev = cpu.clone();
    let mut k = ParticlesGpu::new(&gpu, &dev, &s_cpu.clone(), &Constraints::none())
        .expect("the device takes it");
    // 0.2 s: the free block falls 2.45 cm and its bottom (2.45 cm down) lands on the floor.
    cpu_steps(&mut cpu, &mut s_cpu, &how, 200);
    k.advance(&mut dev, &how, 200).expect("steps");
    k.download(&mut dev).expect("read back");
    let lowest = |p: &Particles| p.x.iter().map(|x| x.y).fold(f32::MAX, f32::min);
    assert!(lowest(&cpu) >= floor && lowest(&dev) >= floor);
    let on_floor = |p: &Particles| p.x.iter().filter(|x| x.y == floor).count();
    assert!(on_floor(&cpu) > 0, "the block reached the floor");
    assert!(
        largest_gap(&cpu.x, &dev.x) < 1e-4,
        "GPU vs CPU on the floor"
    );
}

#[test]
fn two_runs_on_one_adapter_give_the_same_bytes() {
    let gpu = gpu();
    let how = stepping(Some(-0.02));
    let run = |push: bool| {
        let (mut p, s) = block(false);
        // Particle 124 is halfway down (a = 2, b = 4, c = 4), free.
        if push {
            p.add_force(124, Vec3::new(0.05, 0.0, 0.0));
        }
        let mut k = ParticlesGpu::new(&gpu, &p, &s, &Constraints::none())
            .expect("the device takes the block");
        k.advance(&mut p, &how, 100).expect("steps");
        k.download(&mut p).expect("read back");
        p.state_hash()
    };
    let a = run(true);
    assert_eq!(a, run(true));
    // The external force went up and acted.
    assert_ne!(a, run(false));
}

mod solver {
    use super::*;
    use crate::models::particles::adhesion::{Adhesion, AdhesionParams};
    use crate::models::particles::chain::Chains;
    use crate::models::particles::cloth::{Cloth, ClothParams};
    use crate::models::particles::contacts::BodyContacts;
    use crate::models::particles::solver::{ParticleSolver, SolverParams, SolverParts};
    use crate::models::xpbd::Stretch;
    use crate::sim::{ModelOutput, TissueModel};

    pub(super) fn params(iterations: u32, damping_per_s: f32, floor_y_m: f32) -> SolverParams {
        SolverParams {
            iterations,
            substeps: 2,
            damping_per_s,
            gravity_m_per_s2: Vec3::new(0.0, -9.81, 0.0),
            floor_y_m,
            tie_stiffness_n_per_m: 200.0,
            grasp_reach_m: 0.004,
            grasp_most: 8,
            grasp_stiffness_n_per_m: 200.0,
        }
    }

    /// A solver over `p` with `shape`, `ties`, a cloth of `triangles` (50 N/m edges) and
    /// strands between `pairs`, nothing else.
    /// Strands of 3 segments of 100 N/m.
    const STRANDS: AdhesionParams = AdhesionParams {
        segments: 3,
        strand_mass_kg: 1e-6,
        body: 7,
        stiffness_n_per_m: 100.0,
        weak_stiffness_n_per_m: 1e-3,
        breakable_per_strand: 1,
        break_stretch: 1.1,
        tear_strain: 0.5,
    };

    /// What a test's solver holds besides its particles and clusters.
    struct Sets<'a> {
        ties: Vec<Stretch>,
        triangles: &'a [[u32; 3]],
        chains: Chains,
        /// Strands of `strand_params` between these pairs.
        pairs: &'a [(u32, u32)],
        strand_params: AdhesionParams,
        /// Particles in contacts between bodies.
        contacts: Vec<u32>,
    }

    impl Default for Sets<'_> {
        fn default() -> Self {
            Sets {
                ties: Vec::new(),
                triangles: &[],
                chains: Chains::default(),
                pairs: &[],
                strand_params: STRANDS,
                contacts: Vec::new(),
            }
        }
    }

    /// A solver over `p` with `shape` and `sets` (the cloth's edges 50 N/m), nothing else.
    fn solver_of(
        mut p: Particles,
        shape: ShapeMatching,
        sets: Sets,
        params: SolverParams,
    ) -> ParticleSolver {
        let Sets {
            ties,
            triangles,
            chains,
            pairs,
            strand_params,
            contacts,
        } = sets;
        let adhesion = Adhesion::new(&mut p, pairs, strand_params, 1).expect("strands");
        let bonds = Adhesion::new(&mut p, &[], strand_params, 2).expect("no strands");
        let cloth = Cloth::new(
            &p,
            triangles,
            ClothParams {
                stretch_stiffness_n_per_m: 50.0,
                bend_stiffness_n_m_per_rad: 1e-5,
            },
        )
        .expect("a cloth");
        let parts = SolverParts {
            particles: p,
            shape,
            chains,
            ties,
            cloth,
            adhesion,
            bonds,
            contacts: BodyContacts::new(contacts, 0.001, 0.001),
            contact_radius_m: 0.001,
        };
        ParticleSolver::new("test", parts, params)
    }

    /// The pinned block as a solver, its particles in contacts between bodies when asked.
    pub(super) fn solver(contacts: bool) -> ParticleSolver {
        let (p, shape) = block(false);
        let sets = Sets {
            contacts: if contacts {
                (0..p.len() as u32).collect()
            } else {
                Vec::new()
            },
            ..Sets::default()
        };
        solver_of(p, shape, sets, params(2, 5.0, -0.05))
    }

    /// A 10 x 10 sheet of cloth 4 mm apart, 20 mg a particle, hung from two corners by ties to
    /// pinned particles above them, falling and swinging under gravity.
    pub(super) fn sheet() -> ParticleSolver {
        let n = 10u32;
        let h = 0.004f32;
        let mut p = Particles::new();
        for i in 0..n {
            for j in 0..n {
                p.add(Vec3::new(j as f32 * h, 0.0, i as f32 * h), 2e-5, 0);
            }
        }
        let a = p.add(Vec3::new(0.0, 0.004, 0.0), 0.0, 1);
        let b = p.add(Vec3::new((n - 1) as f32 * h, 0.004, 0.0), 0.0, 1);
        let id = |i: u32, j: u32| i * n + j;
        let mut triangles = Vec::new();
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                triangles.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                triangles.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        let tie = |from: u32, to: u32| Stretch {
            a: from,
            b: to,
            rest_m: 0.004,
        };
        let ties = vec![tie(id(0, 0), a), tie(id(0, n - 1), b)];
        let shape = ShapeMatching::new(&p, Vec::new()).expect("no clusters");
        let sets = Sets {
            ties,
            triangles: &triangles,
            ..Sets::default()
        };
        solver_of(p, shape, sets, params(4, 2.0, -1.0))
    }

    /// `n` steps of 1 ms; the events they raised.
    pub(super) fn steps(s: &mut ParticleSolver, n: usize) -> Vec<crate::sim::EventKind> {
        let mut out = ModelOutput::default();
        for _ in 0..n {
            s.step(1e-3, &[], &mut out);
        }
        out.events
    }

    /// The solver is still on its device: no step fell back to the CPU.
    pub(super) fn still_on_gpu(s: &mut ParticleSolver) {
        assert_eq!(s.take_device_note(), None, "the device failed");
        assert!(s.gpu_adapter().is_some(), "the device was given up");
    }

    #[test]
    fn a_solver_of_clusters_steps_on_the_gpu_as_on_the_cpu() {
        let gpu = gpu();
        let (mut cpu, mut dev) = (solver(false), solver(false));
        dev.use_gpu(&gpu)
            .expect("the device takes clusters and a floor");
        assert!(dev.gpu_adapter().is_some() && cpu.gpu_adapter().is_none());
        let start = cpu.particles.x.clone();
        steps(&mut cpu, 200);
        steps(&mut dev, 200);
        let sag = largest_gap(&cpu.particles.x, &start);
        still_on_gpu(&mut dev);
        let gap = largest_gap(&cpu.particles.x, &dev.particles.x);
        assert!(
            sag > 2e-5 && gap < 0.01 * sag,
            "sag {sag} m, GPU vs CPU {gap} m"
        );
        // The clusters' frames, read back from the device (each substep reads only the
        // particles): the goals agree too.
        dev.read_device_clusters();
        let goal_gap = (0..cpu.shape.clusters())
            .map(|k| cpu.shape.goal(k, 0).distance(dev.shape.goal(k, 0)))
            .fold(0.0, f32::max);
        assert!(goal_gap < 0.01 * sag, "goals {goal_gap} m apart");
    }

    #[test]
    fn a_lost_device_leaves_the_session_on_the_cpu_from_the_last_step() {
        let gpu = gpu();
        let (mut cpu, mut dev) = (solver(false), solver(false));
        dev.use_gpu(&gpu).expect("the device takes it");
        steps(&mut cpu, 100);
        steps(&mut dev, 100);
        assert!(dev.inject_device_loss());
        steps(&mut cpu, 100);
        let events = steps(&mut dev, 100);
        assert!(dev.gpu_adapter().is_none(), "the device was given up");
        let notes: Vec<_> = events
            .iter()
            .filter_map(|e| match e {
                crate::sim::EventKind::ComputeFallback { model, reason } => Some((model, reason)),
                _ => None,
            })
            .collect();
        assert_eq!(notes.len(), 1, "the loss is reported once: {events:?}");
        assert!(notes[0].0 == "test" && !notes[0].1.is_empty(), "{notes:?}");
        assert!(dev.particles.is_finite());
        let sag = largest_gap(&cpu.particles.x, &solver(false).particles.x);
        let gap = largest_gap(&cpu.particles.x, &dev.particles.x);
        assert!(
            gap < 0.01 * sag,
            "after the loss: {gap} m from the CPU's run (sag {sag} m)"
        );
    }

    /// Two blocks of liver-like particles (6 x 4 x 6, 3.5 mm apart, contact radius 1.5 mm):
    /// the lower one's bottom pinned, the upper one (another body) falling onto it from 2 mm
    /// above; the contacts between bodies keep them apart.
    pub(super) fn stacked() -> ParticleSolver {
        let h = 0.0035f32;
        let rho = 1060.0;
        let mut p = Particles::new();
        let mut specs = Vec::new();
        for (body, base) in [(0u16, 0.0f32), (1, 4.0 * h + 0.002)] {
            let first = p.len() as u32;
            for a in 0..6 {
                for b in 0..4 {
                    for c in 0..6 {
                        let x = Vec3::new(a as f32 * h, base + b as f32 * h, c as f32 * h);
                        p.add(x, rho * h * h * h, body);
                    }
                }
            }
            let members: Vec<u32> = (first..p.len() as u32).collect();
            let r = 2.5 * h;
            specs.extend(lattice_clusters(
                &p.x,
                &members,
                h,
                3,
                r,
                frequency_for(5000.0, rho, r),
            ));
        }
        let shape = ShapeMatching::new(&p, specs).expect("clusters");
        for i in 0..p.len() {
            if p.x[i].y == 0.0 {
                p.pin(i);
            }
        }
        let mut s = solver_of(p, shape, Sets::default(), params(3, 5.0, -1.0));
        s.contacts = BodyContacts::new((0..s.particles.len() as u32).collect(), 0.0015, 0.001);
        s
    }

    #[test]
    fn blocks_of_two_bodies_meet_and_stay_apart_on_the_gpu_as_on_the_cpu() {
        let gpu = gpu();
        let (mut cpu, mut dev) = (stacked(), stacked());
        dev.use_gpu(&gpu)
            .expect("the device takes clusters and contacts");
        let start = cpu.particles.x.clone();
        // The upper block falls 2.5 mm to touch in 23 ms, bounces a little and settles on the
        // lower one.
        let mut touched = [0usize; 2];
        for _ in 0..80 {
            for (k, s) in [&mut cpu, &mut dev].into_iter().enumerate() {
                steps(s, 1);
                touched[k] = touched[k].max(s.contacts.touching);
            }
        }
        assert!(
            touched[0] > 0 && touched[1] > 0,
            "pairs touched: {touched:?}"
        );
        // The closest pair of particles of different bodies.
        let closest = |s: &ParticleSolver| {
            let x = &s.particles.x;
            (0..144)
                .flat_map(|i| (144..288).map(move |j| (i, j)))
                .map(|(i, j)| x[i].distance(x[j]))
                .fold(f32::MAX, f32::min)
        };
        for s in [&cpu, &dev] {
            assert!(s.contacts.searches > 1);
            let d = closest(s);
            // Two radii are 3 mm: nothing passed through, and the blocks are close.
            assert!(d > 0.0027 && d < 0.004, "closest across bodies {d} m");
        }
        let moved = largest_gap(&cpu.particles.x, &start);
        still_on_gpu(&mut dev);
        let apart = largest_gap(&cpu.particles.x, &dev.particles.x);
        assert!(moved > 0.002, "the upper block moved {moved} m");
        assert!(
            apart < 0.01 * moved,
            "GPU vs CPU: {apart} m apart ({moved} m moved)"
        );
        assert_eq!(cpu.contacts.searches, dev.contacts.searches);
    }

    #[test]
    fn a_steps_push_acts_through_all_its_substeps_on_both_paths() {
        // One free particle of 1 g, pushed by 0.1 N for one 1 ms step, no gravity, no
        // damping: it leaves at F dt / m = 0.1 m/s however many substeps the step has.
        let gpu = gpu();
        for substeps in [1, 2, 4] {
            for on_gpu in [false, true] {
                let mut p = Particles::new();
                p.add(Vec3::ZERO, 1e-3, 0);
                let shape = ShapeMatching::new(&p, Vec::new()).expect("no clusters");
                let mut how = params(2, 0.0, -1.0);
                how.gravity_m_per_s2 = Vec3::ZERO;
                how.substeps = substeps;
                let mut s = solver_of(p, shape, Sets::default(), how);
                if on_gpu {
                    s.use_gpu(&gpu).expect("the device takes a particle");
                }
                s.particles.add_force(0, Vec3::X * 0.1);
                steps(&mut s, 1);
                let v = s.particles.v[0].x;
                assert!(
                    (v - 0.1).abs() < 1e-5,
                    "{substeps} substeps, GPU {on_gpu}: {v} m/s"
                );
                assert_eq!(s.particles.ext[0], Vec3::ZERO, "the push is used up");
                if on_gpu {
                    still_on_gpu(&mut s);
                }
            }
        }
    }

    #[test]
    fn a_rollback_goes_up_before_the_next_device_step() {
        let gpu = gpu();
        let (mut cpu, mut dev) = (solver(false), solver(false));
        dev.use_gpu(&gpu).expect("the device takes it");
        for s in [&mut cpu, &mut dev] {
            steps(s, 50);
            s.checkpoint();
            steps(s, 50);
            s.restore();
            steps(s, 50);
        }
        let sag = largest_gap(&cpu.particles.x, &solver(false).particles.x);
        still_on_gpu(&mut dev);
        let gap = largest_gap(&cpu.particles.x, &dev.particles.x);
        assert!(
            gap < 0.01 * sag,
            "{gap} m apart after a rollback (sag {sag} m)"
        );
    }

    #[test]
    fn a_hanging_sheet_of_cloth_swings_on_the_gpu_as_on_the_cpu() {
        let gpu = gpu();
        let (mut cpu, mut dev) = (sheet(), sheet());
        dev.use_gpu(&gpu).expect("the device takes cloth and ties");
        let (edges, hinges) = cpu.cloth.colours();
        let colours = |c: &[u32]| c.iter().max().map_or(0, |m| m + 1);
        assert!(colours(edges) >= 6 && colours(hinges) >= 4);
        let start = cpu.particles.x.clone();
        steps(&mut cpu, 150);
        steps(&mut dev, 150);
        // The sheet falls and folds over 150 ms: centimetres, every edge and hinge working.
        let moved = largest_gap(&cpu.particles.x, &start);
        still_on_gpu(&mut dev);
        let gap = largest_gap(&cpu.particles.x, &dev.particles.x);
        assert!(moved > 0.02, "the sheet moved {moved} m");
        assert!(
            gap < 0.01 * moved,
            "GPU vs CPU: {gap} m apart ({moved} m moved)"
        );
        // Hung by its ties: the tied corners stay within a stretched tie of their anchors.
        let anchor = cpu.particles.x[100];
        assert!(dev.particles.x[0].distance(anchor) < 0.006);
    }

    #[test]
    fn a_cut_reaches_the_device_before_its_next_step() {
        let gpu = gpu();
        let (mut cpu, mut dev) = (sheet(), sheet());
        dev.use_gpu(&gpu).expect("the device takes cloth and ties");
        steps(&mut cpu, 50);
        steps(&mut dev, 50);
        // Cut across the middle row: the lower half falls away on both.
        let mid = cpu.particles.x[4 * 10 + 5];
        let a = cpu.dissect(mid, 0.012);
        let b = dev.dissect(dev.particles.x[4 * 10 + 5], 0.012);
        assert!(
            a.cloth > 0 && a.cloth == b.cloth,
            "{} vs {}",
            a.cloth,
            b.cloth
        );
        steps(&mut cpu, 100);
        steps(&mut dev, 100);
        let moved = largest_gap(&cpu.particles.x, &sheet().particles.x);
        still_on_gpu(&mut dev);
        let gap = largest_gap(&cpu.particles.x, &dev.particles.x);
        assert!(
            gap < 0.01 * moved,
            "after the cut: {gap} m apart ({moved} m moved)"
        );
    }

    /// The pinned block with a vessel hanging from its bottom corner (8 particles of 0.2 g,
    /// 3 mm apart) and strands from its bottom layer's 36 particles to pinned particles 1 cm
    /// below, each of 4 segments holding at 500 N/m and tearing past 30 % strain.
    pub(super) fn strands_scene() -> ParticleSolver {
        let (mut p, shape) = block(false);
        let corner = 47u32;
        let top = p.x[corner as usize];
        let mut vessel = vec![corner];
        for k in 1..8 {
            vessel.push(p.add(top - Vec3::Y * (0.003 * k as f32), 2e-4, 4));
        }
        let mut chains = Chains::new();
        chains.add(&p, &vessel, 300.0, 15.0);
        let bottom: Vec<u32> = (0..p.len() as u32)
            .filter(|&i| (p.x[i as usize].y + 0.0245).abs() < 1e-4)
            .collect();
        let pairs: Vec<(u32, u32)> = bottom
            .iter()
            .map(|&i| (i, p.add(p.x[i as usize] - Vec3::Y * 0.01, 0.0, 5)))
            .collect();
        let sets = Sets {
            chains,
            pairs: &pairs,
            strand_params: AdhesionParams {
                segments: 4,
                strand_mass_kg: 4e-6,
                body: 6,
                stiffness_n_per_m: 500.0,
                weak_stiffness_n_per_m: 1.0,
                breakable_per_strand: 1,
                break_stretch: 1.15,
                tear_strain: 0.3,
            },
            ..Sets::default()
        };
        solver_of(p, shape, sets, params(3, 5.0, -1.0))
    }

    /// Steps `steps` with the bottom layer pulled up, harder every step (1 N more a particle a
    /// second): the strands below stretch, weaken and tear. Returns the strands torn each step.
    pub(super) fn pulled(s: &mut ParticleSolver, steps: std::ops::Range<usize>) -> Vec<usize> {
        let mut out = ModelOutput::default();
        let bottom: Vec<usize> = (0..288)
            .filter(|&i| (s.particles.x[i].y + 0.0245).abs() < 2e-3)
            .collect();
        steps
            .map(|k| {
                let f = k as f32 * 1e-3;
                for &i in &bottom {
                    s.particles.add_force(i, Vec3::Y * f);
                }
                s.step(1e-3, &[], &mut out);
                s.outcome().breaks.len()
            })
            .collect()
    }

    #[test]
    fn a_vessel_and_strands_step_on_the_gpu_as_on_the_cpu_and_tear_alike() {
        // The strands' interior particles weigh a microgram each and swing: a nudge of 1 nm
        // on the CPU alone moves the first tear by 15 steps here. So the GPU is held to the
        // CPU as closely as that nudge holds the CPU to itself.
        let gpu = gpu();
        let (mut cpu, mut nudged, mut dev) = (strands_scene(), strands_scene(), strands_scene());
        assert!(cpu.chains.chains() == 1 && cpu.adhesion.strands() == 36);
        dev.use_gpu(&gpu)
            .expect("the device takes clusters, vessels and strands");
        assert!(dev.gpu_adapter().is_some());
        nudged.particles.x[100].x += 1e-9;
        let start = cpu.particles.x.clone();
        let organ_gap = |a: &ParticleSolver, b: &ParticleSolver| {
            largest_gap(&a.particles.x[..288], &b.particles.x[..288])
        };
        // Before any strand weakens: the block and the vessel alike.
        for s in [&mut cpu, &mut nudged, &mut dev] {
            assert_eq!(pulled(s, 0..100).iter().sum::<usize>(), 0);
        }
        let moved = largest_gap(&cpu.particles.x[..288], &start[..288]);
        let (by_nudge, by_gpu) = (organ_gap(&cpu, &nudged), organ_gap(&cpu, &dev));
        assert!(moved > 1e-4, "the block moved {moved} m");
        assert!(
            by_gpu <= 2.0 * by_nudge + 1e-3 * moved,
            "GPU {by_gpu} m off, a nudge {by_nudge} m"
        );
        let vessel = |s: &ParticleSolver| s.particles.x[288 + 6];
        assert!(
            vessel(&cpu).distance(vessel(&dev))
                <= 2.0 * vessel(&cpu).distance(vessel(&nudged)) + 1e-3 * moved
        );
        // Then every strand weakens and tears on each, at about the same time.
        still_on_gpu(&mut dev);
        let torn: Vec<Vec<usize>> = [&mut cpu, &mut nudged, &mut dev]
            .into_iter()
            .map(|s| pulled(s, 100..400))
            .collect();
        still_on_gpu(&mut dev);
        let total = |t: &[usize]| t.iter().sum::<usize>();
        assert_eq!(total(&torn[0]), 36, "every strand tore on the CPU");
        assert_eq!(total(&torn[2]), 36, "every strand tore on the GPU");
        let first = |t: &[usize]| t.iter().position(|&n| n > 0).unwrap_or(usize::MAX);
        let (fc, fn_, fg) = (first(&torn[0]), first(&torn[1]), first(&torn[2]));
        assert!(
            fg.abs_diff(fc) <= 2 * fn_.abs_diff(fc) + 5,
            "first tear: CPU {fc}, nudged {fn_}, GPU {fg}"
        );
        assert_eq!(cpu.adhesion.broken_counts(), dev.adhesion.broken_counts());
    }

    #[test]
    fn the_bench_line_states_the_device_and_checks_it_against_the_cpu() {
        let gpu = gpu();
        let s = strands_scene();
        let line = crate::models::particles::gpu_bench::bench_line(
            &gpu,
            &s,
            1e-3,
            0.2,
            Sweeps::Scheduled,
            true,
        )
        .expect("a line on the adapter there is");
        let c = &line.compute;
        assert_eq!(c.backend, Some("gpu"));
        assert_eq!(c.adapter.as_deref(), Some(gpu.describe().as_str()));
        assert_eq!(c.substeps_per_step, Some(2));
        assert!(line.steps >= 5 && line.all_awake);
        assert_eq!(line.vertices, s.particles.len());
        let check = c.check_rel_err.expect("checked");
        assert!(check.is_finite() && check < 0.01, "{check}");
        // A step's two substeps share a submission unless something fell between them.
        let per_step = c.submissions_per_step.expect("submissions");
        assert!(
            (1.0..2.0).contains(&per_step),
            "{per_step} submissions a step"
        );
        // A sweep moves at least each membership's entry and each particle's position.
        let bytes = c.bytes_per_substep.expect("bytes");
        assert!(
            bytes > 3 * (s.shape.memberships() as u64 * 88 + 288 * 32),
            "{bytes}"
        );
    }
}

#[path = "gpu_tool_tests.rs"]
mod tools;

#[path = "gpu_schedule_tests.rs"]
mod schedule;

#[path = "gpu_ahead_tests.rs"]
mod ahead;
