//! Vesalius' bindings to the hardware's C interfaces, the one crate of the workspace allowed
//! `unsafe` (each block with a `// SAFETY:` line): OpenXR (the interaction profiles in
//! `profiles/*.toml`, HTC Vive first; the session state machine; the session over the Khronos
//! loader with the Vulkan -> wgpu interop in `app`) and the force-feedback devices in
//! `haptics` (OpenHaptics HD and Force Dimension DHD, their libraries opened at run time).
//! The simulated OpenXR runtime for tests lives in `xr-bindings/sim-runtime`.

pub mod app;
pub mod haptics;
pub mod keyframes;
pub mod profiles;
pub mod session_state;
pub mod stage;
pub mod vive;

pub use openxr;
pub use profiles::{Action, ActionKind, Hand, Profile, ProfileError, is_path};
pub use session_state::{Command, Phase, SessionMachine};
