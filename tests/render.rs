//! Rendering on the Vulkan adapter the machine has (Mesa's lavapipe in CI): the organ shows,
//! the eyes see it with the disparity the camera model predicts, a cut changes the picture
//! where it was made, and the counters match a hand count of a known scene.

use glam::Vec3;
use vesalius::mesh::icosphere;
use vesalius::render::camera::{DEFAULT_IPD_M, nephrectomy_eyes};
use vesalius::render::gpu::{EYE_FORMAT, read_png, write_png};
use vesalius::render::{EyeTarget, EyeView, Gpu, Renderer};
use vesalius::sim::{ModelSnapshot, Snapshot};

const SIZE: (u32, u32) = (270, 300);

fn ball(radius: f32, drop_near: Option<(Vec3, f32)>) -> ModelSnapshot {
    let m = icosphere(3);
    let positions: Vec<Vec3> = m.positions.iter().map(|p| *p * radius).collect();
    let mut indices = Vec::new();
    let mut cut_edge = vec![false; positions.len()];
    for t in &m.triangles {
        let c = t.iter().map(|&i| positions[i as usize]).sum::<Vec3>() / 3.0;
        if let Some((at, r)) = drop_near {
            let d = (c - at).length();
            if d < r {
                continue;
            }
            if d < r * 1.3 {
                for &i in t {
                    cut_edge[i as usize] = true;
                }
            }
        }
        indices.extend_from_slice(t);
    }
    let regions = vec![0; indices.len() / 3];
    ModelSnapshot {
        name: "kidney".into(),
        normals: positions.iter().map(|p| p.normalize()).collect(),
        positions,
        indices,
        regions,
        cut_edge,
    }
}

fn scene(model: ModelSnapshot) -> Snapshot {
    Snapshot {
        models: vec![model],
        ..Default::default()
    }
}

struct Shot {
    eyes: [Vec<u8>; 2],
    counters: vesalius::profiler::FrameCounters,
}

fn render(gpu: &Gpu, snap: &Snapshot, eyes: &[EyeView; 2]) -> Shot {
    let mut r = Renderer::new(gpu, EYE_FORMAT);
    let target = EyeTarget::new(gpu, SIZE);
    r.update(snap);
    let counters = r.render(target.target(r.multiview()), SIZE, eyes);
    let eyes = target.read(gpu).expect("read back");
    Shot { eyes, counters }
}

fn background(p: &[u8]) -> bool {
    // The clear colour is about (39, 29, 26) in sRGB; the darkest lit tissue is far above.
    p[0] < 55 && p[1] < 45 && p[2] < 45
}

/// Fraction of non-background pixels and their mean x.
fn coverage(img: &[u8]) -> (f64, f64) {
    let (mut n, mut sx) = (0usize, 0f64);
    for (k, p) in img.chunks_exact(4).enumerate() {
        if !background(p) {
            n += 1;
            sx += (k % SIZE.0 as usize) as f64;
        }
    }
    (n as f64 / (SIZE.0 * SIZE.1) as f64, sx / n.max(1) as f64)
}

fn gpu(multiview: bool) -> Gpu {
    Gpu::headless(multiview).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)")
}

#[test]
fn the_organ_shows_in_both_eyes_with_the_predicted_disparity() {
    let gpu = gpu(true);
    let eyes = nephrectomy_eyes(DEFAULT_IPD_M);
    let shot = render(&gpu, &scene(ball(0.03, None)), &eyes);
    let (fl, xl) = coverage(&shot.eyes[0]);
    let (fr, xr) = coverage(&shot.eyes[1]);
    assert!(
        fl > 0.01 && fr > 0.01,
        "organ covers {fl:.3} / {fr:.3} of the eyes"
    );
    assert!((fl - fr).abs() < 0.2 * fl, "same size in both eyes");
    let pl = eyes[0].project(Vec3::ZERO, SIZE).expect("in front");
    let pr = eyes[1].project(Vec3::ZERO, SIZE).expect("in front");
    let expected = (pl.x - pr.x) as f64;
    let measured = xl - xr;
    assert!(expected > 5.0, "the scene is near enough to show disparity");
    assert!(
        (measured - expected).abs() < 0.1 * expected + 1.5,
        "disparity {measured:.1} px, camera model says {expected:.1} px"
    );
    // Lit, not flat: the organ's pixels vary in brightness.
    let lum: Vec<u32> = shot.eyes[0]
        .chunks_exact(4)
        .filter(|p| !background(p))
        .map(|p| p[0] as u32 + p[1] as u32 + p[2] as u32)
        .collect();
    let (lo, hi) = (
        lum.iter().min().copied().unwrap_or(0),
        lum.iter().max().copied().unwrap_or(0),
    );
    assert!(hi > lo + 60, "shading range {lo}..{hi}");
}

