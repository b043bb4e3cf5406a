use super::*;
use glam::Quat;

/// Two blocks of `n^3` particles `h` apart (bodies 0 and 1), the second `gap` above the first
/// along y (negative: overlapping), every particle `mass` kg.
fn two_blocks(n: usize, h: f32, gap: f32, mass: f32) -> Particles {
    let mut p = Particles::new();
    for body in 0..2u16 {
        let y0 = if body == 0 {
            0.0
        } else {
            (n - 1) as f32 * h + gap
        };
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    let x = Vec3::new(a as f32 * h, y0 + b as f32 * h, c as f32 * h);
                    p.add(x, mass, body);
                }
            }
        }
    }
    p
}

fn brute_pairs(p: &Particles, reach: f32) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            if p.body[i] != p.body[j] && p.x[i].distance(p.x[j]) <= reach {
                out.push((i as u32, j as u32));
            }
        }
    }
    out
}

#[test]
fn the_grid_finds_the_pairs_brute_force_finds() {
    let (h, r, margin) = (0.002, 0.001, 0.0005);
    let mut p = two_blocks(6, h, 0.0008, 1e-5);
    // Jitter so that distances are not all equal.
    for (i, x) in p.x.iter_mut().enumerate() {
        *x += Vec3::new(
            ((i * 7) % 13) as f32,
            ((i * 11) % 17) as f32,
            ((i * 5) % 19) as f32,
        ) * 2e-5;
    }
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let mut c = BodyContacts::new(all, r, margin);
    c.refresh(&p);
    let want = brute_pairs(&p, 2.0 * r + margin);
    assert!(!want.is_empty());
    assert_eq!(c.pairs(), &want[..]);
    // A sparse set (two particles far apart) goes through the sorted search: same answer.
    let mut q = Particles::new();
    q.add(Vec3::ZERO, 1e-5, 0);
    q.add(Vec3::new(0.0021, 0.0, 0.0), 1e-5, 1);
    q.add(Vec3::new(5.0, 5.0, 5.0), 1e-5, 1);
    let mut c = BodyContacts::new(vec![0, 1, 2], r, margin);
    c.refresh(&q);
    assert_eq!(c.pairs(), &[(0, 1)]);
}

#[test]
fn the_grid_finds_the_pairs_brute_force_finds_among_many_bodies() {
    // 2,000 members scattered through a 3 cm box, of 20 bodies (those from 15 on share the
    // grid's last body bit), a shell of one body round a core of another, and two members of
    // bodies 15 and 16 alone: the columns' body bits pass over most members, and nothing they
    // pass over had a pair.
    let (r, margin) = (0.001, 0.0005);
    let mut p = Particles::new();
    let mut seed = 0x9e37_79b9_u32;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32
    };
    for k in 0..2000 {
        let x = Vec3::new(next(), next(), next()) * 0.03;
        p.add(x, 1e-5, (k % 20) as u16);
    }
    for k in 0..400 {
        // A sphere of body 0 (4 cm across) about a small core of body 1 far from the rest.
        let t = k as f32 * 2.399_963;
        let z = 1.0 - 2.0 * (k as f32 + 0.5) / 400.0;
        let s = (1.0 - z * z).sqrt();
        let on = Vec3::new(s * t.cos(), s * t.sin(), z);
        p.add(Vec3::splat(0.2) + on * 0.02, 1e-5, 0);
        if k < 20 {
            p.add(Vec3::splat(0.2) + on * 0.0015, 1e-5, 1);
        }
    }
    // Two bodies from 15 on, alone together.
    let lone = [
        p.add(Vec3::splat(0.1), 1e-5, 15),
        p.add(Vec3::new(0.102, 0.1, 0.1), 1e-5, 16),
    ];
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let mut c = BodyContacts::new(all, r, margin);
    c.refresh(&p);
    let want = brute_pairs(&p, 2.0 * r + margin);
    assert!(want.len() > 100, "{} pairs", want.len());
    assert!(want.contains(&(lone[0], lone[1])));
    assert!(
        want.iter()
            .any(|&(i, j)| p.body[i as usize] >= 15 && p.body[j as usize] >= 15)
    );
    assert_eq!(c.pairs(), &want[..]);
}

