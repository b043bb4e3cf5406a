use super::*;

const DT: f32 = 1e-3;
/// The strand's length, m.
const L: f32 = 0.01;

fn params() -> AdhesionParams {
    AdhesionParams {
        segments: 5,
        strand_mass_kg: 1e-6,
        body: 7,
        stiffness_n_per_m: 1e4,
        weak_stiffness_n_per_m: 1e-3,
        breakable_per_strand: 1,
        break_stretch: 1.1,
        tear_strain: 0.5,
    }
}

/// A liver particle pinned at the origin and a gallbladder particle of 1 g `L` along x, joined
/// by one strand; returns the world, the strand and the gallbladder particle.
fn pair(params: AdhesionParams, seed: u64) -> (Particles, Adhesion, usize) {
    let mut p = Particles::new();
    let liver = p.add(Vec3::ZERO, 0.0, 1);
    let gallbladder = p.add(Vec3::new(L, 0.0, 0.0), 1e-3, 2);
    let a = Adhesion::new(&mut p, &[(gallbladder, liver)], params, seed).expect("strand");
    (p, a, gallbladder as usize)
}

/// One step (no gravity) with `iters` sweeps; returns the step's tears.
fn step(p: &mut Particles, a: &mut Adhesion, iters: usize, damping: f32) -> Vec<AdhesionBreak> {
    p.predict(DT, Vec3::ZERO);
    a.begin_step();
    for _ in 0..iters {
        a.project(p, DT);
    }
    p.finish(DT, damping);
    a.update(p)
}

#[test]
fn a_strand_is_a_chain_of_particles_on_the_line() {
    let (p, a, g) = pair(params(), 1);
    assert_eq!((a.strands(), a.segments(), p.len()), (1, 5, 2 + 4));
    let chain = a.strand_particles(0);
    assert_eq!(chain, vec![g as u32, 2, 3, 4, 5, 0]);
    for (k, &i) in chain.iter().enumerate() {
        // Evenly from the gallbladder (x = L) to the liver (x = 0).
        let expect = Vec3::new(L * (1.0 - k as f32 / 5.0), 0.0, 0.0);
        assert!(p.x[i as usize].distance(expect) < 1e-8, "{k}");
        if (1..5).contains(&k) {
            assert!((p.mass(i as usize) - 0.25e-6).abs() < 1e-12);
            assert_eq!(p.body[i as usize], 7);
        }
    }
    let drawn: Vec<_> = a.segments_for_drawing().collect();
    let links: Vec<_> = chain.windows(2).map(|w| (w[0], w[1])).collect();
    assert_eq!(drawn, links);
    assert_eq!(a.breakable_segments(0).count(), 1);
    assert!(a.heap_bytes() > 0);
}

#[test]
fn below_the_threshold_the_strand_holds_and_carries_the_pull() {
    // 0.05 N, far below the 2 N at which the stiff strand (k / 5 = 2000 N/m) would reach the
    // 10 % break stretch: it stretches by F / (k / n) = 25 um and carries the pull.
    let f = 0.05;
    let (mut p, mut a, g) = pair(params(), 1);
    let mut longest = 0.0f32;
    for _ in 0..1000 {
        p.add_force(g, Vec3::new(f, 0.0, 0.0));
        assert!(step(&mut p, &mut a, 10, 20.0).is_empty());
        longest = longest.max(p.x[g].length());
    }
    let length = p.x[g].length();
    let expect = L + f * 5.0 / 1e4;
    let tension = a.tension_n(0);
    println!(
        "held strand: length {length} m (spring of the stiff segments: {expect} m), longest \
         {longest} m, tension {tension} N for {f} N"
    );
    assert!(longest < 1.01 * L, "{longest}");
    assert!(
        (length - expect).abs() < 0.1 * (expect - L),
        "{length} vs {expect}"
    );
    assert!((tension - f).abs() < 0.05 * f, "{tension}");
    assert!(!a.is_weakened(0));
    assert_eq!((a.intact_strands(), a.torn_segments()), (1, 0));
    assert!(p.v[g].length() < 1e-4, "{}", p.v[g]);
}

