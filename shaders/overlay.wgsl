// The headset's text panel (src/render/overlay.rs): one quad of the panel's texture, placed in
// the world before the eyes, drawn last with no depth test and premultiplied-alpha blending.
// Compiled like tissue.wgsl with multiview or the eye fixed per pass (the lines marked
// VIEW_INDEX and VIEW are rewritten). The frame's uniform (frame.wgsl) is prepended.

struct Placement {
    centre: vec4<f32>,
    // Half the panel's width and height along the eyes' right and up, metres.
    right: vec4<f32>,
    up: vec4<f32>,
};

@group(1) @binding(0) var<uniform> placement: Placement;
@group(1) @binding(1) var panel_texture: texture_2d<f32>;
@group(1) @binding(2) var panel_sampler: sampler;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) corner: u32 /*VIEW_INDEX*/) -> VertexOut {
    let eye = VIEW;
    let at = quad_corner(corner);
    let world = placement.centre.xyz + placement.right.xyz * at.x + placement.up.xyz * at.y;
    var out: VertexOut;
    out.clip = frame.eyes[eye].view_proj * vec4<f32>(world, 1.0);
    out.uv = vec2<f32>(0.5 + 0.5 * at.x, 0.5 - 0.5 * at.y);
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return textureSample(panel_texture, panel_sampler, in.uv);
}
