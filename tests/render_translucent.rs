//! Translucency on the Vulkan adapter the machine has (lavapipe in CI): a membrane blends over
//! what lies behind it at its alpha and never over what lies in front; membranes write no
//! depth; smoke shows as grey above where it was given off, only there, and the same snapshot
//! draws the same bytes; the two-pass path draws what multiview draws.

mod common;

use glam::{Vec2, Vec3};
use vesalius::render::camera::stereo_eyes;
use vesalius::render::gpu::EYE_FORMAT;
use vesalius::render::{EyeTarget, EyeView, Fov, Gpu, MEMBRANE_ALPHA, Renderer};
use vesalius::sim::{Emission, EmissionKind, ModelSnapshot, Snapshot, SurfaceRole};

const SIZE: (u32, u32) = (240, 240);

fn gpu(multiview: bool) -> Gpu {
    Gpu::headless(multiview).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)")
}

/// Both eyes 10 cm in front of the origin (+z) looking at it, 1 cm apart, with a narrow field
/// (about 4 pixels a millimetre at the origin) so that millimetre features cover pixels.
fn eyes() -> [EyeView; 2] {
    let fov = Fov {
        left: -0.3,
        right: 0.3,
        up: 0.3,
        down: -0.3,
    };
    stereo_eyes(Vec3::new(0.0, 0.0, 0.1), Vec3::ZERO, 0.01).map(|e| EyeView { fov, ..e })
}

/// A square of half-side `half` centred on `centre`, facing +z (the eyes), one region.
fn square(name: &str, centre: Vec3, half: f32, role: SurfaceRole) -> ModelSnapshot {
    let positions: Vec<Vec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(x, y)| centre + Vec3::new(x * half, y * half, 0.0))
        .collect();
    ModelSnapshot {
        name: name.into(),
        normals: vec![Vec3::Z; 4],
        positions,
        indices: vec![0, 1, 2, 0, 2, 3],
        regions: vec![0, 0],
        roles: vec![role],
        cut_edge: vec![false; 4],
        seared: Vec::new(),
    }
}

/// The artery-red square 1 cm behind the origin, 4 cm across.
fn backdrop() -> ModelSnapshot {
    square(
        "quad",
        Vec3::new(0.0, 0.0, -0.01),
        0.02,
        SurfaceRole::Artery,
    )
}

/// A membrane 2 cm across at depth `z`.
fn membrane(z: f32) -> ModelSnapshot {
    square(
        "fascia",
        Vec3::new(0.0, 0.0, z),
        0.01,
        SurfaceRole::Membrane,
    )
}

/// A small opaque (vein-blue) square 5 mm in front of the origin, 4 mm right of it.
fn in_front() -> ModelSnapshot {
    square(
        "front",
        Vec3::new(0.004, 0.0, 0.005),
        0.0015,
        SurfaceRole::Vein,
    )
}

fn scene(models: Vec<ModelSnapshot>) -> Snapshot {
    Snapshot {
        models,
        ..Default::default()
    }
}

struct Shot {
    eyes: [Vec<u8>; 2],
    counters: vesalius::profiler::FrameCounters,
}

fn shoot(gpu: &Gpu, snap: &Snapshot) -> Shot {
    let mut r = Renderer::new(gpu, EYE_FORMAT).expect("shaders compile");
    let target = EyeTarget::new(gpu, SIZE);
    r.update(snap);
    let counters = r.render(target.target(r.multiview()), SIZE, &eyes());
    let eyes = target.read(gpu).expect("read back");
    assert!(gpu.check().is_ok(), "no GPU error");
    Shot { eyes, counters }
}

fn pixel(img: &[u8], at: Vec2) -> [u8; 3] {
    let (x, y) = (at.x.floor() as usize, at.y.floor() as usize);
    let i = (y * SIZE.0 as usize + x) * 4;
    [img[i], img[i + 1], img[i + 2]]
}

/// Where a world point lands in eye `k`'s image.
fn at(k: usize, p: Vec3) -> Vec2 {
    eyes()[k].project(p, SIZE).expect("in front of the eye")
}

fn max_diff(a: [u8; 3], b: [u8; 3]) -> u8 {
    (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0)
}