/// Pulls the gallbladder particle of a strand by a force growing 1 N/s until the strand
/// tears; returns the world, the strand, the gallbladder particle, the pull at the tear, N, and
/// the tears.
fn pull_until_break(
    params: AdhesionParams,
    seed: u64,
    iters: usize,
) -> (Particles, Adhesion, usize, f32, Vec<AdhesionBreak>) {
    let (mut p, mut a, g) = pair(params, seed);
    let mut t = 0.0;
    loop {
        t += DT;
        p.add_force(g, Vec3::new(t, 0.0, 0.0));
        let tears = step(&mut p, &mut a, iters, 20.0);
        if !tears.is_empty() {
            return (p, a, g, t, tears);
        }
        assert!(t < 3.0, "no break");
    }
}

#[test]
fn pulled_past_the_threshold_the_strand_breaks_at_a_breakable_segment() {
    // The stiff strand reaches 1.1 L at F = (k / n) 0.1 L = 2 N; its breakable segment goes
    // weak and tears within a few steps, whatever the iterations. A seed that makes the middle
    // segment breakable, so that both halves have particles of the strand's own.
    let seed = (0..100)
        .find(|&seed| pair(params(), seed).1.breakable_segments(0).eq([2]))
        .expect("a seed");
    let at3 = pull_until_break(params(), seed, 3).3;
    let at20 = pull_until_break(params(), seed, 20).3;
    let (mut p, mut a, g, broke_at, tears) = pull_until_break(params(), seed, 10);
    println!(
        "strand broke at a pull of {broke_at} N ({at3} N at 3 iterations, {at20} N at 20): \
         {tears:?}"
    );
    for f in [broke_at, at3, at20] {
        assert!((f - 2.0).abs() < 0.05 * 2.0, "{f}");
    }
    assert_eq!(tears.len(), 1);
    assert_eq!((tears[0].strand, tears[0].segment), (0, 2));
    assert!(a.is_weakened(0));
    assert_eq!((a.intact_strands(), a.torn_segments()), (0, 1));
    // Pulled on, the gallbladder flies off with its half; 50 ms on, each half hangs from its
    // organ, every particle its chain's length from it.
    for _ in 0..50 {
        p.add_force(g, Vec3::new(broke_at, 0.0, 0.0));
        assert!(step(&mut p, &mut a, 10, 0.0).is_empty());
    }
    let chain = a.strand_particles(0);
    let cut = tears[0].segment as usize;
    let l0 = L / 5.0;
    assert!(p.x[g].x > 5.0 * L, "{}", p.x[g]);
    for (k, &i) in chain.iter().enumerate() {
        let (end, links) = if k <= cut {
            (p.x[g], k)
        } else {
            (Vec3::ZERO, 5 - k)
        };
        let d = p.x[i as usize].distance(end);
        assert!(d <= links as f32 * l0 * 1.01, "{k}: {d}");
    }
    for k in 0..5 {
        assert_eq!(a.segment_intact(0, k), k != cut);
    }
    assert_eq!(a.segments_for_drawing().count(), 4);
}

#[test]
fn a_strand_tears_once_and_its_other_weak_link_holds_again() {
    // Every segment breakable: all go weak together and stretch alike, but only the most
    // stretched tears; the others are stiff again, and the halves stay whole.
    let all = AdhesionParams {
        breakable_per_strand: 5,
        ..params()
    };
    let (mut p, mut a, g, broke_at, tears) = pull_until_break(all, 1, 10);
    assert!((broke_at - 2.0).abs() < 0.1, "{broke_at}");
    assert_eq!(tears.len(), 1);
    for _ in 0..50 {
        assert!(step(&mut p, &mut a, 10, 0.0).is_empty());
    }
    assert_eq!(a.torn_segments(), 1);
    let chain = a.strand_particles(0);
    for (s, w) in chain.windows(2).enumerate() {
        if a.segment_intact(0, s) {
            let d = p.x[w[0] as usize].distance(p.x[w[1] as usize]);
            assert!((d - L / 5.0).abs() < 0.01 * L / 5.0, "{s}: {d}");
        }
    }
    assert!(p.x[g].x > 5.0 * L);
}

