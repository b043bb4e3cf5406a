//! Layer 0's loads summed by group (`anchor_sums.rs`) against the loads node by node
//! ([`Membrane::anchor_loads`]), on the CPU and on whatever Vulkan adapter there is (CI:
//! lavapipe).

use super::*;
use glam::DVec3;

/// The sleepy tube of the active-set tests, 48 x 64 (6 x 4 tiles), its layer-0 nodes in one
/// group per four rows, each weighted by its place across its group's rows; the groups'
/// points on the tube's axis.
fn grouped() -> Membrane {
    let mut p = super::tests::params(Integrator::Symplectic);
    p.gravity = Vec3::ZERO;
    p.damping_per_s = 20.0;
    let (rows, cols) = (48, 64);
    let length = 0.032 * rows as f32 / 128.0;
    let shape = super::tests::tube(rows, cols, length, [0.01, 0.012, 0.013, 0.016]);
    let mut m = Membrane::new(shape, p).expect("membrane");
    m.use_active_set(ActivityParams::default());
    let groups = rows / 4;
    let members: Vec<_> = (0..rows)
        .flat_map(|i| (0..cols).map(move |j| (i, j, i / 4, (i % 4) as f32 / 3.0)))
        .collect();
    let about: Vec<Vec3> = (0..groups)
        .map(|g| Vec3::new(length * (g as f32 + 0.5) / groups as f32, 0.0, 0.0))
        .collect();
    m.group_anchor_loads(&members, &about)
        .expect("valid groups");
    m
}

/// Step `k`: a tool near layer 0's node at row 24, column 32 pushes it and layer 1's beside
/// it for 30 steps (waking the tiles around), then lets go.
fn push(m: &mut Membrane, k: usize) {
    if k < 30 {
        let (a, b) = (m.node(0, 24, 32), m.node(1, 26, 30));
        m.read_tiles(&[m.tile_of(24, 32)]);
        let p = m.position(a);
        m.wake_near(&[(p - Vec3::splat(1e-3), p + Vec3::splat(1e-3))]);
        m.add_force(a, Vec3::new(3e-4, -2e-4, 1e-4));
        m.add_force(b, Vec3::new(-1e-4, 0.0, 2e-4));
    }
}

/// What the step about to run on `m` will sum, node by node from [`Membrane::anchor_loads`]
/// on a copy (its sleeping tiles placed, as the step places those beside the awake ones),
/// with the couple about the axis from `a` to `b` of each group, taken node by node.
fn node_by_node(m: &Membrane, groups: usize, a: DVec3, b: DVec3) -> (Vec<AnchorSum>, Vec<DVec3>) {
    let mut r = m.clone();
    r.place_sleeping();
    let (tr, tc) = r.tiles();
    let awake: Vec<usize> = (0..tr * tc).filter(|&t| r.tile_awake(t)).collect();
    let mut loads = Vec::new();
    r.anchor_loads(&awake, &mut loads);
    let mut sums = vec![AnchorSum::default(); groups];
    let mut couples = vec![DVec3::ZERO; groups];
    let length = 0.032 * 48.0 / 128.0;
    for (i, j, f) in loads {
        let (i, j) = (i as usize, j as usize);
        let (g, u) = (i / 4, f64::from((i % 4) as f32 / 3.0));
        let about = DVec3::new(
            f64::from(length * (g as f32 + 0.5) / groups as f32),
            0.0,
            0.0,
        );
        let (target, _) = r.anchor_pull(i, j).expect("in the grid");
        let (f, t) = (f.as_dvec3(), target.as_dvec3());
        let k = f64::from(r.anchor_stiffness(i, j));
        let s = &mut sums[g];
        s.force += f;
        s.weighted_force += u * f;
        s.moment += (t - about).cross(f);
        s.stiffness += k;
        s.weighted_stiffness += u * k;
        couples[g] += (t - (a + (b - a) * u)).cross(f);
    }
    (sums, couples)
}

/// The largest difference between two lists of vectors, over the largest of the second.
fn vec_error(a: impl Iterator<Item = DVec3>, b: impl Iterator<Item = DVec3>) -> f64 {
    let (mut diff, mut most) = (0.0f64, 0.0f64);
    for (x, y) in a.zip(b) {
        diff = diff.max((x - y).length());
        most = most.max(y.length());
    }
    diff / most.max(f64::MIN_POSITIVE)
}

