//! The simulation core: fixed-step clock, per-step input, the tissue-model trait, contacts,
//! events, snapshots and the emissions they carry, the per-step haptic channel, the NaN
//! quarantine, the world that holds a procedure's models and the interactions between
//! them, and the vocabulary every layer shares about procedures (the `Procedure` trait, its
//! description, tools, plans, tunables, reports, the catalog handed down by the registry,
//! the operative field around the models and the benchmark lines).

mod attachment;
pub mod bench;
mod cases;
mod catalog;
mod clock;
mod coupling;
mod emission;
mod events;
pub mod field;
mod haptic;
mod hash;
mod input;
mod model;
mod plugin;
pub mod precompute;
mod procedure;
mod quarantine;
mod snapshot;
mod snapshot_bus;
mod world;

/// What tools, rays and cuts see of a model: collision's words, used by every model.
pub use crate::collision::{Collider, MeshSurface, TriangleSource};
pub use attachment::{Attachment, Link, LinkSpring};
pub use bench::{
    ALL_AWAKE_S, BenchError, BenchLine, ComputeFigures, ExtraBench, FrameFigures, GpuBench, Once,
    StepPace, peak_gflops,
};
pub use cases::{Case, Measured};
pub use catalog::Catalog;
pub use clock::{Clock, Pacing};
pub use coupling::{Couplings, Models, Phase, Uncoupled};
pub use emission::{Bleed, Emission, EmissionKind, EmissionLog};
pub use events::{EventKind, ProcedureEvent, SimEvent, shortest_f32};
pub use haptic::{HapticFrame, HapticSlot, SeqWords, ToolHaptics};
pub use hash::Fnv;
pub use input::{Buttons, Hand, HandInput, InputFrame, PadDirection, Pose};
pub use model::{Contact, ContactKind, CutStroke, ModelOutput, ModelSizes, TissueModel, ToolId};
pub use plugin::{ChecklistScore, completion_share, time_efficiency, weighted_score};
pub use procedure::{
    BuildError, BuildFn, DeviceChoice, MassSpring, ModelError, ModelReport, Options, Plan,
    Procedure, ProcedureInfo, ProcedureReport, SessionStatus, TaskStatus, TaskStep, ToolInfo,
    ToolKind, Tunable, Viewpoint, out_of_order, tick_off,
};
pub use quarantine::Quarantine;
pub use snapshot::{
    InstrumentShape, ModelSnapshot, ScopeView, Snapshot, SurfaceRole, ToolSnapshot,
};
pub use snapshot_bus::{MeshJob, SnapshotBus, SnapshotJob};
pub use world::{
    CHECKPOINT_STEPS, Interaction, MeshesJob, ModelId, ModelSet, PointForces, PointSource, World,
};

/// Runs a closure on a pool of so many workers (tests comparing the bytes of 1 and 2 threads).
#[cfg(test)]
pub(crate) use crate::testing::on_threads;