#[test]
fn the_seed_picks_the_breakable_segments() {
    let mut p = Particles::new();
    let mut pairs = Vec::new();
    for i in 0..200 {
        let x = i as f32 * 1e-3;
        let g = p.add(Vec3::new(x, 0.0, L), 1e-3, 2);
        let l = p.add(Vec3::new(x, 0.0, 0.0), 0.0, 1);
        pairs.push((g, l));
    }
    let picks = |seed: u64| {
        let mut q = p.clone();
        let par = AdhesionParams {
            segments: 8,
            breakable_per_strand: 2,
            ..params()
        };
        let a = Adhesion::new(&mut q, &pairs, par, seed).expect("strands");
        (0..200)
            .map(|s| a.breakable_segments(s).collect::<Vec<u32>>())
            .collect::<Vec<_>>()
    };
    let (one, again, two) = (picks(1), picks(1), picks(2));
    assert_eq!(one, again);
    // Two random pairs of 8 segments are the same pair once in 28.
    let differ = one.iter().zip(&two).filter(|(a, b)| a != b).count();
    assert!(differ > 170, "{differ}");
    // Every strand has 2 distinct ones, and each of the 8 is picked 200 * 2 / 8 = 50 times
    // give or take (binomial sd 6.1).
    let mut counts = [0; 8];
    for s in &one {
        assert_eq!(s.len(), 2);
        for &k in s {
            counts[k as usize] += 1;
        }
    }
    println!("seeds 1 and 2 differ on {differ} of 200 strands; seed 1 picks {counts:?}");
    assert!(counts.iter().all(|&c| (25..=75).contains(&c)), "{counts:?}");
}

#[test]
fn bad_params_and_pairs_are_refused_naming_what_is_wrong() {
    let mut p = Particles::new();
    let g = p.add(Vec3::new(L, 0.0, 0.0), 1e-3, 2);
    let l = p.add(Vec3::ZERO, 0.0, 1);
    let cases: [(AdhesionParams, &str); 9] = [
        (
            AdhesionParams {
                segments: 1,
                ..params()
            },
            "segments must be at least 2",
        ),
        (
            AdhesionParams {
                strand_mass_kg: 0.0,
                ..params()
            },
            "strand_mass_kg",
        ),
        (
            AdhesionParams {
                stiffness_n_per_m: f32::INFINITY,
                ..params()
            },
            "stiffness_n_per_m",
        ),
        (
            AdhesionParams {
                weak_stiffness_n_per_m: -1.0,
                ..params()
            },
            "weak_stiffness_n_per_m",
        ),
        (
            AdhesionParams {
                weak_stiffness_n_per_m: 2e4,
                ..params()
            },
            "weak_stiffness_n_per_m must be a positive number less than stiffness_n_per_m",
        ),
        (
            AdhesionParams {
                breakable_per_strand: 6,
                ..params()
            },
            "breakable_per_strand must be at most segments (got 6)",
        ),
        (
            AdhesionParams {
                break_stretch: 1.0,
                ..params()
            },
            "break_stretch",
        ),
        (
            AdhesionParams {
                tear_strain: f32::NAN,
                ..params()
            },
            "tear_strain",
        ),
        (
            AdhesionParams {
                strand_mass_kg: f32::NAN,
                ..params()
            },
            "strand_mass_kg must be a positive finite number",
        ),
    ];
    for (par, says) in cases {
        let e = Adhesion::new(&mut p, &[(g, l)], par, 1).expect_err(says);
        assert!(e.to_string().contains(says), "{e} / {says}");
    }
    let e = Adhesion::new(&mut p, &[(g, l), (g, 9)], params(), 1).expect_err("missing");
    assert!(e.to_string().contains("pair 1: particle 9"), "{e}");
    let e = Adhesion::new(&mut p, &[(g, g)], params(), 1).expect_err("itself");
    assert!(e.to_string().contains("pair 0 joins particle 0"), "{e}");
    let m = p.add(Vec3::ZERO, 1e-3, 2);
    let e = Adhesion::new(&mut p, &[(g, l), (m, l)], params(), 1).expect_err("no length");
    assert!(e.to_string().contains("pair 1"), "{e}");
    // Nothing was added on the way.
    assert_eq!(p.len(), 3);
}

