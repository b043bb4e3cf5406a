//! Rendering on the Vulkan adapter the machine has (Mesa's lavapipe in CI): the organ shows,
//! the eyes see it with the disparity the camera model predicts, a cut changes the picture
//! where it was made, and the counters match a hand count of a known scene.

mod common;

use glam::Vec3;
use vesalius::mesh::icosphere;
use vesalius::render::camera::{DEFAULT_IPD_M, field_eyes};
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
        roles: vec![vesalius::sim::SurfaceRole::Tissue],
        cut_edge,
        seared: Vec::new(),
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
    render_at(gpu, snap, eyes, SIZE)
}

fn render_at(gpu: &Gpu, snap: &Snapshot, eyes: &[EyeView; 2], size: (u32, u32)) -> Shot {
    let mut r = Renderer::new(gpu, EYE_FORMAT).expect("shaders compile");
    let target = EyeTarget::new(gpu, size);
    r.update(snap);
    let counters = r.render(target.target(r.multiview()), size, eyes);
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
    let eyes = field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M);
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
    let eyes = field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M);
    // The instrument scene: its shaft runs past the eyes, through the near plane.
    let snap = reference_scenes().swap_remove(0).1;
    let one = render(&gpu(true), &snap, &eyes);
    let two = render(&gpu(false), &snap, &eyes);
    assert_eq!(two.counters.passes, 2);
    assert_eq!(
        two.counters.draw_calls,
        2 * one.counters.draw_calls / one.counters.passes
    );
    for k in 0..2 {
        let differ = common::pixels_differing(&one.eyes[k], &two.eyes[k], 2);
        assert!(differ < 50, "eye {k}: {differ} pixels differ");
    }
}

#[test]
fn a_cut_changes_the_image_where_it_was_made() {
    let gpu = gpu(true);
    let eyes = field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M);
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
    let eyes = field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M);
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
        &field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M),
    );
    let dir = common::tmp("png", "saved");
    let path = dir.join("left_0000.png");
    write_png(&path, SIZE, &shot.eyes[0]).expect("written");
    let (size, pixels) = read_png(&path).expect("read");
    assert_eq!(size, SIZE);
    assert_eq!(pixels, shot.eyes[0]);
}

/// The three fixed reference scenes: the organ with an instrument and its beam, the organ with
/// a cut, and a tumour highlighted once identified.
fn reference_scenes() -> Vec<(&'static str, Snapshot)> {
    let mut tool = scene(ball(0.05, None));
    tool.tools[1].tip = Vec3::new(0.02, 0.04, 0.1);
    tool.tools[1].direction = Vec3::new(-0.2, -0.3, -1.0).normalize();
    tool.tools[1].beam_end = Some(Vec3::new(0.0, 0.01, 0.049));
    tool.tools[1].active = true;
    let cut = scene(ball(0.05, Some((Vec3::new(0.0, 0.02, 0.045), 0.015))));
    let mut tumour = ball(0.05, None);
    tumour.regions = tumour
        .indices
        .chunks_exact(3)
        .map(|t| {
            let c: Vec3 = t
                .iter()
                .map(|&i| tumour.positions[i as usize])
                .sum::<Vec3>()
                / 3.0;
            u8::from(c.x > 0.02 && c.z > 0.0)
        })
        .collect();
    tumour.roles = vec![
        vesalius::sim::SurfaceRole::Tissue,
        vesalius::sim::SurfaceRole::Target,
    ];
    let mut tumour = scene(tumour);
    tumour.target_found = true;
    vec![("instrument", tool), ("cut", cut), ("tumour", tumour)]
}

/// The pixel at image point `at`, if inside.
fn pixel(img: &[u8], size: (u32, u32), at: glam::Vec2) -> Option<[u8; 3]> {
    let (x, y) = (at.x.floor() as i64, at.y.floor() as i64);
    if x < 0 || y < 0 || x >= i64::from(size.0) || y >= i64::from(size.1) {
        return None;
    }
    let i = (y as usize * size.0 as usize + x as usize) * 4;
    Some([img[i], img[i + 1], img[i + 2]])
}