fn to_linear(c: u8) -> f32 {
    let c = f32::from(c) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn to_srgb(l: f32) -> f32 {
    let l = l.clamp(0.0, 1.0);
    255.0
        * if l <= 0.0031308 {
            l * 12.92
        } else {
            1.055 * l.powf(1.0 / 2.4) - 0.055
        }
}

#[test]
fn a_membrane_blends_over_what_is_behind_it_at_its_alpha_and_never_over_what_is_in_front() {
    for multiview in [true, false] {
        let gpu = gpu(multiview);
        let bare = shoot(&gpu, &scene(vec![backdrop()]));
        let alone = shoot(&gpu, &scene(vec![membrane(0.0)]));
        let through = shoot(&gpu, &scene(vec![backdrop(), membrane(0.0)]));
        let background = shoot(&gpu, &scene(Vec::new()));
        for k in 0..2 {
            let o = at(k, Vec3::ZERO);
            let (b, a, t, g) = (
                pixel(&bare.eyes[k], o),
                pixel(&alone.eyes[k], o),
                pixel(&through.eyes[k], o),
                pixel(&background.eyes[k], o),
            );
            let path = if multiview { "multiview" } else { "two passes" };
            // Without the membrane: the artery's red.
            assert!(b[0] > b[1] + 60 && b[0] > b[2] + 60, "{path}: bare {b:?}");
            // Through it: neither the bare square nor the membrane over the background.
            assert!(max_diff(t, b) > 20, "{path}: through {t:?} vs bare {b:?}");
            assert!(max_diff(t, a) > 20, "{path}: through {t:?} vs alone {a:?}");
            // In linear light, `over` at alpha a: through - alone = (1 - a) (bare - background).
            for c in 0..3 {
                let expected = to_srgb(
                    to_linear(a[c]) + (1.0 - MEMBRANE_ALPHA) * (to_linear(b[c]) - to_linear(g[c])),
                );
                assert!(
                    (f32::from(t[c]) - expected).abs() <= 3.0,
                    "{path}: channel {c}: {} through, {expected:.1} expected at alpha {MEMBRANE_ALPHA}",
                    t[c]
                );
            }
        }
        // An opaque square in front of the membrane is drawn as if the membrane were not there.
        let front = shoot(&gpu, &scene(vec![backdrop(), in_front()]));
        let both = shoot(&gpu, &scene(vec![backdrop(), membrane(0.0), in_front()]));
        for k in 0..2 {
            let p = at(k, Vec3::new(0.004, 0.0, 0.005));
            let (f, w) = (pixel(&front.eyes[k], p), pixel(&both.eyes[k], p));
            assert!(f[2] > f[0] + 30, "the vein's blue: {f:?}");
            assert_eq!(f, w, "the membrane behind is not drawn over it");
        }
        // Membranes write no depth: a farther one drawn after a nearer one still shows.
        let two = shoot(
            &gpu,
            &scene(vec![backdrop(), membrane(0.002), membrane(0.0)]),
        );
        let one = shoot(&gpu, &scene(vec![backdrop(), membrane(0.002)]));
        let o = at(0, Vec3::ZERO);
        let (p2, p1) = (pixel(&two.eyes[0], o), pixel(&one.eyes[0], o));
        assert!(max_diff(p2, p1) > 10, "two layers {p2:?}, one {p1:?}");
        // The opaque square and the membrane: one draw each, two pipelines, in each pass.
        let c = &through.counters;
        assert_eq!(c.passes, if multiview { 1 } else { 2 });
        assert_eq!(c.draw_calls, 2 * c.passes);
        assert_eq!(c.setpass_calls, 2 * c.passes);
        assert_eq!(c.triangles, 4 * c.passes);
    }
}

#[test]
fn two_passes_blend_as_multiview_does() {
    let snap = scene(vec![backdrop(), membrane(0.0), in_front()]);
    let (one, two) = (shoot(&gpu(true), &snap), shoot(&gpu(false), &snap));
    for k in 0..2 {
        let differ = common::pixels_differing(&one.eyes[k], &two.eyes[k], 2);
        assert!(differ < 20, "eye {k}: {differ} pixels differ");
    }
}

/// Smoke from three emissions about 0.3 s old at the origin, over the bare background.
fn smoky(with: bool) -> Snapshot {
    let mut s = scene(Vec::new());
    s.time_s = 2.0;
    if with {
        s.emissions = [1.685, 1.7, 1.715]
            .iter()
            .map(|&time_s| Emission {
                time_s,
                position: Vec3::ZERO,
                kind: EmissionKind::Smoke,
            })
            .collect();
    }
    s
}

/// Grey: the channels within 16 levels of each other, and well above the background's
/// (about 39, 29, 26).
fn grey(p: [u8; 3]) -> bool {
    let (lo, hi) = (p.iter().min().copied(), p.iter().max().copied());
    matches!((lo, hi), (Some(lo), Some(hi)) if hi - lo <= 16 && lo >= 55)
}

/// Grey pixels within `r` pixels of `centre`.
fn grey_around(img: &[u8], centre: Vec2, r: i32) -> usize {
    let mut n = 0;
    for dy in -r..=r {
        for dx in -r..=r {
            let p = centre + Vec2::new(dx as f32, dy as f32);
            if p.x >= 0.0 && p.y >= 0.0 && p.x < SIZE.0 as f32 && p.y < SIZE.1 as f32 {
                n += usize::from(grey(pixel(img, p)));
            }
        }
    }
    n
}

#[test]
fn smoke_shows_grey_above_where_it_was_given_off_and_draws_the_same_bytes_every_time() {
    let gpu = gpu(true);
    let with = shoot(&gpu, &smoky(true));
    let without = shoot(&gpu, &smoky(false));
    for k in 0..2 {
        // 0.3 s on, puffs have risen 6-10 mm (2-3.5 cm/s) and are 2.7-3.6 mm in radius.
        let above = at(k, Vec3::new(0.0, 0.008, 0.0));
        let below = at(k, Vec3::new(0.0, -0.008, 0.0));
        let grey_above = grey_around(&with.eyes[k], above, 12);
        assert!(grey_above > 40, "eye {k}: {grey_above} grey pixels above");
        assert_eq!(grey_around(&without.eyes[k], above, 12), 0);
        assert_eq!(
            grey_around(&with.eyes[k], below, 12),
            0,
            "smoke does not sink"
        );
    }
    // Drawn with depth testing: an opaque square in front hides it.
    let mut hidden = smoky(true);
    hidden.models = vec![square(
        "front",
        Vec3::new(0.0, 0.008, 0.03),
        0.005,
        SurfaceRole::Vein,
    )];
    let mut bare = smoky(false);
    bare.models = hidden.models.clone();
    let (h, b) = (shoot(&gpu, &hidden), shoot(&gpu, &bare));
    let above = at(0, Vec3::new(0.0, 0.008, 0.0));
    assert_eq!(pixel(&h.eyes[0], above), pixel(&b.eyes[0], above));
    // One draw for all the puffs, counted as an object.
    assert_eq!(with.counters.draw_calls, 1);
    assert_eq!(with.counters.objects, without.counters.objects + 1);
    assert_eq!(with.counters.triangles, 2 * 15);
    // The same snapshot: the same bytes, from a new renderer and from the same one again.
    let again = shoot(&gpu, &smoky(true));
    assert!(again.eyes == with.eyes, "a new renderer drew other bytes");
    let mut r = Renderer::new(&gpu, EYE_FORMAT).expect("shaders compile");
    let target = EyeTarget::new(&gpu, SIZE);
    let snap = smoky(true);
    let mut frames = Vec::new();
    for _ in 0..2 {
        r.update(&snap);
        r.render(target.target(r.multiview()), SIZE, &eyes());
        frames.push(target.read(&gpu).expect("read back"));
    }
    assert!(frames[0] == frames[1] && frames[0] == with.eyes);
    // The two-pass path draws the same smoke.
    let two = shoot(&self::gpu(false), &smoky(true));
    for k in 0..2 {
        let differ = two.eyes[k]
            .chunks_exact(4)
            .zip(with.eyes[k].chunks_exact(4))
            .filter(|(a, b)| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) > 2))
            .count();
        assert!(differ < 20, "eye {k}: {differ} pixels differ");
    }
}
