//! What a laser cut looks like (lavapipe): the nephrectomy's demo cut leaves a hole whose
//! outline is a smooth seared ring (no staircase of whole triangles) around a bed of raw
//! tissue, not a window onto what lies behind the kidney; the laser smokes while it cuts, and
//! only then; a laser cut into the renal artery bleeds; and a grasper pressed side-on into the kidney dents it along its shaft, as a
//! depth map of the drawn surface shows. A snapshot whose meshes are built beside the
//! simulation while it cuts on draws the instant it was handed over.

mod common;

use glam::{Vec2, Vec3};
use vesalius::procedures::Viewpoint;
use vesalius::procedures::nephrectomy::{INFO, Nephrectomy, REGION_TUMOUR, Scenario};
use vesalius::render::frames::Look;
use vesalius::render::{EyeTarget, Gpu};
use vesalius::sim::{Hand, InputFrame, ModelSnapshot, Pose, Snapshot};
use vesalius::trace::KeyTrace;

const SIZE: (u32, u32) = (400, 400);

/// The nephrectomy stepped along its demo trace for `seconds`.
fn demo_at(seconds: f64) -> (Nephrectomy, Snapshot) {
    let s = Scenario::parse("builtin nephrectomy scenario", INFO.scenario).expect("scenario");
    let dt = f64::from(s.dt_s);
    let mut n = Nephrectomy::new(s).expect("nephrectomy");
    let keys = KeyTrace::parse("demo", INFO.demo_trace).expect("demo trace");
    let steps = (seconds / dt) as u64;
    let mut events = Vec::new();
    for step in 0..steps {
        n.step(&keys.sample(step as f64 * dt), step, &mut events);
    }
    let snap = n.snapshot(steps);
    (n, snap)
}

/// Per vertex: the part (joined by triangles) it belongs to, as a representative vertex.
fn parts(m: &ModelSnapshot) -> Vec<usize> {
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let n = m.positions.len();
    let mut parent: Vec<usize> = (0..n).collect();
    for t in m.indices.chunks_exact(3) {
        for k in 1..3 {
            let (a, b) = (
                root(&mut parent, t[0] as usize),
                root(&mut parent, t[k] as usize),
            );
            parent[a] = b;
        }
    }
    (0..n).map(|i| root(&mut parent, i)).collect()
}

fn rgb(img: &[u8], q: Vec2) -> Option<[u8; 3]> {
    let (x, y) = (q.x.floor(), q.y.floor());
    if x < 0.0 || y < 0.0 || x >= SIZE.0 as f32 || y >= SIZE.1 as f32 {
        return None;
    }
    let i = (y as usize * SIZE.0 as usize + x as usize) * 4;
    Some([img[i], img[i + 1], img[i + 2]])
}

/// Seared: dark and brown-black, not the red of tissue (raw or whole).
fn seared(c: [u8; 3]) -> bool {
    c[0] < 90 && i16::from(c[0]) - i16::from(c[1]) < 30 && c[1] > c[2]
}

/// Raw or whole kidney: red.
fn red(c: [u8; 3]) -> bool {
    i16::from(c[0]) - i16::from(c[1]) > 50
}

