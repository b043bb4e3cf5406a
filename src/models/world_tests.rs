//! The world stepping real models: soft bodies, and a strand of the tests' own beside them
//! (here, above the core, since they name the models).

use crate::mesh::icosphere;
use crate::models::{SimplexMesh, SoftBody, SoftBodyParams};
use crate::sim::*;
use glam::Vec3;

/// A soft ball of radius `r` at `center`, level-2 icosphere (320 points).
fn ball(name: &str, center: Vec3, r: f32) -> SoftBody {
    let mut m = icosphere(2);
    for p in &mut m.positions {
        *p = center + *p * r;
    }
    let s = SimplexMesh::dual(&m).expect("an icosphere has a dual");
    let n = s.len();
    SoftBody::new(name, s, vec![0; n], SoftBodyParams::default())
}

/// A press on top of the ball at `center` (radius `r`) with `pressure_pa`.
fn press(center: Vec3, r: f32, pressure_pa: f32) -> Contact {
    Contact {
        tool: Hand::Right,
        point: center + Vec3::Y * r,
        normal: Vec3::Y,
        kind: ContactKind::Press {
            pressure_pa,
            area_m2: 1e-4,
        },
    }
}

fn centers(n: usize) -> Vec<Vec3> {
    (0..n)
        .map(|i| Vec3::new(0.1 * i as f32, 0.0, 0.0))
        .collect()
}

fn is_quarantine(e: &EventKind, name: &str) -> bool {
    matches!(e, EventKind::Quarantined { model, .. } if model == name)
}

#[test]
fn a_model_that_goes_bad_is_frozen_alone_and_the_others_go_on() {
    let mut world = World::new();
    let c = centers(3);
    let ids: Vec<ModelId> = (0..3)
        .map(|i| world.add(ball(&format!("ball{i}"), c[i], 0.02)))
        .collect();
    let mut events = Vec::new();
    for step in 0..20 {
        for (i, &id) in ids.iter().enumerate() {
            world.contact(id, press(c[i], 0.02, 2000.0));
        }
        world.step(0.002, step, &mut events);
    }
    assert!(
        events
            .iter()
            .all(|e| !matches!(e, EventKind::Quarantined { .. }))
    );
    let good = world.model(ids[1]).state_hash();
    // A fault: one point of the middle ball becomes NaN.
    world.model_mut(ids[1]).set_position(5, Vec3::NAN);
    let before = [ids[0], ids[2]].map(|id| world.model(id).state_hash());
    events.clear();
    for step in 20..40 {
        for (i, &id) in ids.iter().enumerate() {
            world.contact(id, press(c[i], 0.02, 2000.0 + 100.0 * step as f32));
        }
        world.step(0.002, step, &mut events);
    }
    let quarantined: Vec<&EventKind> = events
        .iter()
        .filter(|e| matches!(e, EventKind::Quarantined { .. }))
        .collect();
    assert_eq!(quarantined.len(), 1, "{events:?}");
    assert!(is_quarantine(quarantined[0], "ball1"));
    assert!(world.is_frozen(ids[1]));
    assert!(!world.is_frozen(ids[0]) && !world.is_frozen(ids[2]));
    // The bad ball is back at its last checkpoint (step 16), finite.
    let frozen = world.model(ids[1]).state_hash();
    assert!(world.model(ids[1]).state_is_finite());
    assert_ne!(
        frozen, good,
        "the checkpoint is step 16's state, not step 19's"
    );
    // The others kept stepping under their growing presses.
    let after = [ids[0], ids[2]].map(|id| world.model(id).state_hash());
    assert_ne!(before[0], after[0]);
    assert_ne!(before[1], after[1]);
    // And the frozen one no longer moves or pushes.
    world.contact(ids[1], press(c[1], 0.02, 5000.0));
    world.step(0.002, 40, &mut events);
    assert_eq!(world.model(ids[1]).state_hash(), frozen);
    assert_eq!(world.reactions_from(ids[1]), [Vec3::ZERO; 2]);
    assert!(world.reactions()[1].is_finite());
}