/// Pixels within `r` pixels of `at` that `pick` accepts, and all pixels looked at.
fn around(
    img: &[u8],
    size: (u32, u32),
    at: glam::Vec2,
    r: i32,
    pick: impl Fn([u8; 3]) -> bool,
) -> (usize, usize) {
    let (mut hit, mut all) = (0, 0);
    for dy in -r..=r {
        for dx in -r..=r {
            if let Some(p) = pixel(img, size, at + glam::Vec2::new(dx as f32, dy as f32)) {
                all += 1;
                hit += usize::from(pick(p));
            }
        }
    }
    (hit, all)
}

/// The laser's beam: bright (it is emissive), green the strongest channel.
fn laser_green(p: [u8; 3]) -> bool {
    p[1] > 180 && p[1] >= p[0] && p[1] >= p[2] + 10
}

/// Tissue or target lit, as opposed to the cavity's near-black background.
fn lit(p: [u8; 3]) -> bool {
    !background(&[p[0], p[1], p[2], 255])
}

/// Properties each reference scene's picture must have, worked out from the scene itself:
/// the organ where it projects and background far from it; the beam green along its
/// projected path; a found target glowing green on its own side only; raw tissue (green
/// channel far below red) around a cut, and not on the intact side.
fn shows_its_scene(name: &str, snap: &Snapshot, eye: &EyeView, size: (u32, u32), img: &[u8]) {
    let project = |p: Vec3| eye.project(p, size).expect("in front of the eye");
    let centre = project(Vec3::ZERO);
    assert!(
        pixel(img, size, centre).is_some_and(lit),
        "{name}: the organ's centre is lit"
    );
    let corner = glam::Vec2::new(2.0, size.1 as f32 - 3.0);
    assert!(
        pixel(img, size, corner).is_some_and(|p| !lit(p)),
        "{name}: the corner is background"
    );
    match name {
        "instrument" => {
            let t = snap.tools[1];
            let end = t.beam_end.expect("the beam lands");
            let samples = 20;
            let on_beam = (1..samples)
                .filter(|k| {
                    let at = project(t.tip.lerp(end, *k as f32 / samples as f32));
                    around(img, size, at, 2, laser_green).0 > 0
                })
                .count();
            let seen: Vec<_> = (1..samples)
                .filter_map(|k| {
                    pixel(
                        img,
                        size,
                        project(t.tip.lerp(end, k as f32 / samples as f32)),
                    )
                })
                .collect();
            assert!(
                on_beam >= samples * 8 / 10,
                "{name}: beam green at {on_beam} of {} points along it: {seen:?}",
                samples - 1
            );
        }
        "tumour" => {
            let glow = |p: [u8; 3]| p[1] > p[0] && p[1] > 60;
            // The target region is the +x, +z cap: right of the centre in the image.
            let side = |sign: f32| {
                let at = project(Vec3::new(0.035 * sign, 0.0, 0.035));
                around(img, size, at, 6, glow)
            };
            let (target, all) = side(1.0);
            let (tissue, _) = side(-1.0);
            assert!(
                target * 2 > all && tissue == 0,
                "{name}: green on the target {target}/{all}, on tissue {tissue}"
            );
        }
        "cut" => {
            // Raw tissue's albedo is (0.20, 0.006, 0.008) in linear light against intact
            // tissue's sRGB (0.58, 0.18, 0.14), a hue drift of 15 % at most: in sRGB raw
            // tissue's green is about 0.12 of its red, intact tissue's over 0.26.
            let raw = |p: [u8; 3]| p[0] > 60 && f32::from(p[1]) < 0.2 * f32::from(p[0]);
            // The ring of cut edge lies 15-20 mm around the hole's centre on the 50 mm ball:
            // a box 14 px around the centre holds it; the intact side is 55 mm away.
            let cut = project(Vec3::new(0.0, 0.02, 0.045));
            let intact = project(Vec3::new(0.0, -0.035, 0.035));
            let (near, all) = around(img, size, cut, 14, raw);
            let (far, _) = around(img, size, intact, 14, raw);
            assert!(
                near * 10 > all && far * 20 < all,
                "{name}: raw tissue {near}/{all} at the cut, {far} on the intact side"
            );
        }
        other => panic!("no property for scene {other}"),
    }
}