#[test]
fn the_laser_cut_has_a_smooth_seared_outline_around_a_raw_bed() {
    // The demo has lifted the tumour out by 20 s.
    let (_, mut snap) = demo_at(20.0);
    // The instruments out of the way.
    for t in &mut snap.tools {
        t.tip = Vec3::new(0.0, 1.0, 0.0);
        t.beam_end = None;
        t.beam_reach = None;
    }
    let k = snap
        .models
        .iter_mut()
        .find(|m| m.name == "kidney")
        .expect("kidney");
    // The seared outlines: the kidney's hole, and the specimen's, which the grasper holds
    // away. The specimen is the part with the tumour's triangles.
    let part = parts(k);
    let specimen: Vec<usize> = k
        .indices
        .chunks_exact(3)
        .zip(&k.regions)
        .filter(|(_, r)| **r == REGION_TUMOUR)
        .map(|(t, _)| part[t[0] as usize])
        .collect();
    let hole: Vec<(Vec3, Vec3, usize)> = (0..k.positions.len())
        .filter(|&i| k.seared.get(i).copied().unwrap_or(false))
        .filter(|&i| !specimen.contains(&part[i]))
        .map(|i| (k.positions[i], k.normals[i], part[i]))
        .collect();
    assert!(
        hole.len() > 30,
        "{} seared vertices on the hole",
        hole.len()
    );
    let centre = hole.iter().map(|h| h.0).sum::<Vec3>() / hole.len() as f32;
    let normal = hole.iter().map(|h| h.1).sum::<Vec3>().normalize();
    // Without the specimen: the kidney's triangles, in the hole's part.
    let body = hole[0].2;
    let keep: Vec<usize> = (0..k.indices.len() / 3)
        .filter(|&t| part[k.indices[3 * t] as usize] == body)
        .collect();
    k.indices = keep
        .iter()
        .flat_map(|&t| k.indices[3 * t..3 * t + 3].to_vec())
        .collect();
    k.regions = keep.iter().map(|&t| k.regions[t]).collect();
    // Looking straight into the hole from 4.5 cm, both eyes at one point.
    let view = Viewpoint {
        eye: centre + normal * 0.045,
        target: centre,
    };
    let look = Look::bare(view);
    let gpu = Gpu::headless(true).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)");
    let mut r = look.renderer(&gpu).expect("shaders compile");
    let target = EyeTarget::new(&gpu, SIZE);
    r.update(&snap);
    let mut eyes = look.eyes(&look.view, SIZE);
    for e in &mut eyes {
        e.position = view.eye;
    }
    r.render(target.target(r.multiview()), SIZE, &eyes);
    let [img, _] = target.read(&gpu).expect("read back");
    gpu.check().expect("no GPU errors");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("cut-look");
    std::fs::create_dir_all(&dir).expect("scratch folder");
    vesalius::render::gpu::write_png(&dir.join("hole.png"), SIZE, &img).expect("png");

    // From the hole's middle outwards along 120 rays: raw red floor, then the seared ring,
    // then the kidney's surface (or past its edge).
    let mid = eyes[0].project(centre, SIZE).expect("ahead");
    let mut outer = Vec::new();
    let mut floor_red = 0;
    for a in 0..120 {
        let d = Vec2::from_angle(a as f32 * std::f32::consts::TAU / 120.0);
        let at = |r: f32| rgb(&img, mid + d * r);
        let first = (0..150).find(|&r| at(r as f32).is_some_and(seared));
        let Some(first) = first else {
            panic!("ray {a}: no seared ring");
        };
        floor_red += usize::from(at(first as f32 * 0.5).is_some_and(red));
        // The ring's outer edge: the last seared pixel before two pixels that are not.
        let mut last = first;
        while (1..=2).any(|s| at((last + s) as f32).is_some_and(seared)) {
            last += 1;
        }
        outer.push(last as f32);
    }
    // The bed is raw red tissue on every ray (no fat or void seen through the hole).
    assert!(floor_red >= 118, "{floor_red} of 120 rays see red inside");
    // The outline is smooth: its radius changes little from ray to ray (3 degrees apart)
    // and bends gently (a bounded second difference), where a staircase of whole triangles
    // (0.5-1 mm, 4-8 px here) jumps.
    let n = outer.len();
    let mean = outer.iter().sum::<f32>() / n as f32;
    let jump = (0..n)
        .map(|i| (outer[(i + 1) % n] - outer[i]).abs())
        .fold(0.0, f32::max);
    let bend = (0..n)
        .map(|i| (outer[(i + n - 1) % n] - 2.0 * outer[i] + outer[(i + 1) % n]).abs())
        .fold(0.0, f32::max);
    eprintln!("outline radius {mean:.1} px, largest jump {jump:.1} px, largest bend {bend:.1} px");
    assert!(mean > 30.0, "the hole is {mean:.1} px across");
    assert!(jump <= 3.0, "the outline jumps {jump} px between rays");
    assert!(bend <= 4.0, "the outline bends {bend} px");
}

/// Pixels of `snap` drawn differently when its emissions (the smoke) are left out.
fn smoke_pixels(gpu: &Gpu, look: &Look, snap: &Snapshot) -> usize {
    let mut clear = snap.clone();
    clear.emissions.clear();
    common::pixels_differing(&eye(gpu, look, snap), &eye(gpu, look, &clear), 2)
}