/// Twelve balls pressed with pressures over six decades: the tool's reaction is a sum whose
/// float rounding depends on the order of its terms.
fn pressed_world(threads: usize, steps: u64) -> (u64, [Vec3; 2], Vec<[Vec3; 2]>, usize) {
    crate::sim::on_threads(threads, || {
        let mut world = World::new();
        let c = centers(12);
        for (i, p) in c.iter().enumerate() {
            world.add(ball(&format!("ball{i}"), *p, 0.01 + 0.001 * i as f32));
        }
        let mut events = Vec::new();
        for step in 0..steps {
            for (i, id) in world.ids().enumerate() {
                let pressure = 10f32.powi(i as i32 % 6) * (1.0 + 0.37 * i as f32);
                world.contact(id, press(c[i], 0.01 + 0.001 * i as f32, pressure));
            }
            world.step(0.002, step, &mut events);
        }
        let parts = world.ids().map(|id| world.reactions_from(id)).collect();
        (world.state_hash(), world.reactions(), parts, events.len())
    })
}

#[test]
fn one_two_and_three_threads_step_the_world_to_the_same_bits() {
    let (hash1, sum1, parts, events1) = pressed_world(1, 30);
    // The reaction is the sum of the models' parts in model order...
    let forward = parts.iter().fold(Vec3::ZERO, |s, p| s + p[1]);
    assert_eq!(
        sum1[1].to_array().map(f32::to_bits),
        forward.to_array().map(f32::to_bits)
    );
    // ...and this workload is one where the order shows: summed the other way round, or in
    // two halves as two worker threads would, the bits differ. A reduction that followed the
    // threads' chunks would fail the comparisons below.
    let backward = parts.iter().rev().fold(Vec3::ZERO, |s, p| s + p[1]);
    let halves = parts[..6].iter().fold(Vec3::ZERO, |s, p| s + p[1])
        + parts[6..].iter().fold(Vec3::ZERO, |s, p| s + p[1]);
    assert!(
        backward != forward || halves != forward,
        "the workload does not show summation order: {forward} {backward} {halves}"
    );
    for threads in [2, 3] {
        let (hash, sum, _, events) = pressed_world(threads, 30);
        assert_eq!(hash, hash1, "{threads} threads");
        assert_eq!(
            sum.map(|v| v.to_array().map(f32::to_bits)),
            sum1.map(|v| v.to_array().map(f32::to_bits)),
            "{threads} threads"
        );
        assert_eq!(events, events1);
    }
}

/// Points at fixed places, for driving an attachment by hand.
struct Fixed(Vec<Vec<Vec3>>);

impl PointSource for Fixed {
    fn point(&self, model: ModelId, point: u32) -> Option<Vec3> {
        self.0.get(model.index())?.get(point as usize).copied()
    }

    fn name(&self, model: ModelId) -> &str {
        ["a", "b"][model.index()]
    }
}

/// Empty force lists for two models.
fn two_forces() -> PointForces {
    PointForces::for_models(2)
}

