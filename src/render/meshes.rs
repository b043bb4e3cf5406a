//! The renderer's GPU meshes: buffers that grow only when what they hold outgrows them, the
//! draw of an index range, and the instruments built as cylinders each frame.

use super::camera::{self, EyeView};
use super::{GpuMesh, Vertex, material};
use crate::profiler::{Category, FrameCounters, Ledger, Tracked};
use crate::sim::ToolSnapshot;
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

/// An open cylinder of 8 sides from `a` to `b`.
pub(super) fn cylinder(
    a: Vec3,
    b: Vec3,
    radius: f32,
    mat: u32,
    v: &mut Vec<Vertex>,
    idx: &mut Vec<u32>,
) {
    cone(a, b, [radius, radius], mat, v, idx);
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

/// A laparoscopic instrument: a 5 mm shaft ending at the tip, with two short jaws.
/// Shaft and two jaws of an instrument as (from, to, radius, material) cylinders.
pub(super) fn instrument_segments(t: &ToolSnapshot, out: &mut Vec<(Vec3, Vec3, f32, u32)>) {
    let d = t.direction.normalize_or(Vec3::NEG_Z);
    let jaw_base = t.tip - d * 0.012;
    out.push((t.tip - d * 0.30, jaw_base, 0.0025, material::INSTRUMENT));
    let side = d.any_orthonormal_vector() * 0.0015;
    for s in [side, -side] {
        out.push((jaw_base + s, t.tip + s * 0.5, 0.0008, material::INSTRUMENT));
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
