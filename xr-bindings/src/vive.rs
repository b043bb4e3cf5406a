//! The HTC Vive's figures that both the application (headless eyes) and the simulated runtime
//! (the headset it pretends to be) use.

/// Per-eye panel, pixels.
pub const EYE_SIZE: (u32, u32) = (1080, 1200);
/// Left eye's field of view as OpenXR gives it (left, right, up, down), radians; the right
/// eye's is its mirror image.
pub const LEFT_FOV_RAD: [f32; 4] = [-0.967, 0.845, 0.944, -0.952];
/// Default distance between the eyes, metres.
pub const IPD_M: f32 = 0.063;
/// Display refresh rate, Hz.
pub const REFRESH_HZ: i64 = 90;