/// Runs the pushing session on `m` for 40 steps, comparing each step's sums with the node-by-
/// node ones: the largest relative differences of the forces, the weighted forces, the
/// moments, the couples about an axis rebuilt from the sums, and the stiffness.
fn compare(m: &mut Membrane) -> [f64; 5] {
    let groups = 12;
    let (a, b) = (
        DVec3::new(0.001, 0.002, -0.001),
        DVec3::new(0.004, 0.001, 0.0),
    );
    let mut worst = [0.0f64; 5];
    let mut out = crate::sim::ModelOutput::default();
    let mut loaded = 0;
    for k in 0..40 {
        push(m, k);
        // The copy node by node takes every awake tile as the device has it.
        m.catch_up();
        let (want, couples) = node_by_node(m, groups, a, b);
        out.clear();
        crate::sim::TissueModel::step(m, 1e-3, &[], &mut out);
        assert!(out.events.is_empty(), "{:?}", out.events);
        let got = m.anchor_sums();
        assert_eq!(got.len(), groups);
        let length = 0.032 * 48.0 / 128.0;
        let rebuilt = got.iter().enumerate().map(|(g, s)| {
            let p = DVec3::new(f64::from(length * (g as f32 + 0.5) / 12.0), 0.0, 0.0);
            s.moment + (p - a).cross(s.force) - (b - a).cross(s.weighted_force)
        });
        let errs = [
            vec_error(got.iter().map(|s| s.force), want.iter().map(|s| s.force)),
            vec_error(
                got.iter().map(|s| s.weighted_force),
                want.iter().map(|s| s.weighted_force),
            ),
            vec_error(got.iter().map(|s| s.moment), want.iter().map(|s| s.moment)),
            vec_error(rebuilt, couples.iter().copied()),
            vec_error(
                got.iter()
                    .map(|s| DVec3::new(s.stiffness, s.weighted_stiffness, 0.0)),
                want.iter()
                    .map(|s| DVec3::new(s.stiffness, s.weighted_stiffness, 0.0)),
            ),
        ];
        for (w, e) in worst.iter_mut().zip(errs) {
            *w = w.max(e);
        }
        if want.iter().any(|s| s.force.length() > 1e-5) {
            loaded += 1;
        }
    }
    assert!(loaded >= 20, "the push loaded layer 0 in {loaded} steps");
    worst
}

#[test]
fn the_loads_summed_by_group_are_the_loads_node_by_node() {
    let mut m = grouped();
    let worst = compare(&mut m);
    // The same loads in the same order, in f64: rounding of the last bits only. The couple
    // about an axis rebuilt from the moment, the sum and the weighted sum is the couple
    // taken node by node.
    for (what, e) in ["force", "weighted force", "moment", "couple", "stiffness"]
        .iter()
        .zip(worst)
    {
        assert!(e < 1e-12, "{what}: {e:e}");
    }
}

#[test]
fn the_device_sums_the_loads_as_the_cpu_does() {
    let gpu = crate::gpu::Gpu::headless(false).expect("a Vulkan adapter");
    let mut m = grouped();
    m.use_gpu(&gpu).expect("uploads");
    let worst = compare(&mut m);
    assert!(m.gpu_adapter().is_some(), "it stayed on the device");
    // f32 loads summed in f32 in another order: lavapipe differs by 2e-7 of the largest.
    for (what, e) in ["force", "weighted force", "moment", "couple", "stiffness"]
        .iter()
        .zip(worst)
    {
        assert!(e < 1e-5, "{what}: {e:e}");
    }
}

#[test]
fn bad_groups_are_refused_with_the_member_and_why() {
    let mut m = grouped();
    let before = m.anchor_sums().to_vec();
    let about = [Vec3::ZERO];
    for (members, says) in [
        (vec![(0, 0, 0, 0.5), (48, 0, 0, 0.5)], "outside 48 x 64"),
        (vec![(0, 0, 1, 0.5)], "group 1 has no point"),
        (vec![(0, 0, 0, 1.5)], "not in [0, 1]"),
        (vec![(0, 0, 0, 0.5), (0, 0, 0, 0.2)], "in a group already"),
    ] {
        let e = m
            .group_anchor_loads(&members, &about)
            .expect_err("refused")
            .to_string();
        assert!(e.contains(says), "{e}");
    }
    let e = m
        .group_anchor_loads(&[], &[Vec3::NAN])
        .expect_err("refused")
        .to_string();
    assert!(e.contains("not finite"), "{e}");
    assert_eq!(m.anchor_sums(), &before[..], "left as it was");
}