#[test]
fn overlapping_bodies_are_pushed_apart_keeping_momentum() {
    let (h, r) = (0.002, 0.001);
    // The second block's bottom layer 0.8 mm into the first's top layer.
    let mut p = two_blocks(4, h, h - 0.0008 - h, 1e-5);
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let mut c = BodyContacts::new(all, r, 0.0005);
    let dt = 1e-3;
    for _ in 0..20 {
        p.predict(dt, Vec3::ZERO);
        c.refresh(&p);
        for _ in 0..4 {
            c.project(&mut p);
        }
        p.finish(dt, 0.0);
    }
    let closest = brute_pairs(&p, 1.0)
        .iter()
        .map(|&(i, j)| p.x[i as usize].distance(p.x[j as usize]))
        .fold(f32::INFINITY, f32::min);
    assert!(closest > 2.0 * r - 1e-5, "{closest}");
    // Equal and opposite pushes: the total momentum stays zero.
    let momentum: Vec3 = p.v.iter().map(|v| *v * 1e-5).sum();
    let scale: f32 = p.v.iter().map(|v| v.length() * 1e-5).sum();
    assert!(scale > 0.0, "they were pushed");
    assert!(momentum.length() < 1e-4 * scale, "{momentum} of {scale}");
}

#[test]
fn the_pairs_are_kept_until_something_moves_half_the_margin() {
    let (h, r, margin) = (0.002, 0.001, 0.001);
    let mut p = two_blocks(3, h, 0.0005, 1e-5);
    let all: Vec<u32> = (0..p.len() as u32).collect();
    let mut c = BodyContacts::new(all, r, margin);
    c.refresh(&p);
    assert_eq!(c.searches, 1);
    p.x[0].x += 0.4 * margin;
    c.refresh(&p);
    assert_eq!(c.searches, 1, "under half the margin");
    p.x[0].x += 0.2 * margin;
    c.refresh(&p);
    assert_eq!(c.searches, 2, "over half the margin");
    assert_eq!(c.pairs(), &brute_pairs(&p, 2.0 * r + margin)[..]);
}

#[test]
fn an_instrument_pushes_particles_out_and_feels_what_it_did_to_them() {
    // A 10 x 10 sheet of free particles at y = 0 (one body), a grasper's shaft pressed 1 mm
    // into it from above, lying along x.
    let (h, r, mass, dt) = (0.002, 0.001, 2e-5, 1e-3);
    let mut p = Particles::new();
    for a in 0..10 {
        for c in 0..10 {
            p.add(Vec3::new(a as f32 * h, 0.0, c as f32 * h), mass, 0);
        }
    }
    let before = p.x.clone();
    // Shaft along -z (aim-pose forward) rotated to lie along +x: forward -Z -> +X.
    let q = Quat::from_rotation_y(-std::f32::consts::FRAC_PI_2);
    let hinge = Vec3::new(0.0, 0.0025 + r - 0.001, 0.009);
    let tool = Instrument::grasper(hinge, q, 0.0).expect("grasper");
    let mut push = ToolPush::new(&p, r);
    push.begin_step();
    let touched = push.project(&tool, &mut p, dt);
    assert!(touched > 0);
    // Nobody is left inside the grown shaft.
    let grown = tool.inflated(r);
    let mut inside = Vec::new();
    grown.contacts_all(PointCloud::from_points(&p.x), &mut inside);
    assert!(
        inside.iter().all(|c| c.depth_m < 1e-6),
        "{:?}",
        inside.first()
    );
    // The reaction is minus the sum of m dx / dt^2 over the particles, and points up (the
    // sheet pushes back on a tool pressing down).
    let moved: Vec3 =
        p.x.iter()
            .zip(&before)
            .map(|(a, b)| (*a - *b) * (mass / (dt * dt)))
            .sum();
    let reaction = push.reaction_n();
    assert!(
        (reaction + moved).length() <= 1e-4 * moved.length(),
        "{reaction} {moved}"
    );
    assert!(reaction.y > 0.9 * reaction.length(), "{reaction}");
}