#[test]
fn the_laser_smokes_while_it_cuts_and_only_then() {
    let s = Scenario::parse("builtin nephrectomy scenario", INFO.scenario).expect("scenario");
    let (dt, threshold) = (f64::from(s.dt_s), s.tools.cut_threshold);
    let keys = KeyTrace::parse("demo", INFO.demo_trace).expect("demo trace");
    let total = (keys.duration_s() / dt) as usize;
    let pulled: Vec<bool> = (0..total)
        .map(|k| keys.sample(k as f64 * dt).hands[1].buttons.trigger >= threshold)
        .collect();
    // Instants: half a second before the first cut; half a second into it; and 1.6 s (past a
    // puff's 1.5 s life) after the trigger is let go for good.
    let first = pulled.iter().position(|&p| p).expect("the demo cuts");
    let last = pulled.iter().rposition(|&p| p).expect("the demo cuts");
    let per_s = (1.0 / dt) as usize;
    let before = first - per_s / 2;
    let during = first + per_s / 2;
    assert!(pulled[during], "the demo still cuts half a second in");
    let after = last + per_s * 16 / 10;
    assert!(after < total, "the demo runs 1.6 s past its last cut");
    let mut n = Nephrectomy::new(s).expect("nephrectomy");
    let mut events = Vec::new();
    let mut shots = Vec::new();
    for step in 0..=after {
        n.step(&keys.sample(step as f64 * dt), step as u64, &mut events);
        if [before, during, after].contains(&step) {
            shots.push(n.snapshot(step as u64 + 1));
        }
    }
    let gpu = Gpu::headless(true).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)");
    let look = Look::monitor(&INFO);
    let counts: Vec<usize> = shots.iter().map(|s| smoke_pixels(&gpu, &look, s)).collect();
    gpu.check().expect("no GPU errors");
    eprintln!("smoke pixels before, during and after cutting: {counts:?}");
    assert_eq!(counts[0], 0, "smoke before the laser cut");
    assert!(counts[1] > 150, "{} smoke pixels while it cuts", counts[1]);
    assert_eq!(counts[2], 0, "smoke 1.6 s after the last cut");
}

/// Distance along the ray from `origin` (unit `dir`) to the nearest triangle of `m`.
fn depth(m: &ModelSnapshot, origin: Vec3, dir: Vec3) -> Option<f32> {
    let mut best: Option<f32> = None;
    for t in m.indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| m.positions[i as usize]);
        // Moller-Trumbore.
        let (e1, e2) = (b - a, c - a);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = origin - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = dir.dot(q) / det;
        let d = e2.dot(q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && d > 0.0 && best.is_none_or(|b| d < b) {
            best = Some(d);
        }
    }
    best
}

#[test]
fn a_grasper_pressed_side_on_dents_the_kidney_along_its_shaft() {
    let s = Scenario::parse("builtin nephrectomy scenario", INFO.scenario).expect("scenario");
    press_side_on(Hand::Left, s.grasper.tip_radius_m);
}

/// The laser probe's 5 mm body pushed side-on into the kidney dents it as the grasper does
/// (its beam off): it does not pass through the tissue.
#[test]
fn the_laser_probe_pressed_side_on_dents_the_kidney_too() {
    press_side_on(Hand::Right, 0.0025);
}

