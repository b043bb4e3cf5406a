//! Writes the rectum's demo trace (`assets/traces/rectum-demo.toml`) to stdout from the
//! default anatomy: the hook's end follows the midpoints of the plane between the fasciae
//! over the target in passes along the arc, after the grasper has lifted the rectum.
//! `cargo run --release --example rectum_trace > assets/traces/rectum-demo.toml`.

use glam::Vec3;
use vesalius::procedures::rectum::{Anatomy, AnatomyParams};

/// Rows of the 600-row grid the hook's end sweeps along, and the arc it sweeps, degrees.
const PASSES: [f32; 3] = [290.0, 299.5, 309.0];
const ARC_DEG: f32 = 37.5;
/// The hook's speed along the plane, m/s; the grasper's lift, m, and when it ends, s.
const SPEED_M_PER_S: f64 = 0.05;
const LIFT_M: f32 = 0.0025;
const LIFT_END_S: f64 = 0.9;
/// The grasper's row (30 % of the section) and when the hook starts down, s.
const GRASP_ROW: usize = 180;
const HOOK_WAIT_S: f64 = 0.6;

fn main() {
    let a = match Anatomy::generate(AnatomyParams::default()) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("the default anatomy: {e}");
            std::process::exit(1);
        }
    };
    let m = &a.membrane;
    let (rows, cols) = (m.rows, m.cols);
    // The plane's midpoint at a fractional row and an angle (bilinear between nodes).
    let plane = |row: f32, deg: f32| -> Vec3 {
        let c = deg.rem_euclid(360.0) / 360.0 * cols as f32;
        let (j0, fj) = (c.floor() as usize % cols, c.fract());
        let j1 = (j0 + 1) % cols;
        let (i0, fi) = (row.floor() as usize, row.fract());
        let i1 = (i0 + 1).min(rows - 1);
        let p = |i: usize, j: usize| {
            0.5 * (m.positions[1][i * cols + j] + m.positions[2][i * cols + j])
        };
        p(i0, j0)
            .lerp(p(i0, j1), fj)
            .lerp(p(i1, j0).lerp(p(i1, j1), fj), fi)
    };
    // The hook points down (-y) with its hook along -z: its end lies 6 mm on -z of its
    // corner, which is where the hand is.
    let off = Vec3::new(0.0, 0.0, 0.006);
    let down = Vec3::new(0.0, -0.05, 0.0);
    let above = Vec3::new(0.0, 0.03, 0.0);
    let mut right: Vec<(f64, Vec3, f32)> = Vec::new();
    let mut t = 0.0f64;
    let start = plane(PASSES[0], ARC_DEG) + off;
    right.push((0.0, start + above, 0.0));
    t += HOOK_WAIT_S;
    right.push((t, start + above, 0.0));
    t += 0.5;
    right.push((t, start, 0.0));
    t += 0.05;
    right.push((t, start, 1.0));
    let mut last = start;
    for (k, &row) in PASSES.iter().enumerate() {
        let (from, to) = if k % 2 == 0 {
            (ARC_DEG, -ARC_DEG)
        } else {
            (-ARC_DEG, ARC_DEG)
        };
        let n = ((to - from).abs() / 3.0).ceil() as usize;
        for s in 0..=n {
            let p = plane(row, from + (to - from) * s as f32 / n as f32) + off;
            t += (f64::from(p.distance(last)) / SPEED_M_PER_S).max(1e-3);
            right.push((t, p, 1.0));
            last = p;
        }
    }
    t += 0.05;
    right.push((t, last, 0.0));
    t += 0.4;
    right.push((t, last + above, 0.0));
    let jaw = m.positions[0][GRASP_ROW * cols];
    let up = Vec3::new(0.0, LIFT_M, 0.0);
    let left = [
        (0.0, jaw + above, 0.0),
        (0.4, jaw, 0.0),
        (0.45, jaw, 1.0),
        (LIFT_END_S, jaw + up, 1.0),
        (t, jaw + up, 1.0),
    ];
    let v = |p: Vec3| format!("[{:.5}, {:.5}, {:.5}]", p.x, p.y, p.z);
    println!(
        "# Demo: the rectum drill (about {t:.1} s), written by examples/rectum_trace.rs from the\n\
         # default anatomy's plane (the midpoints between the fasciae).\n\
         # Left (grasper): comes down onto the rectum's anterior surface at 30 % of the\n\
         # section, closes, lifts it {:.1} mm and holds it (the exposure). Right (L-hook,\n\
         # pointing down, its hook along -z): comes down 6 mm beside the first target point so\n\
         # that its end lies in the plane, turns its current on and sweeps the target's arc\n\
         # ({ARC_DEG} degrees either side of the front) in {} passes {:.2} mm apart at {} cm/s;\n\
         # then the current off and out. Positions in metres.\n\
         procedure = \"rectum\"\n",
        LIFT_M * 1e3,
        PASSES.len(),
        (PASSES[1] - PASSES[0]) * 0.25,
        SPEED_M_PER_S * 100.0,
    );
    for (t, p, g) in left {
        println!(
            "[[left]]\nt_s = {t:.3}\nposition = {}\ntarget = {}\ngrip = {g:.1}\n",
            v(p),
            v(p + down)
        );
    }
    for (t, p, tr) in right {
        println!(
            "[[right]]\nt_s = {t:.3}\nposition = {}\ntarget = {}\ntrigger = {tr:.1}\n",
            v(p),
            v(p + down)
        );
    }
}
