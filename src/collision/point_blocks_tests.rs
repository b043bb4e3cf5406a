//! The broad phase against the brute-force test, block refreshes and thread counts.

use super::*;
use crate::collision::tool_cylinder::{Instrument, ToolCylinder};

const MM: f32 = 1e-3;

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// The orientation that points the instrument (local -Z) along `dir`.
fn aiming(dir: glam::Vec3) -> glam::Quat {
    glam::Quat::from_rotation_arc(Vec3::NEG_Z, dir.normalize())
}

use crate::collision::test_support::Lcg;

/// A 101 x 101 sheet over [-50, 50] mm in x and y, 1 mm apart, row-major (x fastest), each point
/// jittered by up to ±0.3 mm in x and y and ±0.5 mm in z.
fn jittered_sheet() -> Vec<Vec3> {
    let mut rng = Lcg(7);
    let mut pts = Vec::with_capacity(101 * 101);
    for j in 0..101 {
        for i in 0..101 {
            let x = (i as f32 - 50.0 + 0.6 * (rng.next() - 0.5)) * MM;
            let y = (j as f32 - 50.0 + 0.6 * (rng.next() - 0.5)) * MM;
            let z = (rng.next() - 0.5) * MM;
            pts.push(v(x, y, z));
        }
    }
    pts
}

/// One vector per coordinate of `pts` (the membrane's layout).
fn components(pts: &[Vec3]) -> [Vec<f32>; 3] {
    [0, 1, 2].map(|k| pts.iter().map(|p| p[k]).collect())
}

// ---------------------------------------------------------------------------- broad phase

fn poses() -> Vec<(&'static str, Instrument)> {
    vec![
        (
            "hook, steep",
            Instrument::l_hook(v(0.0, 0.0, -6.0 * MM), aiming(v(0.3, 0.2, -1.0))).expect("valid"),
        ),
        (
            "hook, 60° from vertical",
            Instrument::l_hook(v(0.02, -0.03, -2.0 * MM), aiming(v(0.87, 0.0, -0.5)))
                .expect("valid"),
        ),
        (
            "grasper, open 40°",
            Instrument::grasper(v(-0.01, 0.015, 3.0 * MM), aiming(v(1.0, 0.0, -1.0)), 0.7)
                .expect("valid"),
        ),
        (
            "grasper, almost flat across the sheet",
            Instrument::grasper(v(0.04, 0.01, -MM), aiming(v(1.0, 0.3, -0.05)), 0.3)
                .expect("valid"),
        ),
        (
            "hook, far above",
            Instrument::l_hook(v(0.0, 0.0, 0.05), aiming(v(0.0, 0.0, -1.0))).expect("valid"),
        ),
    ]
}

#[test]
fn broad_phase_finds_exactly_the_brute_force_contacts_and_examines_fewer_points() {
    let pts = jittered_sheet();
    let cloud = PointCloud::from_points(&pts);
    let blocks = PointBlocks::new(cloud);
    assert_eq!(blocks.block_count(), pts.len().div_ceil(BLOCK_POINTS));
    let (mut broad, mut brute) = (Vec::new(), Vec::new());
    for (name, tool) in poses() {
        let stats = tool
            .contacts(cloud, &blocks, &mut broad)
            .expect("fresh blocks");
        let all = tool.contacts_all(cloud, &mut brute);
        println!(
            "{name}: {} contacts; examined {} of {} points ({} of {} blocks)",
            broad.len(),
            stats.points_examined,
            all.points_examined,
            stats.blocks_examined,
            all.blocks_examined
        );
        assert_eq!(broad, brute, "{name}");
        assert!(
            broad.windows(2).all(|w| w[0].vertex < w[1].vertex),
            "{name}: ascending"
        );
        if name.contains("far") {
            assert!(broad.is_empty());
            assert_eq!(stats.points_examined, 0, "{name}");
        } else if !name.contains("flat") {
            assert!(!broad.is_empty(), "{name}");
            assert!(stats.points_examined * 4 < pts.len(), "{name}: {stats:?}");
        }
    }

    // A cloud in random order, where blocks prune little: still the same contacts, and the
    // same again from one slice per coordinate.
    let mut rng = Lcg(42);
    let cloud_pts: Vec<Vec3> = (0..4000)
        .map(|_| (v(rng.next(), rng.next(), rng.next()) - Vec3::splat(0.5)) * 0.03)
        .collect();
    let [x, y, z] = components(&cloud_pts);
    let soa = PointCloud::from_components(&x, &y, &z).expect("same lengths");
    let aos = PointCloud::from_points(&cloud_pts);
    let blocks = PointBlocks::new(soa);
    let mut from_soa = Vec::new();
    let tools = [
        Instrument::l_hook(v(0.001, 0.002, 0.0), aiming(v(-0.2, 0.5, -1.0))).expect("valid"),
        Instrument::grasper(v(-0.005, 0.0, 0.004), aiming(v(0.0, 1.0, -0.3)), 1.0).expect("valid"),
    ];
    for tool in &tools {
        tool.contacts(aos, &blocks, &mut broad)
            .expect("fresh blocks");
        tool.contacts(soa, &blocks, &mut from_soa)
            .expect("fresh blocks");
        tool.contacts_all(aos, &mut brute);
        assert!(!brute.is_empty());
        assert_eq!(broad, brute);
        assert_eq!(from_soa, brute);
    }
}

