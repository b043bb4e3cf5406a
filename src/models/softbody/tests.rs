//! The soft body's behaviour: cuts, ties, quarantine, BVH, presses, tips and grasps.

use super::*;
use crate::mesh::icosphere;
use crate::sim::Quarantine;

fn ball(level: u32, radius: f32, at: Vec3) -> crate::mesh::TriMesh {
    let mut m = icosphere(level);
    for p in &mut m.positions {
        *p = at + *p * radius;
    }
    m
}

fn body_of(m: &crate::mesh::TriMesh, regions: Vec<u8>) -> SoftBody {
    let s = SimplexMesh::dual(m).expect("closed mesh");
    SoftBody::new("test", s, regions, SoftBodyParams::default())
}

/// The point farthest along `dir`.
fn farthest(b: &SoftBody, dir: Vec3) -> usize {
    (0..b.mesh().len())
        .max_by(|&i, &j| b.x[i].dot(dir).total_cmp(&b.x[j].dot(dir)))
        .unwrap_or(0)
}

#[test]
fn a_closed_band_of_cut_faces_splits_connectivity() {
    let m = ball(3, 0.03, Vec3::ZERO);
    let mut b = body_of(&m, vec![0; m.triangle_count()]);
    let north = farthest(&b, Vec3::Y);
    let south = farthest(&b, -Vec3::Y);
    b.refresh_topology();
    assert_eq!(b.components()[north], b.components()[south]);
    let band: Vec<u32> = (0..b.mesh().len() as u32)
        .filter(|&f| b.x[f as usize].y.abs() < 0.003)
        .collect();
    let mut out = ModelOutput::default();
    b.cut(
        &CutStroke {
            faces: band.clone(),
        },
        &mut out,
    );
    b.refresh_topology();
    assert_ne!(b.components()[north], b.components()[south]);
    // One half keeps its anchors, the other floats free.
    assert_ne!(b.is_anchored(north), b.is_anchored(south));
    assert!(band.iter().all(|&f| !b.alive()[f as usize]));
    // A cut that does not close the loop leaves one piece.
    let mut c = body_of(&m, vec![0; m.triangle_count()]);
    let open: Vec<u32> = band
        .iter()
        .copied()
        .filter(|&f| c.x[f as usize].x < 0.02)
        .collect();
    c.cut(&CutStroke { faces: open }, &mut out);
    c.refresh_topology();
    assert_eq!(c.components()[north], c.components()[south]);
}

/// Two balls tied by one tie; the second is moved rigidly by `stretch_m` and stepped once.
fn tie_after_stretch(stretch_m: f32) -> bool {
    let mut m = ball(1, 0.01, Vec3::ZERO);
    let n0 = m.triangle_count();
    m.append(&ball(1, 0.01, Vec3::new(0.03, 0.0, 0.0)));
    let mut regions = vec![0u8; n0];
    regions.extend(std::iter::repeat_n(1u8, m.triangle_count() - n0));
    let mut b = body_of(&m, regions.clone());
    let (a, c) = {
        let x = b.positions();
        let a = (0..n0)
            .max_by(|&i, &j| x[i].x.total_cmp(&x[j].x))
            .unwrap_or(0);
        let c = (n0..x.len())
            .min_by(|&i, &j| x[i].x.total_cmp(&x[j].x))
            .unwrap_or(0);
        (a, c)
    };
    let rest = (b.positions()[a] - b.positions()[c]).length();
    b.set_ties(vec![Tie {
        a: a as u32,
        b: c as u32,
        rest_m: rest,
        alive: true,
    }]);
    for i in n0..b.positions().len() {
        let p = b.positions()[i] + Vec3::new(stretch_m, 0.0, 0.0);
        b.set_position(i, p);
    }
    let mut out = ModelOutput::default();
    b.step(0.002, &[], &mut out);
    let broke = out
        .events
        .iter()
        .any(|e| matches!(e, EventKind::TieBroken { .. }));
    assert_eq!(broke, !b.ties()[0].alive);
    b.ties()[0].alive
}

#[test]
fn a_tie_breaks_at_its_threshold_and_not_below() {
    let p = SoftBodyParams::default();
    // A tie tears where its force over its area, stiffness x stretch, passes its strength.
    let at_threshold = p.tie_strength_pa / p.tie_stiffness_pa_per_m;
    assert!(
        tie_after_stretch(0.9 * at_threshold),
        "tie broke below its threshold"
    );
    assert!(
        !tie_after_stretch(1.1 * at_threshold),
        "tie held above its threshold"
    );
}

