//! The Unity-profiler counters of the nephrectomy paper (Tables 2 and 3), measured on our own
//! renderer: batches, draw calls, SetPass calls, triangles, vertices, VRAM, memory by category
//! and scene objects, plus CPU time per stage.
//!
//! GPU memory is counted by a ledger that every buffer and texture we create registers with and
//! leaves when it is dropped. Heap memory comes from a probe the binary installs (a counting
//! global allocator); without one it reads 0.

use serde::Serialize;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

/// What a GPU allocation is for, as Unity's memory profiler groups it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Category {
    /// Render targets, depth buffers.
    Texture,
    /// Vertex and index buffers.
    Mesh,
    /// Uniform buffers holding material and frame constants.
    Material,
    /// Staging and readback buffers.
    Staging,
}

const CATEGORIES: usize = 4;

impl Category {
    fn slot(self) -> usize {
        match self {
            Category::Texture => 0,
            Category::Mesh => 1,
            Category::Material => 2,
            Category::Staging => 3,
        }
    }
}

/// Live GPU allocations by category (count and bytes).
#[derive(Debug, Default)]
pub struct Ledger {
    count: [AtomicI64; CATEGORIES],
    bytes: [AtomicI64; CATEGORIES],
}

impl Ledger {
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    fn add(&self, c: Category, bytes: u64, sign: i64) {
        self.count[c.slot()].fetch_add(sign, Ordering::Relaxed);
        self.bytes[c.slot()].fetch_add(sign * bytes as i64, Ordering::Relaxed);
    }

    /// Count and bytes currently alive in one category.
    pub fn live(&self, c: Category) -> CountBytes {
        CountBytes {
            count: self.count[c.slot()].load(Ordering::Relaxed).max(0) as u64,
            bytes: self.bytes[c.slot()].load(Ordering::Relaxed).max(0) as u64,
        }
    }

    /// Every live GPU byte.
    pub fn total_bytes(&self) -> u64 {
        (0..CATEGORIES)
            .map(|k| self.bytes[k].load(Ordering::Relaxed).max(0) as u64)
            .sum()
    }
}

/// A GPU resource registered with a ledger for as long as it lives.
#[derive(Debug)]
pub struct Tracked<T> {
    pub inner: T,
    bytes: u64,
    category: Category,
    ledger: Arc<Ledger>,
}

impl<T> Tracked<T> {
    pub fn new(inner: T, bytes: u64, category: Category, ledger: &Arc<Ledger>) -> Self {
        ledger.add(category, bytes, 1);
        Tracked {
            inner,
            bytes,
            category,
            ledger: ledger.clone(),
        }
    }

    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl<T> std::ops::Deref for Tracked<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.inner
    }
}

impl<T> Drop for Tracked<T> {
    fn drop(&mut self) {
        self.ledger.add(self.category, self.bytes, -1);
    }
}

static HEAP_PROBE: OnceLock<fn() -> u64> = OnceLock::new();

/// Installs the function that reports live heap bytes (the binary's counting allocator).
pub fn set_heap_probe(probe: fn() -> u64) {
    let _ = HEAP_PROBE.set(probe);
}

/// Live heap bytes, or 0 when no counting allocator is installed.
pub fn heap_bytes() -> u64 {
    HEAP_PROBE.get().map_or(0, |p| p())
}

/// Whether heap bytes are being measured.
pub fn heap_measured() -> bool {
    HEAP_PROBE.get().is_some()
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct CountBytes {
    pub count: u64,
    pub bytes: u64,
}

/// CPU time per stage for one frame, milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StageTimes {
    pub simulation_ms: f64,
    pub collision_ms: f64,
    pub render_encode_ms: f64,
    pub submit_ms: f64,
    pub ui_ms: f64,
    pub haptics_ms: f64,
}

/// The counters of one rendered frame, named as in the paper's Tables 2 and 3.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FrameCounters {
    pub frame: u64,
    /// Draw submissions after batching (we do no dynamic batching: one per draw call).
    pub batches: u64,
    pub draw_calls: u64,
    /// Pipeline or material switches.
    pub setpass_calls: u64,
    /// Triangles and vertices submitted (a multiview pass submits the scene once for both eyes;
    /// two passes submit it twice).
    pub triangles: u64,
    pub vertices: u64,
    /// Render passes this frame (1 with multiview, 2 without).
    pub passes: u64,
    pub multiview: bool,
    /// Every GPU buffer and texture we created and still hold, bytes.
    pub vram_bytes: u64,
    /// Heap bytes (counting allocator) plus GPU bytes.
    pub total_memory_bytes: u64,
    pub textures: CountBytes,
    pub meshes: CountBytes,
    pub materials: CountBytes,
    /// Scene entities: organs, instruments, beam, light, eye rig.
    pub objects: u64,
    pub cpu: StageTimes,
}

