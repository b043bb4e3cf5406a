//! Force feedback: the 1 kHz servo loop, its local force model and its safety, over a device
//! seam that both kinds of vendor driver fit, with a simulated stylus for tests and demos.
//!
//! - [`device`]: the [`HapticDevice`] trait. A device reports its name, kind and limits (the
//!   lesser of what it says and `shared/HAPTICS.md`'s table) and is driven one of two ways:
//!   [`Drive::Pull`] (our 1 kHz thread reads and writes it: Force Dimension DHD, the simulated
//!   stylus) or [`Drive::Push`] (its vendor's scheduler calls our servo callback: OpenHaptics
//!   HD).
//! - [`simulated`]: a point-mass stylus held by a spring-damper hand that plays a script.
//! - [`safety`]: pure, clock-injected force safety: non-finite guard, force and stiffness
//!   clamps, a stall watchdog and a start-up ramp, each raising events.
//! - [`render`]: the local force model between simulation steps, and [`ServoCore`], one tick's
//!   whole work without a thread.
//! - [`servo`]: the servo loop (absolute 1 kHz deadlines for pull devices, or inside a push
//!   device's scheduler) and its timing figures.
//! - [`stand`]: the servo loop against a procedure stepping on its own thread (`vesalius
//!   haptics`).
//! - [`clutch`]: a stylus bound to one hand's instrument, with a clutch to re-centre it.
//! - [`rig`]: one or two devices bound to a session's instruments, each with its servo
//!   thread, and the input the simulation reads from them each step.
//! - [`bound`]: a recorded session driven by one or two devices, without a window (`vesalius
//!   run --haptics --no-window`).
//! - [`vendor`]: [`open_device`], where a device named on the command line is opened, and the
//!   adapters of the vendor drivers: [`HdStylus`] (OpenHaptics HD, push) and [`DhdStylus`]
//!   (Force Dimension DHD, pull).
//!
//! Units are SI throughout: metres, newtons, seconds, N/m. The device frame has x right, y up
//! and z toward the user, as the field has; a [`Workspace`] scales and offsets one into the
//! other.

pub mod bound;
pub mod clutch;
pub mod device;
pub mod render;
pub mod rig;
pub mod safety;
pub mod servo;
pub mod simulated;
pub mod stand;
pub mod vendor;

pub use bound::{BoundOptions, BoundRun, run_bound};
pub use clutch::{Binding, bound_frame, hand_workspace};
pub use device::{
    DeviceKind, DeviceLimits, DeviceState, Drive, HapticDevice, HapticsError, PullDevice,
    PushDevice, PushReply, ServoCallback,
};
pub use render::{ServoCore, Workspace, local_force};
pub use rig::{DeviceRun, Rig, RigInput, RigOptions, bound_hands};
pub use safety::{Safety, SafetyCounters, SafetyOutput, SafetyParams, TickInput};
pub use servo::{ServoConfig, ServoLinks, ServoReport, StylusSlot, run_servo};
pub use simulated::{Keyframe, Script, ScriptError, SimulatedStylus, StylusParams};
pub use stand::{StandOptions, StandReport, run_stand};
pub use vendor::{DeviceChoice, DhdStylus, HdStylus, open_device};
