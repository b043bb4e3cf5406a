//! The simulation core: fixed-step clock, per-step input, the tissue-model trait, contacts,
//! events, snapshots and the emissions they carry, the per-step haptic channel, the NaN
//! quarantine, and the world that holds a procedure's models and the interactions between
//! them.

mod attachment;
mod clock;
mod emission;
mod events;
mod haptic;
mod input;
mod model;
mod quarantine;
mod snapshot;
mod surface;
mod world;

pub use attachment::{Attachment, Link, LinkSpring};
pub use clock::{Clock, Pacing};
pub use emission::{Bleed, Emission, EmissionKind, EmissionLog};
pub use events::{EventKind, ProcedureEvent, SimEvent, shortest_f32};
pub use haptic::{HapticFrame, HapticSlot, SeqWords, ToolHaptics};
pub use input::{Buttons, Hand, HandInput, InputFrame, Pose};
pub use model::{Contact, ContactKind, CutStroke, ModelOutput, ModelSizes, TissueModel, ToolId};
pub use quarantine::Quarantine;
pub use snapshot::{
    InstrumentShape, ModelSnapshot, ScopeView, Snapshot, SnapshotBus, SurfaceRole, ToolSnapshot,
};
pub use surface::{Collider, MeshSurface, TriangleSource};
pub use world::{CHECKPOINT_STEPS, Interaction, ModelId, PointForces, PointSource, World};

/// Runs `f` on a pool of `threads` workers (tests comparing the bytes of 1 and 2 threads).
#[cfg(test)]
pub(crate) fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}