impl FrameCounters {
    pub const CSV_HEADER: &'static str = "frame,batches,draw_calls,setpass_calls,triangles,vertices,passes,multiview,vram_bytes,total_memory_bytes,textures_count,textures_bytes,meshes_count,meshes_bytes,materials_count,materials_bytes,objects,simulation_ms,collision_ms,render_encode_ms,submit_ms,ui_ms,haptics_ms";

    pub fn csv_row(&self) -> String {
        let c = &self.cpu;
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3}",
            self.frame,
            self.batches,
            self.draw_calls,
            self.setpass_calls,
            self.triangles,
            self.vertices,
            self.passes,
            self.multiview as u8,
            self.vram_bytes,
            self.total_memory_bytes,
            self.textures.count,
            self.textures.bytes,
            self.meshes.count,
            self.meshes.bytes,
            self.materials.count,
            self.materials.bytes,
            self.objects,
            c.simulation_ms,
            c.collision_ms,
            c.render_encode_ms,
            c.submit_ms,
            c.ui_ms,
            c.haptics_ms
        )
    }
}

/// The paper's figures (Tables 2 and 3): one column measured on the CPU build, one on the GPU.
#[derive(Debug, Clone, Serialize)]
pub struct PaperColumn {
    pub batches: u64,
    pub draw_calls: u64,
    pub setpass_calls: u64,
    pub triangles: u64,
    pub vertices: u64,
    pub vram_bytes: u64,
    pub total_memory_bytes: u64,
    pub textures: CountBytes,
    pub meshes: CountBytes,
    pub materials: CountBytes,
    pub objects: u64,
}

const KB: u64 = 1000;
const MB: u64 = 1000 * 1000;

impl FrameCounters {
    /// Our frame in the shape of the paper's columns, to print beside them.
    pub fn column(&self) -> PaperColumn {
        PaperColumn {
            batches: self.batches,
            draw_calls: self.draw_calls,
            setpass_calls: self.setpass_calls,
            triangles: self.triangles,
            vertices: self.vertices,
            vram_bytes: self.vram_bytes,
            total_memory_bytes: self.total_memory_bytes,
            textures: self.textures,
            meshes: self.meshes,
            materials: self.materials,
            objects: self.objects,
        }
    }
}

/// Table 2 and 3, "CPU" column.
pub fn paper_cpu() -> PaperColumn {
    PaperColumn {
        batches: 19,
        draw_calls: 19,
        setpass_calls: 20,
        triangles: 50_200,
        vertices: 123_900,
        vram_bytes: 9_200 * KB,
        total_memory_bytes: 38_900 * KB,
        textures: CountBytes {
            count: 29,
            bytes: 299 * KB,
        },
        meshes: CountBytes {
            count: 11,
            bytes: 6_800 * KB,
        },
        materials: CountBytes {
            count: 24,
            bytes: 79 * KB,
        },
        objects: 14,
    }
}

/// Table 2 and 3, "GPU" column.
pub fn paper_gpu() -> PaperColumn {
    PaperColumn {
        batches: 9,
        draw_calls: 9,
        setpass_calls: 9,
        triangles: 50_200,
        vertices: 121_900,
        vram_bytes: 9_100 * KB,
        total_memory_bytes: 49_900 * KB,
        textures: CountBytes {
            count: 31,
            bytes: 300 * KB,
        },
        meshes: CountBytes {
            count: 6,
            bytes: 6_800 * KB,
        },
        materials: CountBytes {
            count: 26,
            bytes: 87 * KB,
        },
        objects: 16,
    }
}

/// Megabytes (10^6 bytes, as the paper's tables read) for printing.
pub fn mb(bytes: u64) -> f64 {
    bytes as f64 / MB as f64
}

/// A frame counter shared by a renderer's frames.
#[derive(Debug, Default)]
pub struct FrameClock(AtomicU64);

impl FrameClock {
    pub fn next(&self) -> u64 {
        self.0.fetch_add(1, Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ledger_counts_creation_and_release() {
        let ledger = Ledger::new();
        let a = Tracked::new((), 1000, Category::Mesh, &ledger);
        let b = Tracked::new((), 24, Category::Material, &ledger);
        assert_eq!(
            ledger.live(Category::Mesh),
            CountBytes {
                count: 1,
                bytes: 1000
            }
        );
        assert_eq!(ledger.total_bytes(), 1024);
        drop(a);
        assert_eq!(ledger.live(Category::Mesh), CountBytes::default());
        assert_eq!(ledger.total_bytes(), 24);
        drop(b);
        assert_eq!(ledger.total_bytes(), 0);
    }

    #[test]
    fn a_csv_row_has_a_value_per_header_column() {
        let row = FrameCounters::default().csv_row();
        assert_eq!(
            row.split(',').count(),
            FrameCounters::CSV_HEADER.split(',').count()
        );
    }
}