/// Pixels whose largest channel difference exceeds 16, and the mean absolute difference.
fn image_difference(a: &[u8], b: &[u8]) -> (usize, f64) {
    let mut off = 0;
    let mut sum = 0u64;
    for (p, q) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let d = (0..3).map(|k| p[k].abs_diff(q[k])).max().unwrap_or(0);
        off += usize::from(d > 16);
        sum += (0..3).map(|k| p[k].abs_diff(q[k]) as u64).sum::<u64>();
    }
    (off, sum as f64 / (a.len() / 4 * 3).max(1) as f64)
}

/// Reference PNGs in tests/reference/ (made on Mesa's lavapipe; `VESALIUS_BLESS=1` rewrites
/// them after an intended change of the picture). A pixel may differ by a rounding step
/// anywhere and by more on at most 0.5 % of the image (edges rasterised a hair apart).
#[test]
fn fixed_scenes_match_their_reference_images() {
    let gpu = gpu(true);
    let size = SIZE;
    let eyes = field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/reference");
    let bless = std::env::var_os("VESALIUS_BLESS").is_some();
    for (name, snap) in reference_scenes() {
        let shot = render_at(&gpu, &snap, &eyes, size);
        for (eye, pixels) in ["left", "right"].iter().zip(&shot.eyes) {
            let path = dir.join(format!("{name}_{eye}.png"));
            if bless {
                std::fs::create_dir_all(&dir).expect("reference dir");
                write_png(&path, size, pixels).expect("reference written");
                continue;
            }
            let (ref_size, reference) = read_png(&path)
                .unwrap_or_else(|e| panic!("{}: {e} (VESALIUS_BLESS=1 makes it)", path.display()));
            assert_eq!(ref_size, size, "{}", path.display());
            // A blessed picture must still show what its scene is: a wrong picture blessed
            // by mistake fails here, whatever the comparison below says.
            let eye_view = if *eye == "left" { &eyes[0] } else { &eyes[1] };
            shows_its_scene(name, &snap, eye_view, size, &reference);
            shows_its_scene(name, &snap, eye_view, size, pixels);
            let (off, mean) = image_difference(pixels, &reference);
            let limit = (size.0 * size.1) as usize / 200;
            assert!(
                off <= limit && mean < 1.5,
                "{name} {eye}: {off} pixels off (at most {limit}), mean difference {mean:.2}"
            );
        }
    }
}

#[test]
fn the_reference_comparison_catches_a_changed_picture() {
    // The same tolerance must reject a scene that changed: the cut scene against the intact one.
    let gpu = gpu(true);
    let size = SIZE;
    let eyes = field_eyes(&vesalius::procedures::nephrectomy::INFO.view, DEFAULT_IPD_M);
    let scenes = reference_scenes();
    let a = render_at(&gpu, &scenes[0].1, &eyes, size);
    let b = render_at(&gpu, &scenes[1].1, &eyes, size);
    let (off, _) = image_difference(&a.eyes[0], &b.eyes[0]);
    assert!(
        off > (size.0 * size.1) as usize / 200,
        "only {off} pixels differ"
    );
    let (same, mean) = image_difference(&a.eyes[0], &a.eyes[0]);
    assert_eq!((same, mean), (0, 0.0));
    // Each scene's properties reject the other scenes' pictures: a wrong picture blessed as a
    // reference would not pass.
    let shots: Vec<Shot> = scenes
        .iter()
        .map(|(_, s)| render_at(&gpu, s, &eyes, size))
        .collect();
    for (k, (name, snap)) in scenes.iter().enumerate() {
        let other = &shots[(k + 1) % shots.len()].eyes[0];
        let wrong = std::panic::catch_unwind(|| shows_its_scene(name, snap, &eyes[0], size, other));
        assert!(
            wrong.is_err(),
            "{name}'s properties accepted another scene's picture"
        );
        shows_its_scene(name, snap, &eyes[0], size, &shots[k].eyes[0]);
    }
}

