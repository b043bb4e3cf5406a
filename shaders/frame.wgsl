// The frame's uniform, shared by every shader of the renderer (prepended to each): both
// eyes' view-projections, positions and lines of sight, flags and the optics.

struct Eye {
    view_proj: mat4x4<f32>,
    position: vec4<f32>,
    // The line of sight: the scope light's axis.
    forward: vec4<f32>,
};

struct Frame {
    eyes: array<Eye, 2>,
    // x: 1 when the target has been found (highlight), y: time in seconds, z: the
    // membranes' alpha.
    flags: vec4<f32>,
    // x: the light's working distance in metres (0: a headlight without falloff), y: the
    // image circle's radius in pixels (0: none), z, w: the image's width and height.
    optics: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;

// The share of light left at a fragment by the image circle's rim (src/render/optics.rs:
// RIM_FADE = 0.06 of the radius), 1 without a circle.
fn rim(frag: vec2<f32>) -> f32 {
    let radius = frame.optics.y;
    if (radius <= 0.0) {
        return 1.0;
    }
    let r = length(frag - 0.5 * frame.optics.zw);
    let inner = radius * (1.0 - 0.06);
    return 1.0 - smoothstep(inner, radius, r);
}

// Corner `corner` (0-5) of a quad of two triangles spanning -1 to 1: the smoke's discs and
// the headset's panel.
fn quad_corner(corner: u32) -> vec2<f32> {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0),
        vec2<f32>(1.0, -1.0),
        vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0),
        vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, 1.0),
    );
    return corners[corner % 6u];
}