#[test]
fn an_injected_nan_is_quarantined_rolled_back_and_reported() {
    let m = ball(2, 0.02, Vec3::ZERO);
    let mut b = body_of(&m, vec![0; m.triangle_count()]);
    let mut guard = Quarantine::new(4);
    let mut out = ModelOutput::default();
    let press = [Contact {
        tool: ToolId::Right,
        point: Vec3::new(0.0, 0.0, 0.02),
        normal: Vec3::Z,
        kind: ContactKind::Press {
            pressure_pa: 1500.0,
            area_m2: 1e-4,
        },
    }];
    for step in 1..=8 {
        b.step(0.002, &press, &mut out);
        assert!(guard.after_step(&mut b, step).is_none());
    }
    let good = b.positions().to_vec();
    b.set_position(5, Vec3::new(f32::NAN, 0.0, 0.0));
    b.step(0.002, &press, &mut out);
    let event = guard.after_step(&mut b, 9);
    assert_eq!(
        event,
        Some(EventKind::Quarantined {
            model: "test".into(),
            restored_step: 8
        })
    );
    assert!(guard.is_frozen());
    assert!(b.positions().iter().all(|p| p.is_finite()));
    assert_eq!(b.positions(), &good[..]);
}

/// Every live face is found by a BVH query for the centre of its own box: each ancestor
/// on its path must contain that point, which stale ancestors after a move do not.
fn bvh_bounds_every_live_face(b: &SoftBody) -> bool {
    (0..b.mesh().len()).filter(|&f| b.alive()[f]).all(|f| {
        let c = b.leaf_aabb(f).center();
        let q = Aabb::new(c, c);
        b.bvh.faces_in(&q).any(|l| l as usize == f)
    })
}

#[test]
fn the_bvh_follows_deformation_through_partial_and_full_refits() {
    let m = ball(3, 0.03, Vec3::ZERO);
    let mut b = body_of(&m, vec![0; m.triangle_count()]);
    let mut out = ModelOutput::default();
    let dt = 0.002;
    // A 4 mm tip pressed 6 mm into the top and dragged sideways: leaves grow past their
    // margin every step (partial refits).
    let top = b.positions()[farthest(&b, Vec3::Z)];
    let tip_at = |k: usize| {
        let s = k as f32 * dt;
        [Contact {
            tool: ToolId::Left,
            point: top + Vec3::new(0.02 * s, 0.0, 0.004 - (0.03 * s).min(0.006)),
            normal: Vec3::Z,
            kind: ContactKind::Sphere { radius_m: 0.004 },
        }]
    };
    for k in 0..300 {
        b.step(dt, &tip_at(k), &mut out);
        if k % 50 == 49 {
            assert!(bvh_bounds_every_live_face(&b), "step {k}");
        }
    }
    let moved = (0..b.mesh().len())
        .map(|i| (b.positions()[i] - b.mesh.rest[i]).length())
        .fold(0.0, f32::max);
    assert!(
        moved > 2.0 * BVH_MARGIN_M,
        "the tip moved the surface {moved} m"
    );
    // A cut removes leaves (whole-tree refit), then the drag goes on (partial again).
    let band: Vec<u32> = (0..b.mesh().len() as u32)
        .filter(|&f| b.x[f as usize].y.abs() < 0.002 && b.x[f as usize].x < 0.0)
        .collect();
    b.cut(&CutStroke { faces: band }, &mut out);
    for k in 300..400 {
        b.step(dt, &tip_at(k), &mut out);
    }
    assert!(bvh_bounds_every_live_face(&b));
    let removed = (0..b.mesh().len()).filter(|&f| !b.alive()[f]).count();
    assert!(removed > 0);
    let root = b.bvh.root_aabb();
    let listed: Vec<u32> = b.bvh.faces_in(&root).collect();
    assert!(
        listed.iter().any(|&f| !b.alive()[f as usize]),
        "a partly cut patch stays"
    );
    let whole = (0..b.mesh().len()).filter(|&f| b.alive()[f]).count();
    assert_eq!(
        listed.iter().filter(|&&f| b.alive()[f as usize]).count(),
        whole,
        "every live face is in the tree once"
    );
}