#[test]
fn a_gpu_validation_error_is_returned_not_a_panic() {
    let gpu = gpu(true);
    assert!(gpu.check().is_ok());
    let small = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("too small"),
        size: 16,
        usage: wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    // 64 bytes into a 16-byte buffer: wgpu's validation rejects it.
    gpu.queue.write_buffer(&small, 0, &[0u8; 64]);
    let err = gpu.check().expect_err("the overrun is reported");
    assert!(
        matches!(err, vesalius::render::gpu::RenderError::Validation(_)),
        "{err}"
    );
    assert!(gpu.check().is_ok(), "reported once");
    // An eye size past the device's limit is refused before anything is made.
    let max = gpu.device.limits().max_texture_dimension_2d;
    assert!(gpu.check_eye_size((max + 1, 16)).is_err());
    assert!(gpu.check_eye_size((max, 16)).is_ok());
}

/// `vesalius profile nephrectomy --json` at full size, with the whole operative field around
/// the models, against the nephrectomy paper's budget (Tables 2 and 3): at least 50,000
/// triangles, at most 9 draw calls for both eyes (its GPU case; the CPU case allows 19), total
/// memory (heap + GPU) at most the 49.9 MB of its GPU case.
#[test]
fn the_full_size_scene_profiles_within_the_papers_budget() {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["profile", "nephrectomy", "--json"])
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    let ours = &v["vesalius"];
    let n = |k: &str| {
        ours[k]
            .as_u64()
            .unwrap_or_else(|| panic!("no {k} in {ours}"))
    };
    assert!(n("triangles") >= 50_000, "{} triangles", n("triangles"));
    assert!(n("batches") <= n("draw_calls"));
    assert!(v["heap_measured"].as_bool() == Some(true));
    let total = n("total_memory_bytes");
    assert!(total <= 49_900_000, "total memory {total} bytes");
    // The field is drawn: one more object than the models, instruments, beams and rig.
    assert!(n("objects") >= 10, "{} objects", n("objects"));
    // The GPU share is the textures and meshes the counters list.
    let bytes = |k: &str| ours[k]["bytes"].as_u64().unwrap_or(0);
    assert!(n("vram_bytes") >= bytes("textures") + bytes("meshes"));
    assert!(total > n("vram_bytes"), "heap counted too");
    // The 2-layer Vive-sized colour target alone: 2 x 1080 x 1200 x 4 bytes.
    assert!(bytes("textures") >= 2 * 1080 * 1200 * 4);
    // Printed beside the paper's columns: no more draw calls than its GPU column's batching.
    let paper_gpu = v["paper"]["gpu"]["draw_calls"]
        .as_u64()
        .expect("the paper's GPU column");
    assert!(
        n("draw_calls") <= paper_gpu,
        "{} > {paper_gpu}",
        n("draw_calls")
    );
}

#[test]
fn frames_show_the_field_from_a_laparoscope_the_trainee_moved() {
    use vesalius::render::frames::render_snapshots;
    use vesalius::sim::ScopeView;
    let gpu = gpu(true);
    let view = vesalius::procedures::nephrectomy::INFO.view;
    let still = scene(ball(0.03, None));
    // The same viewpoint published as a scope, and one moved 4 cm to the camera's right.
    let right = (view.target - view.eye).cross(Vec3::Y).normalize() * 0.04;
    let at_home = Snapshot {
        scope: Some(ScopeView {
            eye: view.eye,
            target: view.target,
        }),
        ..still.clone()
    };
    let moved = Snapshot {
        scope: Some(ScopeView {
            eye: view.eye + right,
            target: view.target + right,
        }),
        ..still.clone()
    };
    let dir = common::tmp("scope", "frames");
    render_snapshots(
        &gpu,
        &vesalius::render::frames::Look::bare(view),
        &[still, at_home, moved],
        1,
        SIZE,
        0.0,
        Some(&*dir),
    )
    .expect("frames");
    let left = |k: usize| {
        let (size, px) = read_png(&dir.join(format!("left_{k:04}.png"))).expect("a frame");
        assert_eq!(size, SIZE);
        px
    };
    let (a, b, c) = (left(0), left(1), left(2));
    assert_eq!(
        a, b,
        "the procedure's own viewpoint as a scope draws the same frame"
    );
    // Moved to the right, the camera sees the organ further left.
    let ((ca, xa), (cc, xc)) = (coverage(&a), coverage(&c));
    assert!(ca > 0.01 && cc > 0.01, "the organ shows: {ca} {cc}");
    assert!(
        xc < xa - 10.0,
        "organ at x {xa} from home, {xc} from the moved scope"
    );
}