#[test]
fn an_attachment_pulls_both_ends_with_equal_and_opposite_spring_forces() {
    let spring = LinkSpring {
        stiffness_n_per_m: 200.0,
        damping_n_s_per_m: 0.5,
        break_force_n: 3.0,
    };
    let links = vec![Link {
        a: 0,
        b: 1,
        rest_m: 0.01,
    }];
    let mut att = Attachment::new("tie", ModelId(0), ModelId(1), spring, links);
    let mut pts = Fixed(vec![
        vec![Vec3::ZERO],
        vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 0.015)],
    ]);
    let mut forces = two_forces();
    let mut events = Vec::new();
    att.apply(0.002, &pts, &mut forces, &mut events);
    // Stretched 5 mm at 200 N/m: 1 N pulling a toward b (+z); no damping on the first step.
    let on_a = forces.on(ModelId(0));
    let on_b = forces.on(ModelId(1));
    assert_eq!(on_a.len(), 1);
    assert_eq!(on_a[0].0, 0);
    assert!(
        (on_a[0].1 - Vec3::new(0.0, 0.0, 1.0)).length() < 1e-5,
        "{:?}",
        on_a[0].1
    );
    assert_eq!(on_b[0], (1, -on_a[0].1));
    // Lengthening 1 mm in a 2 ms step: damping adds 0.5 N s/m x 0.5 m/s = 0.25 N, spring 1.2 N.
    pts.0[1][1].z = 0.016;
    let mut forces = two_forces();
    att.apply(0.002, &pts, &mut forces, &mut events);
    assert!(
        (att.total_force().z - 1.45).abs() < 1e-4,
        "{}",
        att.total_force()
    );
    assert!(events.is_empty());
    // Pulled to 3.2 N (> 3 N) it tears, once.
    pts.0[1][1].z = 0.026;
    let mut forces = two_forces();
    att.apply(0.002, &pts, &mut forces, &mut events);
    assert_eq!(events.len(), 1);
    assert!(
        matches!(&events[0], EventKind::Rupture { what, force_n, .. } if what == "tie" && *force_n > 3.0)
    );
    assert_eq!(att.holding(), 0);
    assert!(forces.on(ModelId(0)).is_empty());
    att.apply(0.002, &pts, &mut forces, &mut events);
    assert_eq!(events.len(), 1);
}

#[test]
fn attached_balls_move_toward_each_other_by_mirror_image_amounts() {
    let mut world = World::new();
    let a = world.add(ball("a", Vec3::ZERO, 0.02));
    let b = world.add(ball("b", Vec3::new(0.06, 0.0, 0.0), 0.02));
    // The point of each ball facing the other, tied with a link 1 cm shorter than the gap.
    let facing = |id: ModelId, toward: Vec3, world: &World<SoftBody>| {
        let m = world.model(id);
        (0..m.mesh().len() as u32)
            .max_by(|&i, &j| {
                let (pi, pj) = (m.positions()[i as usize], m.positions()[j as usize]);
                pi.dot(toward).total_cmp(&pj.dot(toward))
            })
            .expect("points")
    };
    let pa = facing(a, Vec3::X, &world);
    let pb = facing(b, Vec3::NEG_X, &world);
    let gap =
        world.model(a).positions()[pa as usize].distance(world.model(b).positions()[pb as usize]);
    let spring = LinkSpring {
        stiffness_n_per_m: 100.0,
        damping_n_s_per_m: 0.0,
        break_force_n: f32::INFINITY,
    };
    world.add_interaction(Attachment::new(
        "bridge",
        a,
        b,
        spring,
        vec![Link {
            a: pa,
            b: pb,
            rest_m: gap - 0.01,
        }],
    ));
    let mut events = Vec::new();
    for step in 0..50 {
        world.step(0.002, step, &mut events);
    }
    let xa = world.model(a).positions()[pa as usize];
    let xb = world.model(b).positions()[pb as usize];
    let rest_a = world.model(a).mesh().rest[pa as usize];
    let rest_b = world.model(b).mesh().rest[pb as usize];
    assert!(
        xa.x > rest_a.x + 1e-6,
        "a's point moved toward b: {xa} from {rest_a}"
    );
    assert!(
        xb.x < rest_b.x - 1e-6,
        "b's point moved toward a: {xb} from {rest_b}"
    );
    // Symmetric balls, symmetric pull: mirror-image displacements.
    let (da, db) = (xa.x - rest_a.x, xb.x - rest_b.x);
    assert!((da + db).abs() < 1e-3 * da.abs(), "{da} vs {db}");
}

