// The active set's sleep and wake checks on the GPU (`src/models/membrane/device_watch.rs`;
// the CPU's are `watch_row` in `src/models/membrane/active_rows.rs`, the same measures): after
// a step's substeps, each awake tile's fastest node relative to its anchor, how far its edge
// nodes have moved from where they were when the tile woke, and the box round its nodes. A
// node's anchor is its rest position moved by its column's layer-0 target, in proportion to
// how far it lies from layer 3: `rest + (target - rest of layer 0) (1 - weight)`.
//
// Layouts (the CPU's `Activity`): rest, offset and last `(b * 3 + c) * cols + j`, weight
// `b * cols + j`, with `b = layer * rows + row`; the state and the attachments as in
// `shaders/membrane.wgsl`. One workgroup a tile of the list, one invocation a node of its
// 8 rows x 16 columns, every layer in turn; the tile's maxima and minima in a fixed tree (the
// same in any order).

struct Watch {
    rows: u32,
    cols: u32,
    tiles_c: u32,
    // The step, s (speeds are its displacements over it).
    dt: f32,
}

const LAYERS: u32 = 4u;
const TILE_ROWS: u32 = 8u;
const TILE_COLS: u32 = 16u;
const TILE: u32 = 128u;

@group(0) @binding(0) var<uniform> w: Watch;
@group(0) @binding(1) var<storage, read> state: array<f32>;
@group(0) @binding(2) var<storage, read> attach: array<f32>;
@group(0) @binding(3) var<storage, read> rest: array<f32>;
@group(0) @binding(4) var<storage, read> weight: array<f32>;
@group(0) @binding(5) var<storage, read_write> offset: array<f32>;
@group(0) @binding(6) var<storage, read_write> last: array<f32>;
@group(0) @binding(7) var<storage, read> list: array<u32>;
// Per tile of the list: fastest (m/s), edge (m), box low x, y, z, box high x, y, z, and 1
// where a position is not finite (0 where all are: the quarantine's check).
@group(0) @binding(8) var<storage, read_write> measures: array<f32>;
// Both state buffers, to place sleeping tiles in (`place`).
@group(0) @binding(9) var<storage, read_write> place_a: array<f32>;
@group(0) @binding(10) var<storage, read_write> place_b: array<f32>;

var<workgroup> fastest: array<f32, 128>;
var<workgroup> edge: array<f32, 128>;
var<workgroup> lo: array<vec3<f32>, 128>;
var<workgroup> hi: array<vec3<f32>, 128>;
var<workgroup> bad: array<u32, 128>;

// Whether `v` holds an infinity or a NaN: an exponent of all ones (read from the bits: a
// shader may take every float for finite).
fn not_finite(v: vec3<f32>) -> bool {
    let e = bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u);
    return any(e == vec3<u32>(0x7f800000u));
}

// Component `c` of row block `b`, column `j`, in a three-component array.
fn at3(b: u32, c: u32, j: u32) -> u32 {
    return (b * 3u + c) * w.cols + j;
}

// Component `c` of the anchor of the node of row block `b` (row `i`), column `j`, whose share
// of its column's layer-0 displacement is `keep`.
fn anchor(b: u32, i: u32, j: u32, c: u32, keep: f32) -> f32 {
    let target_c = attach[(i * 4u + 1u + c) * w.cols + j];
    return rest[at3(b, c, j)] + (target_c - rest[at3(i, c, j)]) * keep;
}

// Node `li` of the list's `r`th tile: its row and column (beyond the grid for an edge tile's
// missing nodes).
fn node_at(r: u32, li: u32) -> vec2<u32> {
    let t = list[r];
    return vec2<u32>((t / w.tiles_c) * TILE_ROWS + li / TILE_COLS, (t % w.tiles_c) * TILE_COLS + li % TILE_COLS);
}

