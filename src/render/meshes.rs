//! The renderer's GPU meshes: buffers that grow only when what they hold outgrows them, the
//! draw of an index range, and the instruments built as cylinders each frame.

use super::camera::{self, EyeView};
use super::{GpuMesh, Vertex, material};
use crate::profiler::{Category, FrameCounters, Ledger, Tracked};
use crate::sim::{InstrumentShape, ToolSnapshot};
use glam::Vec3;
use std::sync::Arc;

pub(super) fn tracked_buffer(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    label: &str,
    bytes: u64,
    usage: wgpu::BufferUsages,
    category: Category,
) -> Tracked<wgpu::Buffer> {
    // wgpu wants copy sizes in multiples of 4 and no zero-sized bindings.
    let size = bytes.max(16).next_multiple_of(4);
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage,
        mapped_at_creation: false,
    });
    Tracked::new(buffer, size, category, ledger)
}

/// Draws indices `range` of a mesh (nothing when it is empty) and counts it, with its
/// vertices if `vertices`.
pub(super) fn draw_range(
    pass: &mut wgpu::RenderPass<'_>,
    mesh: &GpuMesh,
    range: std::ops::Range<u32>,
    vertices: bool,
    c: &mut FrameCounters,
) {
    if range.is_empty() {
        return;
    }
    pass.set_vertex_buffer(0, mesh.vertex.inner.slice(..));
    pass.set_index_buffer(mesh.index.inner.slice(..), wgpu::IndexFormat::Uint32);
    c.triangles += (range.end - range.start) as u64 / 3;
    pass.draw_indexed(range, 0, 0..1);
    c.draw_calls += 1;
    if vertices {
        c.vertices += mesh.vertex_count as u64;
    }
}

pub(super) fn empty_mesh(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    verts: u64,
    indices: u64,
) -> GpuMesh {
    GpuMesh {
        vertex: tracked_buffer(
            device,
            ledger,
            "vertices",
            verts * std::mem::size_of::<Vertex>() as u64,
            wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            Category::Mesh,
        ),
        index: tracked_buffer(
            device,
            ledger,
            "indices",
            indices * 4,
            wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
            Category::Mesh,
        ),
        vertex_count: 0,
        index_count: 0,
        opaque_count: 0,
    }
}

/// Writes vertices and indices into a mesh's buffers, growing them (by a quarter more than
/// needed) only when they do not fit.
pub(super) fn upload(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    ledger: &Arc<Ledger>,
    mesh: &mut GpuMesh,
    verts: &[Vertex],
    indices: &[u32],
) {
    let vbytes = std::mem::size_of_val(verts) as u64;
    let ibytes = std::mem::size_of_val(indices) as u64;
    ensure_capacity(device, ledger, mesh, vbytes, ibytes);
    if vbytes > 0 {
        queue.write_buffer(&mesh.vertex, 0, bytemuck::cast_slice(verts));
    }
    if ibytes > 0 {
        queue.write_buffer(&mesh.index, 0, bytemuck::cast_slice(indices));
    }
    mesh.vertex_count = verts.len() as u32;
    mesh.index_count = indices.len() as u32;
    mesh.opaque_count = mesh.index_count;
}

/// Grows a mesh's buffers (by a quarter more than asked) when they are too small.
pub(super) fn ensure_capacity(
    device: &wgpu::Device,
    ledger: &Arc<Ledger>,
    mesh: &mut GpuMesh,
    vbytes: u64,
    ibytes: u64,
) {
    if vbytes > mesh.vertex.bytes() {
        mesh.vertex = tracked_buffer(
            device,
            ledger,
            "vertices",
            vbytes + vbytes / 4,
            wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            Category::Mesh,
        );
    }
    if ibytes > mesh.index.bytes() {
        mesh.index = tracked_buffer(
            device,
            ledger,
            "indices",
            ibytes + ibytes / 4,
            wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST,
            Category::Mesh,
        );
    }
}