/// Models of different kinds share one world behind boxes: each steps with its own contacts,
/// the tool's reaction is the sum of what each did to it (in model order), and the world's
/// digest covers both.
#[test]
fn boxed_models_of_any_kind_share_one_world() {
    let mut world: World<Box<dyn TissueModel>> = World::new();
    let ball_id = world.add(Box::new(ball("boxed", Vec3::ZERO, 0.02)));
    let strand_id = world.add(Box::new(Strand::new()));
    // A 2 mm tip 1 mm into the strand's middle, held by the same hand as the press.
    let tip = Contact {
        tool: Hand::Right,
        point: Vec3::new(0.0, 0.05 + 0.0015 + 0.002 - 0.001, 0.0),
        normal: Vec3::Y,
        kind: ContactKind::Sphere { radius_m: 0.002 },
    };
    let start = world.state_hash();
    let mut events = Vec::new();
    for step in 0..3 {
        world.contact(ball_id, press(Vec3::ZERO, 0.02, 2000.0));
        world.contact(strand_id, tip);
        world.step(0.002, step, &mut events);
    }
    let from_ball = world.reactions_from(ball_id)[Hand::Right.index()];
    let from_strand = world.reactions_from(strand_id)[Hand::Right.index()];
    // Both push the tool back up, out of the tissue; the hand feels their sum.
    assert!(
        from_ball.y > 0.0 && from_strand.y > 0.0,
        "{from_ball} {from_strand}"
    );
    assert_eq!(world.reaction(Hand::Right), from_ball + from_strand);
    assert_eq!(world.reaction(Hand::Left), Vec3::ZERO);
    assert_eq!(
        (world.find("boxed"), world.find("strand")),
        (Some(ball_id), Some(strand_id))
    );
    let kinds: Vec<&str> = world.models().map(|(_, m)| m.kind()).collect();
    assert_eq!(kinds, ["simplex_soft_body", "test_strand"]);
    assert_ne!(world.state_hash(), start);
    // Beside the strand a ray goes on to the ball, whose top is 17.3 mm up 1 cm off its axis.
    let hit = world.cast_ray(Vec3::new(0.0, 0.1, 0.01), Vec3::NEG_Y, 1.0);
    assert!(hit.is_some_and(|(m, h)| m == ball_id && (h.distance_m - 0.0827).abs() < 2e-3));
}

/// A taut strand (a rod's collider: a centreline with a radius per point) that sags under a
/// sphere tool by the tool's depth; enough of a model to show the world's queries and
/// contacts reach a model that is no triangle mesh.
struct Strand {
    centreline: Vec<Vec3>,
    radii: Vec<f32>,
    regions: Vec<u8>,
    saved: Vec<Vec3>,
}

impl Strand {
    fn new() -> Self {
        // 10 cm along x at y = 0.05, 2 mm thick tapering to 1 mm; the far half is region 1.
        let centreline: Vec<Vec3> = (0..11)
            .map(|i| Vec3::new(-0.05 + 0.01 * i as f32, 0.05, 0.0))
            .collect();
        let radii = (0..11).map(|i| 0.002 - 0.0001 * i as f32).collect();
        let regions = (0..10).map(|i| u8::from(i >= 5)).collect();
        Self {
            saved: centreline.clone(),
            centreline,
            radii,
            regions,
        }
    }
}