#[test]
fn cutting_removes_the_segments_at_the_tool_only() {
    // Three strands down z from gallbladder (z = L) to liver (z = 0), 5 mm apart in x; their
    // 2 mm segments run 10-8, 8-6, 6-4, 4-2, 2-0 mm.
    let mut p = Particles::new();
    let mut pairs = Vec::new();
    for s in 0..3 {
        let x = s as f32 * 5e-3;
        let g = p.add(Vec3::new(x, 0.0, L), 1e-3, 2);
        let l = p.add(Vec3::new(x, 0.0, 0.0), 0.0, 1);
        pairs.push((g, l));
    }
    let mut a = Adhesion::new(&mut p, &pairs, params(), 1).expect("strands");
    assert!(a.cut_near(Vec3::new(0.1, 0.0, 0.0), 1e-3, &p).is_empty());
    // 0.5 mm from strand 0's middle segment (6-4 mm), 4.5 mm from strand 1.
    let cuts = a.cut_near(Vec3::new(5e-4, 0.0, 5e-3), 6e-4, &p);
    assert_eq!(cuts.len(), 1);
    assert_eq!((cuts[0].strand, cuts[0].segment), (0, 2));
    assert!(cuts[0].position.distance(Vec3::new(0.0, 0.0, 5e-3)) < 1e-7);
    // 1.5 mm about strand 2's particle at 6 mm: the two segments meeting there.
    let cuts = a.cut_near(Vec3::new(0.01, 0.0, 6e-3), 1.5e-3, &p);
    let which: Vec<_> = cuts.iter().map(|c| (c.strand, c.segment)).collect();
    assert_eq!(which, vec![(2, 1), (2, 2)]);
    assert_eq!((a.intact_strands(), a.torn_segments()), (1, 3));
    assert_eq!(a.segments_for_drawing().count(), 15 - 3);
    for (s, k) in [(0, 2), (2, 1), (2, 2)] {
        assert!(!a.segment_intact(s, k));
    }
    assert_eq!(a.tension_n(1), 0.0);
}

#[test]
fn the_same_pulls_give_the_same_bytes_and_breaks() {
    let run = || {
        let mut p = Particles::new();
        let mut pairs = Vec::new();
        for s in 0..6 {
            let y = s as f32 * 2e-3;
            let g = p.add(Vec3::new(L, y, 0.0), 1e-3, 2);
            let l = p.add(Vec3::new(0.0, y, 1e-3 * s as f32), 0.0, 1);
            pairs.push((g, l));
        }
        let par = AdhesionParams {
            segments: 6,
            breakable_per_strand: 2,
            ..params()
        };
        let mut a = Adhesion::new(&mut p, &pairs, par, 42).expect("strands");
        let mut tears = Vec::new();
        for t in 0..1500 {
            for &(g, _) in &pairs {
                p.add_force(g as usize, Vec3::new(t as f32 * 3e-3, 0.0, 0.0));
            }
            tears.extend(step(&mut p, &mut a, 8, 10.0));
        }
        (p.state_hash(), tears)
    };
    let (h1, t1) = run();
    let (h2, t2) = run();
    assert!(!t1.is_empty());
    assert_eq!(h1, h2);
    assert_eq!(t1, t2);
}

#[test]
fn a_whole_strand_sits_at_its_equilibrium_and_tears_by_its_ends() {
    // An interior particle thrown 3 mm off the line (a segment then 80 % longer than its 2 mm
    // rest length, past the 50 % tear strain) with the ends at their rest distance: the
    // strand's tension is nil, so nothing tears, and a step puts the particle back on the line
    // between the ends. Read from the particles, the segment would have torn.
    let (mut p, mut a, g) = pair(params(), 1);
    let chain = a.strand_particles(0);
    let thrown = chain[2] as usize;
    p.x[thrown].y += 0.003;
    assert!(step(&mut p, &mut a, 2, 0.0).is_empty());
    assert_eq!(a.torn_segments(), 0);
    for (k, &i) in chain.iter().enumerate() {
        let on_line = p.x[g].lerp(Vec3::ZERO, k as f32 / 5.0);
        assert!(
            p.x[i as usize].distance(on_line) < 1e-7,
            "{k}: {}",
            p.x[i as usize]
        );
    }
    // Held 12 % apart (past the 10 % break stretch), it is weakened and its breakable segment,
    // which takes all the stretch, tears in the same step: at 1, 2 and 8 sweeps alike.
    for sweeps in [1, 2, 8] {
        let (mut p, mut a, g) = pair(params(), 1);
        p.x[g].x = 1.12 * L;
        p.w[g] = 0.0;
        let tears = step(&mut p, &mut a, sweeps, 0.0);
        assert_eq!(tears.len(), 1, "{sweeps} sweeps");
        let breakable: Vec<_> = a.breakable_segments(0).collect();
        assert_eq!(vec![tears[0].segment], breakable, "{sweeps} sweeps");
    }
}