@compute @workgroup_size(128, 1, 1)
fn watch(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let t = list[wg.x];
    let r0 = (t / w.tiles_c) * TILE_ROWS;
    let c0 = (t % w.tiles_c) * TILE_COLS;
    let r1 = min(r0 + TILE_ROWS, w.rows);
    let c1 = min(c0 + TILE_COLS, w.cols);
    let i = r0 + li / TILE_COLS;
    let j = c0 + li % TILE_COLS;
    var fast = 0.0;
    var moved = 0.0;
    var low = vec3<f32>(3.4028235e38);
    var high = vec3<f32>(-3.4028235e38);
    var wrong = 0u;
    if (i < r1 && j < c1) {
        // The edge: every node of the tile's first and last rows, the first and last of the
        // others.
        let on_edge = i == r0 || i + 1u == r1 || j == c0 || j + 1u == c1;
        for (var l = 0u; l < LAYERS; l++) {
            let b = l * w.rows + i;
            let x = vec3<f32>(
                state[(b * 6u) * w.cols + j],
                state[(b * 6u + 1u) * w.cols + j],
                state[(b * 6u + 2u) * w.cols + j],
            );
            let keep = 1.0 - weight[b * w.cols + j];
            var now = vec3<f32>(0.0);
            var was = vec3<f32>(0.0);
            var off = vec3<f32>(0.0);
            for (var c = 0u; c < 3u; c++) {
                now[c] = x[c] - anchor(b, i, j, c, keep);
                was[c] = last[at3(b, c, j)];
                off[c] = offset[at3(b, c, j)];
                last[at3(b, c, j)] = now[c];
            }
            fast = max(fast, length(now - was) / w.dt);
            if (on_edge) {
                moved = max(moved, length(now - off));
            }
            low = min(low, x);
            high = max(high, x);
            wrong = max(wrong, select(0u, 1u, not_finite(x)));
        }
    }
    fastest[li] = fast;
    edge[li] = moved;
    lo[li] = low;
    hi[li] = high;
    bad[li] = wrong;
    workgroupBarrier();
    for (var s = TILE / 2u; s > 0u; s = s / 2u) {
        if (li < s) {
            fastest[li] = max(fastest[li], fastest[li + s]);
            edge[li] = max(edge[li], edge[li + s]);
            lo[li] = min(lo[li], lo[li + s]);
            hi[li] = max(hi[li], hi[li + s]);
            bad[li] = max(bad[li], bad[li + s]);
        }
        workgroupBarrier();
    }
    if (li == 0u) {
        let o = wg.x * 9u;
        measures[o] = fastest[0];
        measures[o + 1u] = edge[0];
        measures[o + 2u] = lo[0].x;
        measures[o + 3u] = lo[0].y;
        measures[o + 4u] = lo[0].z;
        measures[o + 5u] = hi[0].x;
        measures[o + 6u] = hi[0].y;
        measures[o + 7u] = hi[0].z;
        measures[o + 8u] = f32(bad[0]);
    }
}

// Tiles of the list whose offsets the device lacks (they woke or fell asleep since it last
// held them): their offsets and their last offsets from the CPU, packed
// `((r * 4 + l) * 128 + n) * 6 + c`, c = offset x, y, z, last x, y, z (the `measures` binding
// holds them here).
@compute @workgroup_size(128, 1, 1)
fn start(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let n = node_at(wg.x, li);
    let i = n.x;
    let j = n.y;
    if (i >= w.rows || j >= w.cols) {
        return;
    }
    for (var l = 0u; l < LAYERS; l++) {
        let b = l * w.rows + i;
        let k = ((wg.x * LAYERS + l) * TILE + li) * 6u;
        for (var c = 0u; c < 3u; c++) {
            offset[at3(b, c, j)] = measures[k + c];
            last[at3(b, c, j)] = measures[k + 3u + c];
        }
    }
}

// The halo (the sleeping tiles of the list, beside awake ones): each node placed at its anchor
// plus its offset, at rest, in both state buffers (a neighbour reads the same in either): the
// CPU's `place_asleep`, on this step's targets (placed by `carry` in
// `shaders/membrane_chain.wgsl`, or gone up from the CPU).
@compute @workgroup_size(128, 1, 1)
fn place(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let n = node_at(wg.x, li);
    let i = n.x;
    let j = n.y;
    if (i >= w.rows || j >= w.cols) {
        return;
    }
    for (var l = 0u; l < LAYERS; l++) {
        let b = l * w.rows + i;
        let keep = 1.0 - weight[b * w.cols + j];
        for (var c = 0u; c < 3u; c++) {
            let x = anchor(b, i, j, c, keep) + offset[at3(b, c, j)];
            let at = (b * 6u + c) * w.cols + j;
            place_a[at] = x;
            place_b[at] = x;
            place_a[at + 3u * w.cols] = 0.0;
            place_b[at + 3u * w.cols] = 0.0;
        }
    }
}