#[test]
fn a_grasp_holds_a_hanging_weight_and_feels_it() {
    // One particle of 10 g under gravity, held by a grasp: at rest the grasper carries its
    // weight, m g downwards.
    let mut p = Particles::new();
    p.add(Vec3::ZERO, 0.01, 0);
    p.add(Vec3::new(0.1, 0.0, 0.0), 0.01, 0);
    let jaw = Vec3::new(0.0, 0.001, 0.0);
    let mut g = Grasp::take(&p, jaw, 0.003, 8, 200.0);
    assert_eq!(
        g.particles().collect::<Vec<_>>(),
        [0],
        "only the one within reach"
    );
    let dt = 1e-3;
    let gravity = Vec3::new(0.0, -9.81, 0.0);
    for _ in 0..3000 {
        p.predict(dt, gravity);
        g.begin_step();
        for _ in 0..2 {
            g.project(&mut p, jaw, dt);
        }
        p.finish(dt, 10.0);
    }
    let weight = 0.01 * 9.81;
    let r = g.reaction_n(dt);
    assert!(
        (r - Vec3::new(0.0, -weight, 0.0)).length() < 0.02 * weight,
        "{r}"
    );
    // It hangs below its place by m g / k.
    let sag = (jaw.y - p.x[0].y) - (jaw.y - 0.0);
    assert!(
        (sag - weight / 200.0).abs() < 0.02 * weight / 200.0,
        "{sag}"
    );
}

#[test]
fn pairs_built_touching_are_left_as_built() {
    let mut p = Particles::new();
    p.add(Vec3::ZERO, 1e-5, 0);
    p.add(Vec3::new(0.001, 0.0, 0.0), 1e-5, 1);
    p.add(Vec3::new(0.0, 0.01, 0.0), 1e-5, 2);
    let mut c = BodyContacts::new(vec![0, 1, 2], 0.001, 0.0005);
    assert_eq!(c.ignore_present_overlaps(&p), 1);
    // The third comes down onto the first: it is pushed; the first two stay 1 mm apart.
    p.x[2] = Vec3::new(0.0, 0.0015, 0.0);
    c.refresh(&p);
    assert_eq!(c.pairs(), &[(0, 2), (1, 2)]);
    c.project(&mut p);
    assert!((p.x[0].distance(p.x[1]) - 0.001).abs() < 2e-4, "{:?}", p.x);
    assert!(p.x[2].distance(p.x[0]) > 0.0019, "{:?}", p.x);
}

/// An instrument lists the particles within `PUSH_LIST_MARGIN_M` of it at a substep's first
/// sweep: one that comes inside from within that margin during the substep's sweeps is
/// pushed out by them; one that jumps in from further away waits for the next substep.
#[test]
fn an_instrument_pushes_what_it_listed_this_substep_and_the_rest_at_the_next() {
    use crate::collision::ToolCylinder;
    let (r, dt) = (0.001f32, 1e-3f32);
    // A rod of radius 2 mm along x through the origin; grown by r it reaches 3 mm.
    let rod = ToolCylinder::constant(Vec3::new(-0.02, 0.0, 0.0), Vec3::new(0.02, 0.0, 0.0), 0.002)
        .expect("rod");
    let tool = Instrument::new(vec![rod]).expect("tool");
    let mut p = Particles::new();
    let near = p.add(
        Vec3::new(0.0, 0.0035 + 0.5 * PUSH_LIST_MARGIN_M, 0.0),
        1e-5,
        0,
    ) as usize;
    let far = p.add(
        Vec3::new(0.005, 0.0035 + 3.0 * PUSH_LIST_MARGIN_M, 0.0),
        1e-5,
        0,
    ) as usize;
    let mut push = ToolPush::new(&p, r);
    push.begin_step();
    assert_eq!(push.project(&tool, &mut p, dt), 0, "nobody inside yet");
    // Both jump 1 mm inside the grown rod within the substep.
    p.x[near].y = 0.002;
    p.x[far].y = 0.002;
    assert_eq!(push.project(&tool, &mut p, dt), 1);
    assert!((p.x[near].y - 0.003).abs() < 1e-6, "{}", p.x[near].y);
    assert_eq!(p.x[far].y, 0.002, "not listed this substep");
    push.begin_step();
    assert_eq!(push.project(&tool, &mut p, dt), 1);
    assert!((p.x[far].y - 0.003).abs() < 1e-6, "{}", p.x[far].y);
}
