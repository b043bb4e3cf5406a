use super::*;
use crate::collision::Instrument;
use crate::procedures::cholecystectomy::AnatomyParams;
use glam::Quat;

/// The shipped anatomy, laid out (half a second of settling).
fn scene() -> CholeScene {
    let a = Anatomy::generate(&AnatomyParams::default()).expect("anatomy");
    let mut s = CholeScene::new(a, SceneParams::default()).expect("scene");
    let laid = s.settle(0.5, 8, 60.0);
    assert!(laid < 0.015, "laying out moved {laid} m");
    s
}

fn largest_move(s: &CholeScene, from: &[Vec3], bodies: std::ops::RangeInclusive<u16>) -> f32 {
    s.solver()
        .particles
        .x
        .iter()
        .zip(from)
        .enumerate()
        .filter(|(i, _)| bodies.contains(&s.solver().particles.body[*i]))
        .map(|(_, (a, b))| a.distance(*b))
        .fold(0.0, f32::max)
}

#[test]
fn laid_out_and_left_alone_the_scene_stays_put() {
    let mut s = scene();
    let start = s.solver().particles.x.clone();
    for _ in 0..400 {
        let out = s.step(1e-3, [None, None], 0, &mut Vec::new());
        assert!(out.breaks.is_empty(), "a gallbladder strand tore by itself");
    }
    assert!(s.solver().particles.is_finite());
    // Organs, vessels and fascia stay within 3 mm; the fat's strands hold (a few may creep
    // past their tear strain).
    let moved = largest_move(&s, &start, body::LIVER..=body::FASCIA);
    assert!(moved < 0.003, "{moved}");
    assert!(
        s.solver().bonds.torn_segments() * 20 < s.solver().bonds.strands(),
        "{} of {}",
        s.solver().bonds.torn_segments(),
        s.solver().bonds.strands()
    );
}

/// A grasper from above (forward -Z turned to point down), its jaw at `jaw`.
fn grasper(jaw: Vec3, closed: bool) -> HandTool {
    let q = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    HandTool {
        instrument: Instrument::grasper(jaw, q, 0.0).expect("grasper"),
        jaw,
        closed,
    }
}

#[test]
fn pulling_the_fundus_away_tears_the_adhesions_and_is_felt() {
    let mut s = scene();
    // The fundus: the gallbladder's surface particle furthest along +x.
    let p = &s.solver().particles;
    let gb = &s.anatomy.organs[1];
    let fundus = gb
        .surface
        .iter()
        .copied()
        .max_by(|&a, &b| p.x[a as usize].x.total_cmp(&p.x[b as usize].x))
        .expect("fundus");
    let start = p.x[fundus as usize];
    // Closed on it, pulled down 1 mm: it holds, nothing tears, the grasper feels the pull.
    let mut torn = 0;
    let mut reaction = Vec3::ZERO;
    for k in 0..200 {
        let jaw = start - Vec3::Y * (0.001 * (k as f32 / 199.0));
        let out = s.step(1e-3, [None, Some(grasper(jaw, true))], 0, &mut Vec::new());
        torn += out.breaks.len();
        reaction = out.reactions[1];
        assert!(out.held[1] > 0, "the grasp holds particles");
    }
    assert_eq!(torn, 0);
    assert!(
        reaction.y > 0.0,
        "the tissue pulls the grasper back up: {reaction}"
    );
    // Then down and out 4 cm over 2 s: the adhesions tear, one by one.
    let mut steps_with_tears = 0;
    for k in 0..2000 {
        let t = k as f32 / 1999.0;
        let jaw = start - Vec3::Y * (0.001 + 0.04 * t) + Vec3::X * 0.01 * t;
        let out = s.step(1e-3, [None, Some(grasper(jaw, true))], 0, &mut Vec::new());
        torn += out.breaks.len();
        steps_with_tears += usize::from(!out.breaks.is_empty());
    }
    assert!(torn >= 10, "{torn}");
    assert!(steps_with_tears >= 5, "not all at once: {steps_with_tears}");
    assert!(s.solver().particles.is_finite());
}

#[test]
fn one_or_two_threads_give_the_same_bytes() {
    let run = |threads: usize| {
        crate::sim::on_threads(threads, || {
            let a = Anatomy::generate(&AnatomyParams::default()).expect("anatomy");
            let mut s = CholeScene::new(a, SceneParams::default()).expect("scene");
            s.settle(0.05, 4, 60.0);
            for _ in 0..50 {
                s.step(1e-3, [None, None], 0, &mut Vec::new());
            }
            s.state_hash()
        })
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn the_hook_cuts_what_is_near_it_and_knows_the_liver_when_it_touches_it() {
    let mut s = scene();
    // On a fascia node in the middle of the sheet: its constraints go, no strand far away.
    let mid = s.anatomy.fascia[s.anatomy.fascia.len() / 2];
    let at = s.solver().particles.x[mid as usize];
    let edges = s.solver().cloth.edges();
    let cut = s.dissect(at, 0.0015);
    assert!(cut.cloth > 0);
    assert!(s.solver().cloth.edges() < edges && edges - s.solver().cloth.edges() <= cut.cloth);
    // At an adhesion strand's middle: that strand is cut.
    let strand = s.solver().adhesion.strand_particles(0);
    let middle = s.solver().particles.x[strand[strand.len() / 2] as usize];
    let cut = s.dissect(middle, 0.0005);
    assert!(cut.adhesions.iter().any(|b| b.strand == 0), "{cut:?}");
    // The liver's capsule: a liver surface particle is touched, a point 2 cm below the
    // gallbladder touches nothing of the liver.
    let on_liver = s.solver().particles.x[s.anatomy.organs[0].surface[0] as usize];
    assert!(s.touching(body::LIVER, on_liver, 0.001) >= 1);
    assert_eq!(
        s.touching(body::LIVER, Vec3::new(0.0, -0.04, 0.0), 0.002),
        0
    );
    // The clippable vessels are the chains the anatomy built in that order.
    let [duct, artery] = s.clippable();
    assert_eq!(s.anatomy.vessels[duct.chain].body, body::CYSTIC_DUCT);
    assert_eq!(s.anatomy.vessels[artery.chain].body, body::CYSTIC_ARTERY);
}

#[test]
fn calots_triangle_is_hidden_by_its_fat_until_the_fat_is_cleared() {
    let mut s = scene();
    let towards_camera = Vec3::Z;
    let covered = s.calot_exposure(towards_camera, 12, 0.002);
    assert!(covered < 0.5, "{covered}");
    // The fat taken away (moved 10 cm aside): all of it seen.
    let p = &mut s.solver_mut().particles;
    for (x, b) in p.x.iter_mut().zip(&p.body) {
        if *b == body::FAT {
            x.x += 0.1;
        }
    }
    assert_eq!(s.calot_exposure(towards_camera, 12, 0.002), 1.0);
    // Seen from behind, the fat in front does not hide it either.
    let s = scene();
    let behind = s.calot_exposure(-Vec3::Z, 12, 0.002);
    assert!(behind > covered, "{behind} vs {covered}");
}