/// An open cone of 8 sides from `a` (radius `radii[0]`) to `b` (`radii[1]`).
pub(super) fn cone(
    a: Vec3,
    b: Vec3,
    radii: [f32; 2],
    mat: u32,
    v: &mut Vec<Vertex>,
    idx: &mut Vec<u32>,
) {
    let axis = (b - a).normalize_or(Vec3::Z);
    let side = axis.any_orthonormal_vector();
    let up = axis.cross(side);
    let base = v.len() as u32;
    const SIDES: u32 = 8;
    for k in 0..SIDES {
        let t = k as f32 / SIDES as f32 * std::f32::consts::TAU;
        let n = side * t.cos() + up * t.sin();
        for (end, radius) in [(a, radii[0]), (b, radii[1])] {
            v.push(Vertex {
                position: (end + n * radius).to_array(),
                normal: n.to_array(),
                material: mat,
            });
        }
    }
    for k in 0..SIDES {
        let (i0, i1) = (base + 2 * k, base + 2 * ((k + 1) % SIDES));
        idx.extend_from_slice(&[i0, i1, i0 + 1, i1, i1 + 1, i0 + 1]);
    }
}

/// A part of an instrument: a cone from `a` (radius `radii[0]`) to `b` (`radii[1]`), metres.
pub(super) type Part = (Vec3, Vec3, [f32; 2], u32);

/// The shaft's radius: a 5 mm laparoscopic instrument, m.
pub const SHAFT_RADIUS_M: f32 = 0.0025;
/// How much of the shaft is drawn behind the working end, m.
const SHAFT_LENGTH_M: f32 = 0.30;
/// Jaw lengths and how far each jaw turns from the axis when wide open, radians.
pub const GRASPER_JAW_M: f32 = 0.016;
pub const GRASPER_OPEN_RAD: f32 = 30.0 * std::f32::consts::PI / 180.0;
const SCISSORS_BLADE_M: f32 = 0.014;
const SCISSORS_OPEN_RAD: f32 = 20.0 * std::f32::consts::PI / 180.0;
/// The blades' curve: the outer half turns this much further, to one side.
const SCISSORS_CURVE_RAD: f32 = 15.0 * std::f32::consts::PI / 180.0;
const CLIP_JAW_M: f32 = 0.012;
const CLIP_OPEN_RAD: f32 = 12.0 * std::f32::consts::PI / 180.0;
/// The L-hook: the insulated neck's length, and the foot's length (the collision model's
/// 6 mm wire, `collision::Instrument::l_hook`, whose end is the tip).
const HOOK_NECK_M: f32 = 0.010;
pub const HOOK_FOOT_M: f32 = 0.006;

