// The frame's uniform, shared by every shader of the renderer (prepended to each): both
// eyes' view-projections and positions, and flags.

struct Eye {
    view_proj: mat4x4<f32>,
    position: vec4<f32>,
};

struct Frame {
    eyes: array<Eye, 2>,
    // x: 1 when the target has been found (highlight), y: time in seconds, z: the
    // membranes' alpha.
    flags: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;
