// Tissue and instrument shading for both eyes. The renderer compiles this file twice: with
// multiview (the eye is @builtin(view_index)) and, where the adapter lacks multiview, with the
// eye fixed per pass. The line marked VIEW_INDEX is rewritten for that. fs_main draws opaque
// surfaces; fs_membrane the same shading with the membranes' alpha, for the translucent pass.
// The frame's uniform (frame.wgsl) is prepended.

struct Material {
    albedo: vec4<f32>,
    // x: specular strength, y: shininess, z: emissive, w: rim (wet sheen at grazing angles).
    shading: vec4<f32>,
};

@group(0) @binding(1) var<uniform> materials: array<Material, 16>;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) material: u32,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) @interpolate(flat) material: u32,
    @location(3) @interpolate(flat) eye: u32,
};

@vertex
fn vs_main(v: VertexIn /*VIEW_INDEX*/) -> VertexOut {
    let eye = VIEW;
    var out: VertexOut;
    out.clip = frame.eyes[eye].view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.material = v.material;
    out.eye = eye;
    return out;
}

const CUT_FLAG: u32 = 256u;
const TARGET: u32 = 1u;

fn shade(in: VertexOut) -> vec3<f32> {
    let index = in.material & 15u;
    let m = materials[index];
    var albedo = m.albedo.rgb;
    var specular = m.shading.x;
    if ((in.material & CUT_FLAG) != 0u) {
        // Cut parenchyma: raw, darker, duller.
        albedo = vec3<f32>(0.45, 0.04, 0.05);
        specular = specular * 0.3;
    }
    let to_eye = normalize(frame.eyes[in.eye].position.xyz - in.world);
    var n = normalize(in.normal);
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    // A headlight at the eye, as from a laparoscope, plus a soft fill from above.
    let key = max(dot(n, to_eye), 0.0);
    let fill = 0.5 + 0.5 * n.y;
    let half_vec = to_eye;
    let spec = specular * pow(max(dot(n, half_vec), 0.0), m.shading.y);
    let rim = m.shading.w * pow(1.0 - key, 3.0);
    var colour = albedo * (0.18 + 0.72 * key + 0.12 * fill) + vec3<f32>(spec + rim);
    colour = colour + albedo * m.shading.z;
    if (index == TARGET && frame.flags.x > 0.5) {
        // Identified: a green glow the trainee cannot miss.
        colour = mix(colour, vec3<f32>(0.3, 0.95, 0.35), 0.35);
    }
    return colour;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in), 1.0);
}

@fragment
fn fs_membrane(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in), frame.flags.z);
}