impl TissueModel for Strand {
    fn name(&self) -> &str {
        "strand"
    }
    fn kind(&self) -> &'static str {
        "test_strand"
    }
    fn sizes(&self) -> crate::sim::ModelSizes {
        crate::sim::ModelSizes {
            vertices: self.centreline.len(),
            triangles: 0,
            constraints: 0,
        }
    }
    fn step(&mut self, _dt_s: f32, contacts: &[Contact], out: &mut crate::sim::ModelOutput) {
        for c in contacts {
            if let ContactKind::Sphere { radius_m } = c.kind {
                let tube = crate::collision::GeneralizedCylinder {
                    centreline: &self.centreline,
                    radii: &self.radii,
                };
                let touched = tube.sphere_contacts(c.point, radius_m);
                let push: Vec3 = touched.iter().map(|t| -t.normal * t.depth_m).sum();
                for t in &touched {
                    for k in [t.feature as usize, t.feature as usize + 1] {
                        self.centreline[k] += -t.normal * t.depth_m * 0.5;
                    }
                }
                // The strand pushes back like a 100 N/m spring.
                out.reactions.push((c.tool, -push * 100.0));
            }
        }
    }
    fn collider(&self) -> crate::sim::Collider<'_> {
        crate::sim::Collider::Tube(
            crate::collision::GeneralizedCylinder {
                centreline: &self.centreline,
                radii: &self.radii,
            },
            &self.regions,
        )
    }
    fn render_mesh(&mut self) -> ModelSnapshot {
        ModelSnapshot {
            name: "strand".into(),
            positions: self.centreline.clone(),
            normals: vec![Vec3::Y; self.centreline.len()],
            indices: Vec::new(),
            regions: Vec::new(),
            roles: Vec::new(),
            cut_edge: Vec::new(),
            seared: Vec::new(),
        }
    }
    fn checkpoint(&mut self) {
        self.saved.clone_from(&self.centreline);
    }
    fn restore(&mut self) {
        self.centreline.clone_from(&self.saved);
    }
    fn state_is_finite(&self) -> bool {
        self.centreline.iter().all(|p| p.is_finite())
    }
    fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        for p in &self.centreline {
            for c in p.to_array() {
                h.write(c.to_bits());
            }
        }
        h.0
    }
    fn point(&self, i: u32) -> Option<Vec3> {
        self.centreline.get(i as usize).copied()
    }
    fn inject_nan(&mut self) -> bool {
        self.centreline[0] = Vec3::NAN;
        true
    }
}

#[test]
fn rays_and_nearest_reach_every_kind_of_model_through_its_collider() {
    let mut world: World<Box<dyn TissueModel>> = World::new();
    let ball_id = world.add(Box::new(ball("ball", Vec3::ZERO, 0.02)));
    let strand_id = world.add(Box::new(Strand::new()));
    // Straight down at x = 0.025 the strand (radius 2 mm - 7.5 x 0.1 mm = 1.25 mm there,
    // segment 7) lies above the ball.
    let hit = world.cast_ray(Vec3::new(0.025, 0.1, 0.0), Vec3::NEG_Y, 1.0);
    let (id, h) = hit.expect("the strand is in the way");
    assert_eq!(id, strand_id);
    assert_eq!(h.feature, 7);
    assert!(
        (h.distance_m - (0.05 - 0.00125)).abs() < 2e-5,
        "{}",
        h.distance_m
    );
    assert_eq!(world.model(id).collider().region(h.feature), 1);
    // Beside the strand, the ray goes on to the ball's top (r = 2 cm; a level-2 icosphere's
    // flat facets sit up to 1 mm inside it).
    let (id, h) = world
        .cast_ray(Vec3::new(0.0, 0.1, 0.01), Vec3::NEG_Y, 1.0)
        .expect("the ball is below");
    assert_eq!(id, ball_id);
    assert!(h.distance_m > 0.1 - 0.0174 && h.distance_m < 0.1 - 0.0172 + 1.5e-3);
    // Nearest to a point just under the strand's first segment: the strand, 1 mm off.
    let (id, d, f) = world
        .nearest(Vec3::new(-0.045, 0.05 - 0.00295, 0.0), 0.005)
        .expect("something near");
    assert_eq!((id, f), (strand_id, 0));
    assert!((d - 0.001).abs() < 2e-5, "{d}");
    // A ball tip pressed 1 mm into the strand's middle pushes it and feels it.
    world.contact(
        strand_id,
        Contact {
            tool: Hand::Left,
            point: Vec3::new(0.0, 0.05 + 0.0015 + 0.002 - 0.001, 0.0),
            normal: Vec3::Y,
            kind: ContactKind::Sphere { radius_m: 0.002 },
        },
    );
    let before = world.model(strand_id).point(5).expect("a point");
    let mut events = Vec::new();
    world.step(0.002, 0, &mut events);
    let after = world.model(strand_id).point(5).expect("a point");
    assert!(after.y < before.y, "{before} -> {after}");
    assert!(
        world.reaction(Hand::Left).y > 0.0,
        "{}",
        world.reaction(Hand::Left)
    );
}