#[test]
fn a_press_dents_the_surface_and_it_springs_back() {
    let m = ball(3, 0.03, Vec3::ZERO);
    let mut b = body_of(&m, vec![0; m.triangle_count()]);
    let top = farthest(&b, Vec3::Z);
    let z0 = b.positions()[top].z;
    let press = [Contact {
        tool: ToolId::Right,
        point: b.positions()[top],
        normal: Vec3::Z,
        kind: ContactKind::Press {
            pressure_pa: 1500.0,
            area_m2: 1e-4,
        },
    }];
    let mut out = ModelOutput::default();
    for _ in 0..500 {
        b.step(0.002, &press, &mut out);
    }
    let dent = z0 - b.positions()[top].z;
    // The membrane (1000 N/m edges) and the gas pressure share the load with the anchors.
    assert!(dent > 2e-5 && dent < 5e-3, "dent {dent}");
    for _ in 0..3000 {
        b.step(0.002, &[], &mut out);
    }
    assert!((b.positions()[top].z - z0).abs() < 1e-6);
    assert_eq!(b.awake_count(), 0, "everything settles and sleeps");
}

#[test]
fn a_tip_feels_the_tissue_push_back_harder_the_deeper_it_presses() {
    // A 3 mm tip held at depths below the top of an anchored 3 cm ball, 0.6 s each: the
    // tissue tents ahead of it, and the reaction points out of the surface, is zero
    // before contact and after, and grows with depth (more points, each further).
    let m = ball(4, 0.03, Vec3::ZERO);
    let mut b = body_of(&m, vec![0; m.triangle_count()]);
    let top = b.positions()[farthest(&b, Vec3::Z)];
    let r = 0.003;
    let mut out = ModelOutput::default();
    let mut held = |b: &mut SoftBody, depth: f32| {
        let c = [Contact {
            tool: ToolId::Left,
            point: top + Vec3::Z * (r - depth),
            normal: Vec3::Z,
            kind: ContactKind::Sphere { radius_m: r },
        }];
        let mut f = Vec3::ZERO;
        for _ in 0..300 {
            out.clear();
            b.step(0.002, &c, &mut out);
            f = out.reactions.iter().map(|(_, f)| *f).sum();
        }
        f
    };
    assert_eq!(held(&mut b, -0.0005), Vec3::ZERO, "half a millimetre above");
    let forces: Vec<Vec3> = [0.0005, 0.001, 0.002, 0.003]
        .iter()
        .map(|&d| held(&mut b, d))
        .collect();
    for w in forces.windows(2) {
        assert!(w[1].length() > w[0].length(), "{forces:?}");
    }
    for f in &forces {
        // Out of the surface, give or take the mesh's unevenness under a 3 mm tip.
        assert!(f.z > 0.8 * f.length(), "{f} points out of the surface");
    }
    assert!(forces[3].length() > 3.0 * forces[1].length(), "{forces:?}");
    assert_eq!(held(&mut b, -0.02), Vec3::ZERO, "withdrawn");
}

#[test]
fn a_free_ball_pushed_by_a_tip_stays_whole() {
    // A free tumour-sized ball (no anchor region) shoved by a 3 mm tip at 9 cm/s.
    let m = ball(5, 0.02, Vec3::ZERO);
    let mut b = body_of(&m, vec![1; m.triangle_count()]);
    let params = SoftBodyParams {
        foundation_pa_per_m: 4e6,
        volume_stiffness_pa: 4000.0,
        ..SoftBodyParams::default()
    };
    b.params = params;
    let mut out = ModelOutput::default();
    let mut worst = 0.0f32;
    let dt = 0.002;
    for k in 0..800 {
        let depth = (k as f32 * dt * 0.09).min(0.012);
        let tip = Vec3::new(0.0, 0.0, 0.02 + 0.003 - depth);
        let c = [Contact {
            tool: ToolId::Left,
            point: tip,
            normal: Vec3::Z,
            kind: ContactKind::Sphere { radius_m: 0.003 },
        }];
        b.step(dt, &c, &mut out);
        let v = b.v.iter().map(|v| v.length()).fold(0.0, f32::max);
        worst = worst.max(v);
    }
    assert!(b.state_is_finite());
    assert!(worst < 0.5, "fastest point {worst} m/s");
}