#[test]
fn two_passes_draw_the_same_picture_as_multiview() {
    let eyes = nephrectomy_eyes(DEFAULT_IPD_M);
    let snap = scene(ball(0.03, None));
    let one = render(&gpu(true), &snap, &eyes);
    let two = render(&gpu(false), &snap, &eyes);
    assert_eq!(two.counters.passes, 2);
    assert_eq!(
        two.counters.draw_calls,
        2 * one.counters.draw_calls / one.counters.passes
    );
    for k in 0..2 {
        let differ = one.eyes[k]
            .chunks_exact(4)
            .zip(two.eyes[k].chunks_exact(4))
            .filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 2))
            .count();
        assert!(differ < 50, "eye {k}: {differ} pixels differ");
    }
}

#[test]
fn a_cut_changes_the_image_where_it_was_made() {
    let gpu = gpu(true);
    let eyes = nephrectomy_eyes(DEFAULT_IPD_M);
    // Cut a 1 cm hole in the face turned towards the eyes.
    let towards = (eyes[0].position - Vec3::ZERO).normalize() * 0.03;
    let whole = render(&gpu, &scene(ball(0.03, None)), &eyes);
    let cut = render(&gpu, &scene(ball(0.03, Some((towards, 0.01)))), &eyes);
    let at = eyes[0].project(towards, SIZE).expect("in front");
    let (mut near, mut far) = (0usize, 0usize);
    for (k, (a, b)) in whole.eyes[0]
        .chunks_exact(4)
        .zip(cut.eyes[0].chunks_exact(4))
        .enumerate()
    {
        if a.iter().zip(b).any(|(x, y)| x.abs_diff(*y) > 8) {
            let (x, y) = ((k % SIZE.0 as usize) as f32, (k / SIZE.0 as usize) as f32);
            if (x - at.x).hypot(y - at.y) < 20.0 {
                near += 1;
            } else {
                far += 1;
            }
        }
    }
    assert!(near > 30, "{near} pixels changed at the cut");
    assert!(far < near / 4, "{far} pixels changed away from it");
    // The counters see the missing triangles.
    assert!(cut.counters.triangles < whole.counters.triangles);
}

#[test]
fn counters_match_a_hand_count_of_a_known_scene() {
    let gpu = gpu(true);
    let eyes = nephrectomy_eyes(DEFAULT_IPD_M);
    let mut snap = scene(ball(0.03, None));
    // One instrument with its laser aimed: shaft and two jaws (3 cylinders) and a beam.
    snap.tools[1].tip = Vec3::new(0.0, 0.02, 0.08);
    snap.tools[1].direction = Vec3::new(0.0, -0.2, -1.0).normalize();
    snap.tools[1].beam_end = Some(Vec3::new(0.0, 0.01, 0.03));
    let shot = render(&gpu, &snap, &eyes);
    let c = &shot.counters;
    let sphere_tris = 20 * 4u64.pow(3);
    let sphere_verts = 10 * 4u64.pow(3) + 2;
    // 4 cylinders of 8 sides: 16 triangles and 16 vertices each.
    assert_eq!(c.passes, 1);
    assert_eq!(c.draw_calls, 2, "the organ and the instruments");
    assert_eq!(c.batches, 2);
    assert_eq!(c.setpass_calls, 1);
    assert_eq!(c.triangles, sphere_tris + 4 * 16);
    assert_eq!(c.vertices, sphere_verts + 4 * 16);
    assert_eq!(
        c.objects,
        1 + 1 + 1 + 2,
        "organ, instrument, beam, light, eye rig"
    );
    // Two textures: the 2-layer colour target (4 B/px) and the depth buffer (2 B/px).
    let px = (SIZE.0 * SIZE.1 * 2) as u64;
    assert_eq!(c.textures.count, 2);
    assert_eq!(c.textures.bytes, px * 4 + px * 2);
    assert!(c.vram_bytes >= c.textures.bytes + c.meshes.bytes + c.materials.bytes);
    // The organ's vertex buffer holds at least its 28-byte vertices.
    assert!(c.meshes.bytes >= sphere_verts * 28 + sphere_tris * 12);
}

#[test]
fn saved_frames_read_back_as_the_rendered_pixels() {
    let gpu = gpu(true);
    let shot = render(
        &gpu,
        &scene(ball(0.03, None)),
        &nephrectomy_eyes(DEFAULT_IPD_M),
    );
    let dir = std::env::temp_dir().join(format!("vesalius-png-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("left_0000.png");
    write_png(&path, SIZE, &shot.eyes[0]).expect("written");
    let (size, pixels) = read_png(&path).expect("read");
    assert_eq!(size, SIZE);
    assert_eq!(pixels, shot.eyes[0]);
}
