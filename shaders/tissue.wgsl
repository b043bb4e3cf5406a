// Tissue and instrument shading for both eyes. The renderer compiles this file twice: with
// multiview (the eye is @builtin(view_index)) and, where the adapter lacks multiview, with the
// eye fixed per pass. The line marked VIEW_INDEX is rewritten for that. fs_main draws opaque
// surfaces; fs_membrane the same shading with the membranes' alpha, for the translucent pass.
// The frame's uniform (frame.wgsl) is prepended.
//
// Light: the scope's tip (src/render/optics.rs states the model): inverse-square falloff from
// the eye, a cos^SPOT spread about its line of sight, a little ambient light bounced around
// the cavity. Surfaces: a diffuse albedo varied by value noise of the world position (mottle,
// a fine vessel network, relief of the normal), an energy-normalised Blinn-Phong lobe with
// Schlick's Fresnel, and the sharp glint of the film of fluid that makes tissue look wet.

struct Material {
    albedo: vec4<f32>,
    // x: specular strength, y: shininess, z: emissive, w: rim (wet sheen at grazing angles).
    shading: vec4<f32>,
    // x: mottle, y: vessels, z: bump, w: noise scale (features per metre).
    surface: vec4<f32>,
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
const SEAR_FLAG: u32 = 512u;
const TARGET: u32 = 1u;
const SPOT: f32 = 1.0;
const AMBIENT: f32 = 0.04;
const DIFFUSE_GAIN: f32 = 0.85;
const MAX_GAIN: f32 = 4.0;

// A lattice point's value in [0, 1) (an integer hash: the same on every device).
fn lattice(c: vec3<i32>) -> f32 {
    var h = (bitcast<u32>(c.x) * 0x8da6b343u) ^ (bitcast<u32>(c.y) * 0xd8163841u)
        ^ (bitcast<u32>(c.z) * 0xcb1ab31fu);
    h = h ^ (h >> 15u);
    h = h * 0x2c1b3c6du;
    h = h ^ (h >> 12u);
    h = h * 0x297a2d39u;
    h = h ^ (h >> 15u);
    return f32(h >> 8u) / 16777216.0;
}

// Value noise and its gradient (x: value in [0, 1), yzw: gradient): lattice values blended
// with a smoothstep, whose derivative gives the gradient at no extra lookups.
fn value_noise(p: vec3<f32>) -> vec4<f32> {
    let f = floor(p);
    let c = vec3<i32>(f);
    let t = p - f;
    let s = t * t * (3.0 - 2.0 * t);
    let ds = 6.0 * t * (1.0 - t);
    let a = lattice(c);
    let b = lattice(c + vec3<i32>(1, 0, 0));
    let cc = lattice(c + vec3<i32>(0, 1, 0));
    let d = lattice(c + vec3<i32>(1, 1, 0));
    let e = lattice(c + vec3<i32>(0, 0, 1));
    let g = lattice(c + vec3<i32>(1, 0, 1));
    let h = lattice(c + vec3<i32>(0, 1, 1));
    let k = lattice(c + vec3<i32>(1, 1, 1));
    let k1 = b - a;
    let k2 = cc - a;
    let k3 = e - a;
    let k4 = a - b - cc + d;
    let k5 = a - cc - e + h;
    let k6 = a - b - e + g;
    let k7 = -a + b + cc - d + e - g - h + k;
    let v = a + k1 * s.x + k2 * s.y + k3 * s.z + k4 * s.x * s.y + k5 * s.y * s.z
        + k6 * s.z * s.x + k7 * s.x * s.y * s.z;
    let grad = ds * vec3<f32>(
        k1 + k4 * s.y + k6 * s.z + k7 * s.y * s.z,
        k2 + k5 * s.z + k4 * s.x + k7 * s.z * s.x,
        k3 + k6 * s.x + k5 * s.y + k7 * s.x * s.y,
    );
    return vec4<f32>(v, grad);
}

// Three octaves, each twice the frequency and half the amplitude, scaled back to [0, 1); the
// gradient with respect to p.
fn fbm(p: vec3<f32>) -> vec4<f32> {
    let o1 = value_noise(p);
    let o2 = value_noise(p * 2.03 + 17.0);
    let o3 = value_noise(p * 4.01 + 41.0);
    let v = o1.x + 0.5 * o2.x + 0.25 * o3.x;
    let g = o1.yzw + 0.5 * 2.03 * o2.yzw + 0.25 * 4.01 * o3.yzw;
    return vec4<f32>(v, g) / 1.75;
}

fn shade(in: VertexOut) -> vec3<f32> {
    let index = in.material & 15u;
    let m = materials[index];
    var albedo = m.albedo.rgb;
    var specular = m.shading.x;
    let surface = m.surface;
    let p = in.world * surface.w;
    let to_eye_full = frame.eyes[in.eye].position.xyz - in.world;
    let r = max(length(to_eye_full), 1e-6);
    let to_eye = to_eye_full / r;
    var n = normalize(in.normal);
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    if (surface.x + surface.y + surface.z > 0.0) {
        // Mottle: patches a little lighter and darker.
        let mottle = fbm(p);
        albedo = albedo * (1.0 + surface.x * (mottle.x - 0.5) * 1.6);
        // Vessels: thin lines where a coarser noise crosses its middle.
        let coarse = value_noise(p * 0.35 + 5.0).x;
        // Hue drifts between patches: some redder, some paler.
        albedo = albedo * vec3<f32>(1.0, 0.85 + 0.3 * coarse, 0.85 + 0.3 * coarse);
        let line = abs(coarse - 0.5);
        let vessel = (1.0 - smoothstep(0.0, 0.018, line)) * surface.y;
        albedo = mix(albedo, vec3<f32>(0.20, 0.01, 0.012), vessel * 0.6);
        // Relief: the mottle's slope tilts the normal (raised where lighter).
        let tangential = mottle.yzw - n * dot(mottle.yzw, n);
        n = normalize(n - tangential * surface.z * 0.12);
    }
    if ((in.material & CUT_FLAG) != 0u) {
        // Cut parenchyma: raw, darker, duller.
        albedo = vec3<f32>(0.20, 0.006, 0.008) * (0.8 + 0.4 * value_noise(p * 2.0).x);
        specular = specular * 0.3;
    }
    if ((in.material & SEAR_FLAG) != 0u) {
        // Seared by an energy instrument: carbonised tissue, near black, in brown patches
        // where it only coagulated, and dry (almost no film to shine).
        let brown = value_noise(p * 3.0).x;
        albedo = mix(vec3<f32>(0.012, 0.009, 0.007), vec3<f32>(0.09, 0.045, 0.02), brown);
        specular = specular * 0.1;
    }
    // The scope light (optics.rs: irradiance).
    let cos_i = max(dot(n, to_eye), 0.0);
    var e_light = cos_i;
    let reference = frame.optics.x;
    if (reference > 0.0) {
        let axis = frame.eyes[in.eye].forward.xyz;
        let cos_a = max(dot(axis, -to_eye), 0.0);
        e_light = min((reference / r) * (reference / r), MAX_GAIN) * cos_i * pow(cos_a, SPOT);
    }
    // Wet film: light and eye coincide, so the half vector is the view direction. Schlick's
    // Fresnel from water's 2 % at normal incidence; a normalised Blinn-Phong lobe of the
    // material's shininess and, for the film of fluid, a far sharper glint (exponent 2000:
    // a spot of about a degree and a half, where the film mirrors the scope's light).
    let shininess = m.shading.y;
    let fresnel = 0.02 + 0.98 * pow(1.0 - cos_i, 5.0);
    let lobe = (shininess + 2.0) / 6.283 * pow(cos_i, shininess);
    let glint = 2002.0 / 6.283 * pow(cos_i, 2000.0);
    let spec = specular * fresnel * (lobe + 0.5 * glint);
    let sheen = m.shading.w * pow(1.0 - cos_i, 3.0);
    var colour = albedo * (AMBIENT + DIFFUSE_GAIN * e_light) + vec3<f32>((spec + sheen) * e_light);
    colour = colour + albedo * m.shading.z;
    if (index == TARGET && frame.flags.x > 0.5) {
        // Identified: a green glow the trainee cannot miss.
        colour = mix(colour, vec3<f32>(0.35, 0.85, 0.4) * (0.3 + e_light), 0.35);
    }
    return colour * rim(in.clip.xy);
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in), 1.0);
}

@fragment
fn fs_membrane(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(shade(in), frame.flags.z);
}