#[test]
fn a_grasped_free_piece_follows_the_grasper_and_keeps_its_shape() {
    let m = ball(4, 0.02, Vec3::ZERO);
    let mut b = body_of(&m, vec![1; m.triangle_count()]);
    let top = farthest(&b, Vec3::Z);
    let grip = b.positions()[top];
    let rest_centre: Vec3 = b.positions().iter().sum::<Vec3>() / b.mesh().len() as f32;
    let mut out = ModelOutput::default();
    let dt = 0.002;
    // Grip, then lift 4 cm in 1 s and hold for 1 s.
    for k in 0..1000 {
        let lift = (k as f32 * dt).min(1.0) * 0.04;
        let c = [Contact {
            tool: ToolId::Left,
            point: grip + Vec3::Z * lift,
            normal: Vec3::Z,
            kind: ContactKind::Grasp {
                rotation: Quat::IDENTITY,
                radius_m: 0.006,
            },
        }];
        b.step(dt, &c, &mut out);
    }
    assert!(b.state_is_finite());
    let centre: Vec3 = b.positions().iter().sum::<Vec3>() / b.mesh().len() as f32;
    let rise = centre.z - rest_centre.z;
    assert!((rise - 0.04).abs() < 0.004, "centre rose {rise} m of 0.04");
    // Still a ball: every point within 10 % of the radius from the centre.
    let worst = b
        .positions()
        .iter()
        .map(|p| ((*p - centre).length() - 0.02).abs())
        .fold(0.0, f32::max);
    assert!(worst < 0.002, "shape error {worst} m");
}

/// A closed surface painted in two regions is still one body of gas: one pressure group whose
/// rest volume is the ball's (4/3 pi r^3), wherever the ball is (a region alone would be an
/// open patch whose divergence "volume" depends on the origin).
#[test]
fn the_regions_of_one_closed_surface_share_its_gas() {
    let r = 0.02f32;
    let m = ball(3, r, Vec3::new(0.05, 0.01, -0.03));
    let s = SimplexMesh::dual(&m).expect("closed mesh");
    let regions: Vec<u8> = s.rest.iter().map(|p| u8::from(p.z > -0.03)).collect();
    assert!(regions.contains(&0) && regions.contains(&1));
    let mut b = SoftBody::new("test", s, regions, SoftBodyParams::default());
    b.update_topology();
    let g = b.pressure_group[0];
    assert!(b.pressure_group.iter().all(|&q| q == g), "one group");
    let ball_volume = 4.0 / 3.0 * std::f32::consts::PI * r * r * r;
    let v = b.rest_volume[g as usize];
    assert!(
        (v - ball_volume).abs() < 0.03 * ball_volume,
        "{v} vs {ball_volume} m^3"
    );
}

/// A 3 cm ball of 5120 points, every point awake, pressed and cut on a pool of `threads`:
/// its state hash and the tip's reaction. Big enough that the implicit rows, the normals and
/// the CG sums are split into several parallel tasks, and the projection into its blocks.
fn pressed_ball_on(threads: usize) -> (u64, [u32; 3]) {
    crate::sim::on_threads(threads, || {
        let m = ball(4, 0.03, Vec3::ZERO);
        let mut b = body_of(&m, vec![0; m.triangle_count()]);
        b.stay_awake();
        let top = b.positions()[farthest(&b, Vec3::Z)];
        let tip = [Contact {
            tool: ToolId::Left,
            point: top + Vec3::Z * (0.003 - 0.001),
            normal: Vec3::Z,
            kind: ContactKind::Sphere { radius_m: 0.003 },
        }];
        let mut out = ModelOutput::default();
        let side: Vec<u32> = (0..b.mesh().len() as u32)
            .filter(|&f| b.positions()[f as usize].x > 0.027)
            .collect();
        let mut f = Vec3::ZERO;
        for k in 0..60 {
            out.clear();
            if k == 20 {
                b.cut(
                    &CutStroke {
                        faces: side.clone(),
                    },
                    &mut out,
                );
            }
            b.step(0.004, &tip, &mut out);
            f = out.reactions.iter().map(|(_, f)| *f).sum();
        }
        (b.state_hash(), f.to_array().map(f32::to_bits))
    })
}

#[test]
fn one_or_two_threads_step_a_large_awake_body_to_the_same_bits() {
    let one = pressed_ball_on(1);
    assert_eq!(one, pressed_ball_on(2));
    // The tip did press: a reaction out of the surface.
    let f = Vec3::from_array(one.1.map(f32::from_bits));
    assert!(f.z > 0.0, "reaction {f}");
}

