//! Where the operating field stands in the room. OpenXR reports poses in the STAGE space
//! (origin on the floor, +Y up, the trainee facing -Z); the simulation works in the field's
//! frame (metres, the kidney near its origin). The field's axes are the stage's; its origin
//! lies [`FIELD_ORIGIN_IN_STAGE_M`] from the stage origin: 16 cm in front of and 7 cm below the
//! eyes of a trainee whose eyes are 1.6 m up, so the default head sees the field as the
//! headless camera does.

use glam::Vec3;

/// The field's origin in STAGE coordinates, metres.
pub const FIELD_ORIGIN_IN_STAGE_M: [f32; 3] = [0.0, 1.53, -0.16];

/// The head when a trace has no `[[head]]` keys, in field coordinates (metres): eyes' midpoint
/// and the point looked at. The eyes are 1.6 m above the stage floor.
pub const DEFAULT_HEAD: ([f32; 3], [f32; 3]) = ([0.0, 0.07, 0.16], [0.005, 0.01, 0.0]);

/// A point in the field's frame to STAGE coordinates.
pub fn field_to_stage(p: Vec3) -> Vec3 {
    p + Vec3::from(FIELD_ORIGIN_IN_STAGE_M)
}

/// A point in STAGE coordinates to the field's frame.
pub fn stage_to_field(p: Vec3) -> Vec3 {
    p - Vec3::from(FIELD_ORIGIN_IN_STAGE_M)
}