#[test]
fn refreshing_one_block_brings_its_moved_points_into_the_query() {
    let mut pts = jittered_sheet();
    let mut blocks = PointBlocks::new(PointCloud::from_points(&pts));
    // A rod along x, 5 mm above the sheet over the rows of block 3 (y about -42 to -40 mm).
    let tool = Instrument::new(vec![
        ToolCylinder::constant(
            v(-0.04, -0.041, 5.0 * MM),
            v(0.04, -0.041, 5.0 * MM),
            2.5 * MM,
        )
        .expect("valid"),
    ])
    .expect("one cylinder");
    let (mut broad, mut brute) = (Vec::new(), Vec::new());
    tool.contacts(PointCloud::from_points(&pts), &blocks, &mut broad)
        .expect("fresh");
    assert!(broad.is_empty());
    // Lift block 3's points 5 mm into the rod.
    for p in &mut pts[3 * BLOCK_POINTS..4 * BLOCK_POINTS] {
        p.z += 5.0 * MM;
    }
    let cloud = PointCloud::from_points(&pts);
    tool.contacts_all(cloud, &mut brute);
    assert!(!brute.is_empty());
    assert!(
        brute
            .iter()
            .all(|c| PointBlocks::block_of(c.vertex as usize) == 3)
    );
    // With the old boxes the block is skipped; refreshed, it is found.
    tool.contacts(cloud, &blocks, &mut broad)
        .expect("same count");
    assert!(broad.is_empty(), "the stale box hides the block");
    blocks.refresh_blocks(&[3], cloud).expect("block 3 exists");
    let stats = tool.contacts(cloud, &blocks, &mut broad).expect("fresh");
    assert_eq!(broad, brute);
    assert!(stats.points_examined < pts.len() / 4, "{stats:?}");

    assert_eq!(
        blocks.refresh_blocks(&[3, 9999], cloud),
        Err(ToolError::NoSuchBlock {
            block: 9999,
            blocks: blocks.block_count()
        })
    );
    let fewer = PointCloud::from_points(&pts[..100]);
    let stale = ToolError::StaleBlocks {
        blocks_points: pts.len(),
        points: 100,
    };
    assert_eq!(blocks.refresh_blocks(&[0], fewer), Err(stale.clone()));
    assert_eq!(tool.contacts(fewer, &blocks, &mut broad), Err(stale));
    assert!(broad.is_empty());
}

#[test]
fn refresh_and_query_are_the_same_on_one_and_two_threads() {
    let pts = jittered_sheet();
    let cloud = PointCloud::from_points(&pts);
    let run = || {
        let blocks = PointBlocks::new(cloud);
        let mut out = Vec::new();
        let mut all = Vec::new();
        for (_, tool) in poses() {
            tool.contacts(cloud, &blocks, &mut out).expect("fresh");
            all.extend_from_slice(&out);
        }
        (blocks.bounds, all)
    };
    let one = crate::testing::on_threads(1, run);
    let two = crate::testing::on_threads(2, run);
    assert!(!one.1.is_empty());
    assert_eq!(one, two);
}

#[test]
fn the_sieve_keeps_every_point_on_the_edge_of_a_cylinder() {
    // Points at r(t) (1 + e) from each cylinder's axis, e from -1e-5 to +1e-5, at axis
    // parameters from just before p0 to just past p1, round the axis; and points that are not
    // finite. The sieve must pass every point the exact test takes.
    let tools = [
        Instrument::l_hook(v(0.003, -0.002, 0.001), aiming(v(0.3, -0.4, -1.0))).expect("valid"),
        Instrument::grasper(v(0.0, 0.004, -0.002), aiming(v(1.0, 0.2, -0.6)), 0.8).expect("valid"),
    ];
    for tool in &tools {
        let mut pts = Vec::new();
        for cyl in tool.cylinders() {
            let (p0, p1) = (cyl.p0(), cyl.p1());
            let (u, w) = (p1 - p0).normalize().any_orthonormal_pair();
            for ti in -2..=42 {
                let t = ti as f32 / 40.0;
                let centre = p0 + (p1 - p0) * t;
                let r = cyl.radius_at(t);
                for (k, e) in [-1e-5f32, -1e-6, -1e-7, 0.0, 1e-7, 1e-6, 1e-5]
                    .into_iter()
                    .enumerate()
                {
                    let a = 0.7 * (ti * 7 + k as i32) as f32;
                    pts.push(centre + (u * a.cos() + w * a.sin()) * r * (1.0 + e));
                }
            }
        }
        pts.extend([
            Vec3::NAN,
            v(f32::INFINITY, 0.0, 0.0),
            v(0.0, f32::NEG_INFINITY, 0.001),
        ]);
        let [x, y, z] = components(&pts);
        let soa = PointCloud::from_components(&x, &y, &z).expect("same lengths");
        let aos = PointCloud::from_points(&pts);
        let blocks = PointBlocks::new(aos);
        let (mut from_aos, mut from_soa, mut brute) = (Vec::new(), Vec::new(), Vec::new());
        tool.contacts_all(aos, &mut brute);
        tool.contacts(aos, &blocks, &mut from_aos).expect("fresh");
        tool.contacts(soa, &blocks, &mut from_soa).expect("fresh");
        // Both sides of the edge are there: some points in, some out.
        assert!(
            brute.len() > pts.len() / 5,
            "{} of {}",
            brute.len(),
            pts.len()
        );
        assert!(
            brute.len() < pts.len() * 4 / 5,
            "{} of {}",
            brute.len(),
            pts.len()
        );
        assert_eq!(from_aos, brute);
        assert_eq!(from_soa, brute);
    }
}