/// `hand`'s instrument, of radius `r` where tissue meets it, lowered side-on 2 mm into the
/// kidney and held there: the depth map of the drawn surface shows a trough along its shaft
/// and the tissue pushes it back out.
fn press_side_on(hand: Hand, r: f32) {
    let s = Scenario::parse("builtin nephrectomy scenario", INFO.scenario).expect("scenario");
    let mut n = Nephrectomy::new(s).expect("nephrectomy");
    let eye = INFO.view.eye;
    let tumour = n.tumour_center();
    let press = 0.002;
    let before = n.snapshot(0);
    let kidney = |s: &Snapshot| -> ModelSnapshot {
        s.models
            .iter()
            .find(|m| m.name == "kidney")
            .expect("kidney")
            .clone()
    };
    let k0 = kidney(&before);
    // How far the surface rises above the tangent plane at `p` (normal `normal`) along
    // `along`, from 4.5 cm behind the point (where the shaft ends) to 1.2 cm ahead of it.
    let rise = |p: Vec3, normal: Vec3, along: Vec3| -> f32 {
        let at = |u: f32| {
            let origin = p + normal * 0.03 + along * u;
            depth(&k0, origin, -normal).map_or(f32::INFINITY, |d| 0.03 - d)
        };
        (-45..=12)
            .map(|u| at(u as f32 * 1e-3))
            .fold(f32::MIN, f32::max)
    };
    // Of points of the parenchyma facing the laparoscope, 2.5 cm or more from the tumour's
    // middle, and 8 directions along the surface at each, the flattest: where the surface
    // falls away most along the whole shaft (the kidney is a bean with swells: a shaft must
    // not lie across its hilum's hollow or a swell, where it would plough in).
    let (p, normal, along) = (-4..=2)
        .flat_map(|i| (-4..=2).map(move |j| (i as f32 * 0.005, j as f32 * 0.005)))
        .filter_map(|(dx, dy)| {
            let aim = INFO.view.target + Vec3::new(dx, dy, 0.0);
            let (m, h) = n.world().cast_ray(eye, (aim - eye).normalize(), 1.0)?;
            (n.world().model(m).name() == "kidney" && h.point.distance(tumour) > 0.025)
                .then_some((h.point, h.normal))
        })
        .flat_map(|(p, normal)| {
            let first = normal.any_orthonormal_vector();
            (0..8).map(move |k| {
                let turn =
                    glam::Quat::from_axis_angle(normal, k as f32 * std::f32::consts::PI / 8.0);
                (p, normal, turn * first)
            })
        })
        .min_by(|a, b| rise(a.0, a.1, a.2).total_cmp(&rise(b.0, b.1, b.2)))
        .expect("a point of the kidney in view");
    // The shaft lies along the surface, its axis 2 mm less than its radius above it: pressed
    // 2 mm in. Its tip is 1 cm ahead of the point, the shaft runs back from there.
    let across = normal.cross(along);
    let axis = p + normal * (r - press);
    let mut frame = InputFrame::default();
    // The other hand's instrument waits at the laparoscope, pointing away.
    let other = 1 - hand.index();
    frame.hands[other].pose = Pose::looking_at(eye, eye + Vec3::Y);
    let mut events = Vec::new();
    // Lowered onto the surface over 0.2 s, then held there 0.4 s.
    for step in 0..150u64 {
        let lower = (1.0 - step as f32 / 50.0).max(0.0) * 0.01;
        let at = axis + normal * lower + along * 0.01;
        frame.hands[hand.index()].pose = Pose::looking_at(at, at + along);
        n.step(&frame, step, &mut events);
    }
    let after = n.snapshot(150);
    let k1 = kidney(&after);
    // The depth map: from 3 cm above the surface, straight down onto it, every millimetre
    // 2 cm either way along the shaft and 1 cm either way across it; the dent is how much
    // deeper the surface lies than at rest.
    let dent = |u: i32, v: i32| -> f32 {
        let origin = p + normal * 0.03 + along * (u as f32 * 1e-3) + across * (v as f32 * 1e-3);
        match (depth(&k0, origin, -normal), depth(&k1, origin, -normal)) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    };
    let map: Vec<Vec<f32>> = (-10..=10)
        .map(|v| (-20..=20).map(|u| dent(u, v)).collect())
        .collect();
    let deepest = map.iter().flatten().copied().fold(0.0, f32::max);
    let at = |u: i32, v: i32| map[(v + 10) as usize][(u + 20) as usize];
    let over = |d: f32| d > 0.3e-3;
    // Extent along the shaft (u) and across it (v), millimetres.
    let length = (-20..=20)
        .filter(|&u| (-10..=10).any(|v| over(at(u, v))))
        .count();
    let width = (-10..=10)
        .filter(|&v| (-20..=20).any(|u| over(at(u, v))))
        .count();
    let behind = at(-8, 0);
    let reaction = n.reactions()[hand.index()];
    eprintln!(
        "{hand:?}: dent {:.2} mm deep, {length} mm along the shaft, {width} mm across; 8 mm behind the \
         point: {:.2} mm; reaction {reaction} N",
        deepest * 1e3,
        behind * 1e3
    );
    assert!(
        (0.5 * press..=1.3 * press).contains(&deepest),
        "the dent is {:.2} mm deep for a 2 mm press",
        deepest * 1e3
    );
    // The shaft dents too, 1.8 cm behind the tip, where a tip alone would not reach.
    assert!(behind > 0.4 * press, "{:.2} mm behind", behind * 1e3);
    assert!(length >= 2 * width, "{length} mm long, {width} mm wide");
    // Away from the instrument the surface is where it was.
    for v in [-10, 10] {
        for u in -20..=20 {
            let d = at(u, v);
            assert!(d.abs() < 0.3e-3, "{:.2} mm at ({u}, {v})", d * 1e3);
        }
    }
    // The tissue pushes the instrument back out.
    assert!(reaction.dot(normal) > 0.0, "reaction {reaction}");
}

