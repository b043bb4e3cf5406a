//! Vesalius' OpenXR layer, the one crate of the workspace allowed `unsafe` (each block with a
//! `// SAFETY:` line). So far it holds the parts that need no runtime: the interaction profiles
//! (`profiles/*.toml`, HTC Vive first) and the session state machine. The OpenXR session over
//! the Khronos loader, the Vulkan -> wgpu interop and the simulated runtime
//! (`xr-bindings/sim-runtime`) follow.

pub mod app;
pub mod keyframes;
pub mod profiles;
pub mod session_state;
pub mod stage;
pub mod vive;

pub use openxr;
pub use profiles::{Action, ActionKind, Hand, Profile, ProfileError, is_path};
pub use session_state::{Command, Phase, SessionMachine};
