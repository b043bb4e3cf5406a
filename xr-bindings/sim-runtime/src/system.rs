//! What the runtime is and what it simulates: its name and API version, the headset (an HTC
//! Vive: two 1080 x 1200 views at 90 Hz), and the handles of the one instance, system and
//! session it hands out.

use openxr_sys as sys;

/// The API version this runtime implements.
pub const API_VERSION: sys::Version = sys::Version::new(1, 0, 20);
pub const RUNTIME_NAME: &str = "Vesalius simulated runtime";
pub const SYSTEM_NAME: &str = "Vesalius simulated HMD (HTC Vive layout)";
/// Per-eye image size, pixels (the Vive's panels).
pub const EYE_SIZE: (u32, u32) = xr_bindings::vive::EYE_SIZE;
/// The graphics extension this runtime offers.
pub const VULKAN_ENABLE2: &str = "XR_KHR_vulkan_enable2";

/// The one instance handle this runtime hands out.
pub(crate) const INSTANCE: u64 = 1;
/// The head-mounted display's system id.
pub(crate) const SYSTEM: u64 = 1;
/// The one session handle this runtime hands out.
pub(crate) const SESSION: u64 = 1;

/// The Vive's refresh period: 90 Hz, nanoseconds.
pub const FRAME_PERIOD_NS: i64 = 1_000_000_000 / xr_bindings::vive::REFRESH_HZ;
/// Predicted display time of the first frame, nanoseconds (any fixed non-zero origin).
pub const FIRST_DISPLAY_NS: i64 = 1_000_000_000;