/// Collision's ray cast against a soft body's surface.
#[test]
fn ray_hits_the_near_side_of_a_sphere_at_its_radius() {
    let mut m = icosphere(3);
    for p in &mut m.positions {
        *p *= 0.05;
    }
    let s = SimplexMesh::dual(&m).expect("dual");
    let n = s.len();
    let body = SoftBody::new("ball", s, vec![0; n], SoftBodyParams::default());
    let view = crate::sim::TissueModel::collider(&body);
    let hit = view
        .cast_ray(Vec3::new(0.0, 0.0, 0.2), Vec3::NEG_Z, 1.0)
        .expect("hit");
    // The flat facets sit just inside the sphere: 0.15 m to 0.1503 m away.
    assert!(
        hit.distance_m > 0.1495 && hit.distance_m < 0.151,
        "{}",
        hit.distance_m
    );
    assert!(hit.normal.z > 0.9);
    assert!(
        view.cast_ray(Vec3::new(0.0, 0.2, 0.2), Vec3::NEG_Z, 1.0)
            .is_none()
    );
}

/// A live tuning of a soft body's table is checked against its sliders' ranges.
#[test]
fn live_values_are_checked_against_their_sliders() {
    let ok = [("foundation_pa_per_m".to_string(), 2e6)];
    assert!(crate::params::check_tuning::<SoftBodyParams>("tissue", &ok).is_ok());
    let high = [("foundation_pa_per_m".to_string(), 2e7)];
    let e = crate::params::check_tuning::<SoftBodyParams>("tissue", &high)
        .expect_err("above")
        .to_string();
    assert!(
        e.contains("tissue.foundation_pa_per_m") && e.contains("10000000"),
        "{e}"
    );
    let fixed = [("falloff_m".to_string(), 0.01)];
    let e = crate::params::check_tuning::<SoftBodyParams>("tissue", &fixed).expect_err("fixed");
    assert!(matches!(e, crate::params::TuneError::Fixed { .. }), "{e}");
}

/// The snapshot keeps its points' normals from one frame to the next and finds again only
/// those that moved: through a press, a cut and a rollback it draws what finding every
/// normal afresh draws, bit for bit.
#[test]
fn a_snapshot_that_keeps_its_normals_draws_what_a_fresh_one_draws() {
    let m = ball(4, 0.03, Vec3::ZERO);
    let mut b = body_of(&m, vec![0; m.triangle_count()]);
    let top = b.positions()[farthest(&b, Vec3::Z)];
    let tip = [Contact {
        tool: ToolId::Left,
        point: top + Vec3::Z * (0.003 - 0.0015),
        normal: Vec3::Z,
        kind: ContactKind::Sphere { radius_m: 0.003 },
    }];
    let side: Vec<u32> = (0..b.mesh().len() as u32)
        .filter(|&f| b.positions()[f as usize].z > 0.026)
        .collect();
    let bits = |v: &[Vec3]| -> Vec<[u32; 3]> {
        v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
    };
    let mut out = ModelOutput::default();
    let mut moved_between = 0;
    let mut last = b.render_mesh();
    let mut pending: Option<(crate::sim::MeshJob, ModelSnapshot)> = None;
    for k in 0..48 {
        out.clear();
        match k {
            10 => b.checkpoint(),
            20 => b.cut(
                &CutStroke {
                    faces: side.clone(),
                },
                &mut out,
            ),
            30 => b.restore(),
            _ => {}
        }
        b.step(0.004, if k < 36 { &tip } else { &[] }, &mut out);
        if k % 3 != 2 {
            continue;
        }
        // A job handed over before the last step is built on another thread now: it draws
        // the body as it was then, as the snapshot taken at once did.
        if let Some((job, then)) = pending.take() {
            let built = std::thread::spawn(move || crate::sim::MeshJob::build(job))
                .join()
                .unwrap();
            assert_eq!(bits(&built.positions), bits(&then.positions), "step {k}");
            assert_eq!(bits(&built.normals), bits(&then.normals), "step {k}");
            assert_eq!(built.indices, then.indices, "step {k}");
            assert_eq!(built.cut_edge, then.cut_edge, "step {k}");
        }
        let job = b.render_job();
        let kept = b.render_mesh();
        let cache = std::mem::take(&mut *b.drawn_normals());
        let fresh = b.render_mesh();
        *b.drawn_normals() = cache;
        assert_eq!(bits(&kept.positions), bits(&fresh.positions), "step {k}");
        assert_eq!(bits(&kept.normals), bits(&fresh.normals), "step {k}");
        assert_eq!(kept.indices, fresh.indices, "step {k}");
        if kept.positions.len() == last.positions.len() {
            moved_between += kept
                .positions
                .iter()
                .zip(&last.positions)
                .filter(|(a, b)| a != b)
                .count();
        }
        pending = Some((job, kept.clone()));
        last = kept;
    }
    assert!(pending.is_some());
    // The press moved the drawn surface between frames: the kept normals were put to work.
    assert!(moved_between > 0);
}