/// The parts of an instrument as drawn: its shaft along `direction` ending at the working
/// end, and the end its shape has, the jaws opened as `jaw` says. Its roll about the shaft is
/// fixed by the direction (jaws open in the plane of `direction` and a vector normal to it).
pub(super) fn instrument_parts(t: &ToolSnapshot, out: &mut Vec<Part>) {
    let d = t.direction.normalize_or(Vec3::NEG_Z);
    // The roll: the instrument's own up, square to the shaft; without one, any.
    let up = (t.up - d * t.up.dot(d))
        .try_normalize()
        .unwrap_or_else(|| d.cross(d.any_orthonormal_vector()));
    let side = up.cross(d);
    let tip = t.tip;
    let m = material::INSTRUMENT;
    let shaft = |end: Vec3, out: &mut Vec<Part>| {
        out.push((end - d * SHAFT_LENGTH_M, end, [SHAFT_RADIUS_M; 2], m));
    };
    let open = t.jaw.clamp(0.0, 1.0);
    // Two jaws of `length` hinged at the shaft's end, each turned `angle` off the axis, in
    // the plane of the axis and `up`; closed, they meet along the axis and end at the tip.
    let jaws = |length: f32, angle: f32, radii: [f32; 2], out: &mut Vec<Part>| {
        let hinge = tip - d * length;
        shaft(hinge, out);
        for s in [1.0f32, -1.0] {
            let dir = d * angle.cos() + up * (s * angle.sin());
            out.push((
                hinge + up * (s * radii[0] * 0.6),
                hinge + dir * length,
                radii,
                m,
            ));
        }
    };
    match t.shape {
        InstrumentShape::Plain => {
            let jaw_base = tip - d * 0.012;
            shaft(jaw_base, out);
            let s = side * 0.0015;
            for s in [s, -s] {
                out.push((jaw_base + s, tip + s * 0.5, [0.0008; 2], m));
            }
        }
        InstrumentShape::Grasper => jaws(
            GRASPER_JAW_M,
            open * GRASPER_OPEN_RAD,
            [0.0012, 0.0008],
            out,
        ),
        InstrumentShape::ClipApplier => {
            jaws(CLIP_JAW_M, open * CLIP_OPEN_RAD, [0.0014, 0.0011], out)
        }
        InstrumentShape::Scissors => {
            let hinge = tip - d * SCISSORS_BLADE_M;
            shaft(hinge, out);
            let half = 0.5 * SCISSORS_BLADE_M;
            for s in [1.0f32, -1.0] {
                let a = open * SCISSORS_OPEN_RAD;
                let inner = d * a.cos() + up * (s * a.sin());
                let b = a - SCISSORS_CURVE_RAD;
                let outer = (d * b.cos() + up * (s * b.sin())) * SCISSORS_CURVE_RAD.cos()
                    + side * SCISSORS_CURVE_RAD.sin();
                let knee = hinge + inner * half;
                out.push((hinge, knee, [0.0011, 0.0008], m));
                out.push((knee, knee + outer * half, [0.0008, 0.0003], m));
            }
        }
        InstrumentShape::Hook => {
            // The foot ends at the tip; the elbow is a foot's length back along `up`.
            let elbow = tip - up * HOOK_FOOT_M;
            let neck = elbow - d * HOOK_NECK_M;
            shaft(neck, out);
            out.push((neck, elbow, [0.0012, 0.0008], m));
            out.push((elbow, tip, [0.0007, 0.0005], m));
        }
        InstrumentShape::Laser => {
            let taper = tip - d * 0.006;
            shaft(taper, out);
            out.push((taper, tip, [SHAFT_RADIUS_M, 0.0008], m));
        }
        InstrumentShape::Probe => {
            let taper = tip - d * 0.004;
            shaft(taper, out);
            out.push((taper, tip, [SHAFT_RADIUS_M, 0.0015], m));
        }
    }
}

