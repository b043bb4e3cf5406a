// Layer 0's targets placed on the device from a chain's pose (`src/models/membrane/chain.rs`,
// `device_chain.rs`): each node bound to a segment of the chain, a share `t` of the way along
// it, and to a blend of two of the chain's frames with an offset in the blended frame; its
// target is `a + (b - a) t + q offset`. One workgroup a tile of the list, one invocation a
// node of its 8 rows x 16 columns (as `unpack` in `shaders/membrane_sync.wgsl`).

struct Chain {
    rows: u32,
    cols: u32,
    tiles_c: u32,
    // Where the pose's frames start (after its points).
    frames_at: u32,
}

struct Bound {
    segment: u32,
    t: f32,
    pair: u32,
    w: f32,
    offset: vec3<f32>,
    pad: f32,
}

const TILE_ROWS: u32 = 8u;
const TILE_COLS: u32 = 16u;

@group(0) @binding(0) var<uniform> s: Chain;
@group(0) @binding(1) var<storage, read_write> attach: array<f32>;
@group(0) @binding(2) var<storage, read> bound: array<Bound>;
// The pose: the points (xyz), then the frames as quaternions (xyzw).
@group(0) @binding(3) var<storage, read> pose: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> list: array<u32>;

// `v` turned by the unit quaternion `q`.
fn turn(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let t = 2.0 * cross(q.xyz, v);
    return v + q.w * t + cross(q.xyz, t);
}

@compute @workgroup_size(128, 1, 1)
fn carry(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let tile = list[wg.x];
    let i = (tile / s.tiles_c) * TILE_ROWS + li / TILE_COLS;
    let j = (tile % s.tiles_c) * TILE_COLS + li % TILE_COLS;
    if (i >= s.rows || j >= s.cols) {
        return;
    }
    let b = bound[i * s.cols + j];
    let a = pose[b.segment].xyz;
    let z = pose[b.segment + 1u].xyz;
    let c = a + (z - a) * b.t;
    let f = s.frames_at + b.pair;
    let q = normalize(pose[f] * (1.0 - b.w) + pose[f + 1u] * b.w);
    let x = c + turn(q, b.offset);
    // Layer 0's attachments, row `i`: stiffness, then the target's x, y, z, a run of `cols`
    // each.
    attach[(i * 4u + 1u) * s.cols + j] = x.x;
    attach[(i * 4u + 2u) * s.cols + j] = x.y;
    attach[(i * 4u + 3u) * s.cols + j] = x.z;
}
