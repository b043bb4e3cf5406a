// The membrane's active set between the CPU and the GPU: the tiles of a list packed into
// short buffers and unpacked into the grid's (`src/models/membrane/device.rs`). One workgroup
// a tile of the list and a layer, one invocation a node of its 8 rows x 16 columns, as in
// `substep_tiles` (`shaders/membrane.wgsl`), whose row-block layouts these are.
//
// Packed, record `r` (the list's `r`th tile), layer `l`, node `n = li` of the tile:
// - state going up: `((r * 4 + l) * 128 + n) * 6 + c`, c = position x, y, z, velocity x, y, z
//   (coming back, by runs of tiles: see `places`);
// - springs: `((r * 4 + l) * 128 + n) * 9 + f`, the nine fields of a node;
// - attach (layer 0 only): `(r * 128 + n) * 4 + c`, c = stiffness, target x, y, z.

struct Sync {
    rows: u32,
    cols: u32,
    tiles_c: u32,
    // Pack: read state buffer b rather than a.
    flag: u32,
    // Unpack: the list's first tiles whose state goes up (the device holds the others'),
    // and the first (as many or fewer) whose springs go up.
    state_tiles: u32,
    springs_tiles: u32,
    // Unpack: whether layer 0's attachments went up (not where the device places the
    // targets itself: `shaders/membrane_chain.wgsl`).
    attach_sent: u32,
    pad: u32,
}

const LAYERS: u32 = 4u;
const TILE_ROWS: u32 = 8u;
const TILE_COLS: u32 = 16u;
const TILE: u32 = 128u;
const FIELDS: u32 = 9u;

@group(0) @binding(0) var<uniform> s: Sync;
@group(0) @binding(1) var<storage, read_write> state_a: array<f32>;
@group(0) @binding(2) var<storage, read_write> state_b: array<f32>;
@group(0) @binding(3) var<storage, read_write> springs: array<f32>;
@group(0) @binding(4) var<storage, read_write> attach: array<f32>;
@group(0) @binding(5) var<storage, read> list: array<u32>;
@group(0) @binding(6) var<storage, read_write> packed_state: array<f32>;
@group(0) @binding(7) var<storage, read_write> packed_springs: array<f32>;
@group(0) @binding(8) var<storage, read_write> packed_attach: array<f32>;
// Pack: each listed tile's place in the run of awake tiles side by side in its row of tiles
// (`device_pack.rs`): the run's first value, its width in columns, the tile's first column in
// it. A run packs layer by layer, row by row, value by value, a stretch of its width each, so
// that the CPU copies each stretch whole into its row.
@group(0) @binding(9) var<storage, read> places: array<vec4<u32>>;

// Node `li` of layer `wg.y` of the list's tile `wg.x`: its row block, its column and its
// place in the packed buffers; the block is OUTSIDE where the node lies beyond the grid.
const OUTSIDE: u32 = 0xffffffffu;

fn node_of(wg: vec3<u32>, li: u32) -> vec3<u32> {
    let t = list[wg.x];
    let i = (t / s.tiles_c) * TILE_ROWS + li / TILE_COLS;
    let j = (t % s.tiles_c) * TILE_COLS + li % TILE_COLS;
    let n = (wg.x * LAYERS + wg.y) * TILE + li;
    return vec3<u32>(select(OUTSIDE, wg.y * s.rows + i, i < s.rows && j < s.cols), j, n);
}

// The CPU's tiles into both state buffers (a sleeping neighbour must read the same in
// either: the first `state_tiles` of the list), the springs of the first `springs_tiles`, and
// layer 0's attachments of all where they went up.
@compute @workgroup_size(128, 1, 1)
fn unpack(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = node_of(wg, li);
    let b = k.x;
    let j = k.y;
    let n = k.z;
    if (b == OUTSIDE) {
        return;
    }
    if (wg.x < s.state_tiles) {
        for (var c = 0u; c < 6u; c++) {
            let v = packed_state[n * 6u + c];
            state_a[(b * 6u + c) * s.cols + j] = v;
            state_b[(b * 6u + c) * s.cols + j] = v;
        }
    }
    if (wg.x < s.springs_tiles) {
        for (var f = 0u; f < FIELDS; f++) {
            springs[(b * FIELDS + f) * s.cols + j] = packed_springs[n * FIELDS + f];
        }
    }
    // Layer 0's block is its row.
    if (wg.y == 0u && s.attach_sent != 0u) {
        for (var c = 0u; c < 4u; c++) {
            attach[(b * 4u + c) * s.cols + j] = packed_attach[(wg.x * TILE + li) * 4u + c];
        }
    }
}

// The listed tiles' state from state buffer a (b with `flag`) into the packed buffer, each at
// its place in its run (`places`).
@compute @workgroup_size(128, 1, 1)
fn pack(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = node_of(wg, li);
    if (k.x == OUTSIDE) {
        return;
    }
    let p = places[wg.x];
    let row = wg.y * TILE_ROWS + li / TILE_COLS;
    let col = p.z + li % TILE_COLS;
    for (var c = 0u; c < 6u; c++) {
        let at = (k.x * 6u + c) * s.cols + k.y;
        packed_state[p.x + (row * 6u + c) * p.y + col] = select(state_a[at], state_b[at], s.flag != 0u);
    }
}

// A frame's drawn nodes of the tiles the CPU will lag after this step, gathered from the
// newest state buffer (a with `flag` 0, b otherwise) so that only their positions come back
// (`src/models/membrane/device_drawn.rs`): entry `k` of `gather_list` is a place in the
// drawn grid, `drawn_nodes` gives that place's row block and column, and its position goes to
// `gathered[3k..3k+3]`. `pad` holds the list's length; the dispatch may run past it.
@group(0) @binding(10) var<storage, read> drawn_nodes: array<vec2<u32>>;
@group(0) @binding(11) var<storage, read> gather_list: array<u32>;
@group(0) @binding(12) var<storage, read_write> gathered: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn gather(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
          @builtin(local_invocation_index) li: u32) {
    let k = (wg.y * groups.x + wg.x) * 64u + li;
    if (k >= s.pad) {
        return;
    }
    let node = drawn_nodes[gather_list[k]];
    for (var c = 0u; c < 3u; c++) {
        let at = (node.x * 6u + c) * s.cols + node.y;
        gathered[k * 3u + c] = select(state_a[at], state_b[at], s.flag != 0u);
    }
}
