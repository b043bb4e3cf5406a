// Smoke: each particle a soft grey-white disc turned to face the eye, drawn after the opaque
// surfaces and the membranes with depth test on and depth write off. Compiled, like
// tissue.wgsl, with multiview (the eye is @builtin(view_index)) or with the eye fixed per
// pass: the lines marked VIEW_INDEX and VIEW are rewritten for that. The frame's uniform
// (frame.wgsl) is prepended.

// One instance per particle.
struct Particle {
    @location(0) centre: vec3<f32>,
    // x: radius in metres, y: alpha at the middle, z: grey level.
    @location(1) look: vec3<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Where in the disc, -1 to 1 across.
    @location(0) disc: vec2<f32>,
    // x: alpha at the middle, y: grey level.
    @location(1) @interpolate(flat) look: vec2<f32>,
};

@vertex
fn vs_main(p: Particle, @builtin(vertex_index) corner: u32 /*VIEW_INDEX*/) -> VertexOut {
    let eye = VIEW;
    let at = quad_corner(corner);
    // Facing this eye's position (each eye of a multiview pass sees its own disc). The disc is
    // round, so how it turns about the line of sight does not matter: any side vector will do,
    // as long as it is not along that line.
    let to_eye = normalize(frame.eyes[eye].position.xyz - p.centre);
    var up = vec3<f32>(0.0, 1.0, 0.0);
    if (abs(to_eye.y) > 0.99) {
        up = vec3<f32>(0.0, 0.0, 1.0);
    }
    let side = normalize(cross(up, to_eye));
    let top = cross(to_eye, side);
    let world = p.centre + (side * at.x + top * at.y) * p.look.x;
    var out: VertexOut;
    out.clip = frame.eyes[eye].view_proj * vec4<f32>(world, 1.0);
    out.disc = at;
    out.look = p.look.yz;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let r2 = dot(in.disc, in.disc);
    if (r2 >= 1.0) {
        discard;
    }
    // Smoke: densest in the middle, fading to nothing at the rim with no visible edge; grey-
    // white, a shade cool. Blood (a negative grey, src/render/blood.rs): dark red, wet, with
    // a crisper edge.
    var soft = (1.0 - r2) * (1.0 - r2);
    var colour = in.look.y * vec3<f32>(0.96, 0.97, 1.0);
    if (in.look.y < 0.0) {
        soft = 1.0 - r2 * r2 * r2 * r2;
        colour = -in.look.y * vec3<f32>(0.26, 0.008, 0.012) * (1.0 + 0.4 * (1.0 - r2));
    }
    // Nothing outside a monitor image's circle.
    return vec4<f32>(colour, in.look.x * soft * rim(in.clip.xy));
}