#[test]
fn a_laser_cut_into_the_renal_artery_bleeds_and_the_demo_injures_nothing() {
    let s = Scenario::parse("builtin nephrectomy scenario", INFO.scenario).expect("scenario");
    let dt = f64::from(s.dt_s);
    let mut n = Nephrectomy::new(s).expect("nephrectomy");
    // A point of the renal artery the laser can reach from just below the laparoscope.
    let from = INFO.view.eye - Vec3::Y * 0.01;
    let snap = n.snapshot(0);
    let artery = snap
        .models
        .iter()
        .find(|m| m.name == "renal_artery")
        .expect("artery");
    let aim = artery
        .positions
        .iter()
        .step_by(37)
        .copied()
        .find(|&v| {
            n.world()
                .cast_ray(from, (v - from).normalize(), 1.0)
                .is_some_and(|(m, _)| n.world().model(m).name() == "renal_artery")
        })
        .expect("a point of the artery in reach");
    let mut frame = InputFrame::default();
    frame.hands[0].pose = Pose::looking_at(from, from + Vec3::Y);
    frame.hands[1].pose = Pose::looking_at(from, aim);
    let mut events = Vec::new();
    // The trigger pulled 0.1 s on the artery, then let go; 1 s on from the cut.
    let steps = (1.1 / dt) as u64;
    for step in 0..steps {
        frame.hands[1].buttons.trigger = if step < (0.1 / dt) as u64 { 1.0 } else { 0.0 };
        n.step(&frame, step, &mut events);
    }
    let injuries: Vec<_> = events
        .iter()
        .filter_map(|e| match &e.kind {
            vesalius::sim::EventKind::Procedure(p) if p.name == "vessel_injured" => Some(p),
            _ => None,
        })
        .collect();
    assert_eq!(injuries.len(), 1, "one opening of the artery: {injuries:?}");
    assert_eq!(injuries[0].fields["vessel"], "renal_artery");
    assert_eq!(n.metrics.vessel_injuries, 1);
    let bleeding = n.snapshot(steps);
    assert_eq!(bleeding.bleeding.len(), 1);
    assert!(bleeding.bleeding[0].active(bleeding.time_s));
    // Blood shows: the monitor image with the bleeding and without it differ.
    let gpu = Gpu::headless(true).expect("a Vulkan adapter (CI installs mesa-vulkan-drivers)");
    let look = Look::monitor(&INFO);
    let mut dry = bleeding.clone();
    dry.bleeding.clear();
    let (wet, dry) = (eye(&gpu, &look, &bleeding), eye(&gpu, &look, &dry));
    let blood = common::pixels_differing(&wet, &dry, 2);
    gpu.check().expect("no GPU errors");
    eprintln!("blood pixels 1 s after the artery was cut: {blood}");
    assert!(blood > 30, "{blood} blood pixels");
    // The demo, an expert's session, opens no vessel.
    let (d, end) = demo_at(20.0);
    assert_eq!(d.metrics.vessel_injuries, 0);
    assert!(end.bleeding.is_empty());
}

/// The left eye of a look at a snapshot, 270 x 300.
fn eye(gpu: &Gpu, look: &Look, snap: &Snapshot) -> Vec<u8> {
    common::left_eye(gpu, look, snap, (270, 300))
}

#[test]
fn a_snapshot_built_beside_the_simulation_is_the_one_built_at_once() {
    // 8 s into the demo the laser is cutting round the tumour: the job reads the bodies now,
    // the simulation steps on for a second and cuts further (the kidney's mesh changes
    // while the job holds it), and the job, built later on another thread, draws the instant it was
    // handed over, as the snapshot built at once did.
    let (mut n, now) = demo_at(8.0);
    let s = Scenario::parse("builtin nephrectomy scenario", INFO.scenario).expect("scenario");
    let dt = f64::from(s.dt_s);
    let keys = KeyTrace::parse("demo", INFO.demo_trace).expect("demo trace");
    let at = now.step;
    let job = n.snapshot_job(at);
    assert!(!job.is_ready(), "the meshes are left to the build");
    let mut events = Vec::new();
    for step in at..at + 250 {
        n.step(&keys.sample(step as f64 * dt), step, &mut events);
    }
    let later = std::thread::spawn(move || job.build())
        .join()
        .expect("built");
    assert!(later == now, "the job drew another instant");
    // Vertices on a cut's edge in the kidney.
    let edge = |s: &Snapshot| {
        s.models
            .iter()
            .find(|m| m.name == "kidney")
            .map(|m| m.cut_edge.iter().filter(|&&c| c).count())
            .expect("kidney")
    };
    let after = n.snapshot(at + 250);
    assert!(
        edge(&now) > 0 && edge(&after) > edge(&now),
        "the laser did not cut further meanwhile"
    );
}