/// The part of segment a-b (a cylinder of `radius`) in front of both eyes' near planes, kept
/// a cylinder radius clear of them; None when nothing is left.
pub(super) fn clip_to_eyes(
    a: Vec3,
    b: Vec3,
    radius: f32,
    eyes: &[EyeView; 2],
) -> Option<(Vec3, Vec3)> {
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for e in eyes {
        let forward = e.orientation * Vec3::NEG_Z;
        let clear = 2.0 * camera::NEAR_M + radius;
        let (da, db) = (
            (a - e.position).dot(forward) - clear,
            (b - e.position).dot(forward) - clear,
        );
        if da < 0.0 && db < 0.0 {
            return None;
        }
        if da < 0.0 {
            t0 = t0.max(da / (da - db));
        } else if db < 0.0 {
            t1 = t1.min(da / (da - db));
        }
    }
    (t1 > t0).then(|| (a.lerp(b, t0), a.lerp(b, t1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parts(shape: InstrumentShape, jaw: f32) -> Vec<Part> {
        let t = ToolSnapshot {
            tip: Vec3::new(0.01, 0.02, 0.03),
            direction: Vec3::new(0.0, -0.6, -0.8),
            shape,
            jaw,
            ..ToolSnapshot::default()
        };
        let mut out = Vec::new();
        instrument_parts(&t, &mut out);
        out
    }

    #[test]
    fn a_grasper_opens_its_jaws_as_wide_as_its_grip_lets_go() {
        let tip = Vec3::new(0.01, 0.02, 0.03);
        // Shut: both jaws end at the tip.
        let shut = parts(InstrumentShape::Grasper, 0.0);
        assert_eq!(shut.len(), 3, "a shaft and two jaws");
        for p in &shut[1..] {
            assert!(p.1.distance(tip) < 1e-6, "{:?}", p.1);
        }
        // Wide open: 30 degrees each, the ends 2 L sin 30 = 16 mm apart.
        let open = parts(InstrumentShape::Grasper, 1.0);
        let gap = open[1].1.distance(open[2].1);
        let expected = 2.0 * GRASPER_JAW_M * GRASPER_OPEN_RAD.sin();
        assert!((gap - expected).abs() < 1e-5, "{gap} vs {expected}");
        // Half open: half the angle.
        let half = parts(InstrumentShape::Grasper, 0.5);
        let gap = half[1].1.distance(half[2].1);
        let expected = 2.0 * GRASPER_JAW_M * (0.5 * GRASPER_OPEN_RAD).sin();
        assert!((gap - expected).abs() < 1e-5, "{gap} vs {expected}");
        // The shaft is 5 mm across and ends where the jaws are hinged.
        assert_eq!(open[0].2, [SHAFT_RADIUS_M; 2]);
        assert!((open[0].1.distance(tip) - GRASPER_JAW_M).abs() < 1e-6);
    }

    #[test]
    fn the_hooks_foot_points_where_the_instruments_up_says_as_the_collision_model_has_it() {
        let q = glam::Quat::from_rotation_x(-0.7) * glam::Quat::from_rotation_y(0.4);
        let corner = Vec3::new(0.01, 0.02, 0.03);
        let model = crate::collision::Instrument::l_hook(corner, q).expect("hook");
        let foot = &model.cylinders()[1];
        let t = ToolSnapshot {
            tip: foot.p1(),
            direction: q * Vec3::NEG_Z,
            shape: InstrumentShape::Hook,
            up: q * Vec3::Y,
            ..ToolSnapshot::default()
        };
        let mut out = Vec::new();
        instrument_parts(&t, &mut out);
        // The drawn foot is the collision model's: from its corner to its end.
        assert!(out[2].0.distance(corner) < 1e-6, "{} vs {corner}", out[2].0);
        assert!(out[2].1.distance(foot.p1()) < 1e-6);
    }

    #[test]
    fn an_l_hook_ends_in_a_foot_at_right_angles_to_its_shaft() {
        let d = Vec3::new(0.0, -0.6, -0.8);
        let hook = parts(InstrumentShape::Hook, 0.0);
        let (elbow, end) = (hook[2].0, hook[2].1);
        assert!(end.distance(Vec3::new(0.01, 0.02, 0.03)) < 1e-6);
        assert!((elbow.distance(end) - HOOK_FOOT_M).abs() < 1e-6);
        assert!((end - elbow).normalize().dot(d).abs() < 1e-5);
        // The neck runs along the shaft.
        assert!((hook[1].1 - hook[1].0).normalize().dot(d) > 0.9999);
    }

    #[test]
    fn every_shape_is_drawn_its_own_way_near_its_tip() {
        let shapes = [
            InstrumentShape::Plain,
            InstrumentShape::Grasper,
            InstrumentShape::Scissors,
            InstrumentShape::ClipApplier,
            InstrumentShape::Hook,
            InstrumentShape::Laser,
            InstrumentShape::Probe,
        ];
        let tip = Vec3::new(0.01, 0.02, 0.03);
        let drawn: Vec<Vec<Part>> = shapes.iter().map(|&s| parts(s, 0.5)).collect();
        for (k, p) in drawn.iter().enumerate() {
            for part in p {
                for end in [part.0, part.1] {
                    assert!(
                        end.distance(tip) <= SHAFT_LENGTH_M + 0.02,
                        "{:?}",
                        shapes[k]
                    );
                }
                assert!(part.2.iter().all(|&r| r > 0.0 && r <= SHAFT_RADIUS_M));
            }
            for q in &drawn[..k] {
                assert_ne!(p, q, "{:?} looks like another shape", shapes[k]);
            }
        }
        // The scissors' blades curve to one side of the plane they open in.
        let d = Vec3::new(0.0, -0.6, -0.8).normalize();
        let side = d.any_orthonormal_vector();
        let blades = &drawn[2];
        assert!((blades[2].1 - blades[2].0).dot(side) > 0.0);
    }
}
