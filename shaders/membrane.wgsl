// The layered membrane's symplectic Euler substep on the GPU: one invocation per node gathers
// the forces of every spring, tether and attachment that touches it (eqs 3-4, the same terms
// as `src/models/membrane/forces.rs`) and advances its own velocity and position. Nothing is
// scattered and nothing is summed across invocations, so there are no atomics and the bytes
// depend only on the adapter and its compiler. The state is read from one buffer and written
// to the other (ping-pong): a dispatch is one substep.
//
// Layouts are the CPU model's row blocks (block `b = layer * rows + row`, then the column):
// - state: `(b * 6 + c) * cols + j`, c = position x, y, z, velocity x, y, z;
// - springs: `(b * 9 + f) * cols + j`, f = stiffness and rest length around (to column j + 1),
//   along (to row i + 1) and link (to layer l + 1), 1 / mass, shear tether stiffness and place;
// - attach: `((slot * rows + i) * 4 + c) * cols + j`, slot 0 = layer 0, 1 = layer 3,
//   c = stiffness, target x, y, z;
// - beta: per block, the damping time of each spring family (around, along, link, unused).

struct Params {
    rows: u32,
    cols: u32,
    periodic: u32,
    external_count: u32,
    gravity: vec3<f32>,
    damping_per_s: f32,
    dt: f32,
    // Workgroups along x of the flat kernel's grid.
    groups_x: u32,
    // Tiles across the grid (the active set's kernel).
    tiles_c: u32,
    _pad: u32,
}

// An external force on one node (the tools, the coupling's loads), sorted by node.
struct External {
    node: u32,
    fx: f32,
    fy: f32,
    fz: f32,
}

const LAYERS: u32 = 4u;
const K_AROUND: u32 = 0u;
const REST_AROUND: u32 = 1u;
const K_ALONG: u32 = 2u;
const REST_ALONG: u32 = 3u;
const K_LINK: u32 = 4u;
const REST_LINK: u32 = 5u;
const INV_MASS: u32 = 6u;
const SHEAR_K: u32 = 7u;
const SHEAR_W: u32 = 8u;
const FIELDS: u32 = 9u;

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read> state_in: array<f32>;
@group(0) @binding(2) var<storage, read_write> state_out: array<f32>;
@group(0) @binding(3) var<storage, read> springs: array<f32>;
@group(0) @binding(4) var<storage, read> attach: array<f32>;
@group(0) @binding(5) var<storage, read> beta: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> externals: array<External>;
// The awake tiles, each `tile row * tiles_c + tile column` (`substep_tiles` only).
@group(0) @binding(7) var<storage, read> tiles: array<u32>;

// A tile of the active set (`src/models/membrane/active.rs`): rows, then columns.
const TILE_ROWS: u32 = 8u;
const TILE_COLS: u32 = 16u;

fn pos(b: u32, j: u32) -> vec3<f32> {
    let at = b * 6u * p.cols + j;
    return vec3<f32>(state_in[at], state_in[at + p.cols], state_in[at + 2u * p.cols]);
}

fn vel(b: u32, j: u32) -> vec3<f32> {
    let at = (b * 6u + 3u) * p.cols + j;
    return vec3<f32>(state_in[at], state_in[at + p.cols], state_in[at + 2u * p.cols]);
}

fn field(b: u32, f: u32, j: u32) -> f32 {
    return springs[(b * FIELDS + f) * p.cols + j];
}

// The force of the spring from `a` to `b` on `a` (the opposite acts on `b`): `k (|d| - L0)`
// along `d` plus `beta k (dv . d) / |d|` along it.
fn spring(xa: vec3<f32>, va: vec3<f32>, xb: vec3<f32>, vb: vec3<f32>, k: f32, rest: f32, bt: f32) -> vec3<f32> {
    let d = xb - xa;
    let len = sqrt(dot(d, d));
    let inv = 1.0 / max(len, 1e-20);
    let along = dot(vb - va, d);
    let s = k * ((len - rest) + bt * along * inv) * inv;
    return d * s;
}

// The sideways pull on a tethered node at `xl` back onto the line from `x0` (its column's
// layer-0 node) to `x3` (its layer-3 node), at its place `w` along it, stiffness `k`.
fn tether_of(x0: vec3<f32>, xl: vec3<f32>, x3: vec3<f32>, k: f32, w: f32) -> vec3<f32> {
    let u = x3 - x0;
    let inv2 = 1.0 / max(dot(u, u), 1e-30);
    let d = xl - (x0 + w * u);
    let along = dot(d, u) * inv2;
    return -k * (d - along * u);
}

// The pull on the node of layer `l` (1 or 2) of column (row `i`, `j`).
fn tether(l: u32, i: u32, j: u32) -> vec3<f32> {
    let b = l * p.rows + i;
    let x0 = pos(i, j);
    let x3 = pos((LAYERS - 1u) * p.rows + i, j);
    return tether_of(x0, pos(b, j), x3, field(b, SHEAR_K, j), field(b, SHEAR_W, j));
}

// The springs within the node's layer (block `b`, row `i`, column `j`, at `x` moving at
// `v`): around to column j + 1 and from j - 1 (round the ring when periodic; a missing spring
// has stiffness 0 and adds nothing), along to row i + 1 and from i - 1.
fn in_layer(b: u32, i: u32, j: u32, x: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let cols = p.cols;
    let bt = beta[b];
    var f = vec3<f32>(0.0);
    let jr = select(j + 1u, 0u, j + 1u == cols);
    let jl = select(j - 1u, cols - 1u, j == 0u);
    if (j + 1u < cols || p.periodic != 0u) {
        f += spring(x, v, pos(b, jr), vel(b, jr), field(b, K_AROUND, j), field(b, REST_AROUND, j), bt.x);
    }
    if (j > 0u || p.periodic != 0u) {
        f -= spring(pos(b, jl), vel(b, jl), x, v, field(b, K_AROUND, jl), field(b, REST_AROUND, jl), bt.x);
    }
    if (i > 0u) {
        let bb = b - 1u;
        f -= spring(pos(bb, j), vel(bb, j), x, v, field(bb, K_ALONG, j), field(bb, REST_ALONG, j), beta[bb].y);
    }
    if (i + 1u < p.rows) {
        f += spring(x, v, pos(b + 1u, j), vel(b + 1u, j), field(b, K_ALONG, j), field(b, REST_ALONG, j), bt.y);
    }
    return f;
}

// The pull of layer `l`'s attachment (slot 0: layer 0 to its targets, slot 1: layer 3 to
// its rest) on its node at row `i`, column `j`, at `x`.
fn attachment(slot: u32, i: u32, j: u32, x: vec3<f32>) -> vec3<f32> {
    let cols = p.cols;
    let at = (slot * p.rows + i) * 4u * cols + j;
    let goal = vec3<f32>(attach[at + cols], attach[at + 2u * cols], attach[at + 3u * cols]);
    return -attach[at] * (x - goal);
}

// The external forces on `node`: the sorted list bisected, then every entry for it added.
fn external_force(node: u32) -> vec3<f32> {
    var f = vec3<f32>(0.0);
    if (p.external_count > 0u) {
        var lo = 0u;
        var hi = p.external_count;
        while (lo < hi) {
            let mid = (lo + hi) / 2u;
            if (externals[mid].node < node) {
                lo = mid + 1u;
            } else {
                hi = mid;
            }
        }
        while (lo < p.external_count && externals[lo].node == node) {
            let e = externals[lo];
            f += vec3<f32>(e.fx, e.fy, e.fz);
            lo++;
        }
    }
    return f;
}

// Symplectic Euler with the node's own terms (point damping and gravity) as accelerations:
// the node (block `b`, column `j`) at `x` moving at `v` under the force `f`, written out.
fn integrate(b: u32, j: u32, x: vec3<f32>, v: vec3<f32>, f: vec3<f32>) {
    let cols = p.cols;
    let a = f * field(b, INV_MASS, j) + (p.gravity - p.damping_per_s * v);
    let nv = v + p.dt * a;
    let nx = x + p.dt * nv;
    let at = b * 6u * cols + j;
    state_out[at] = nx.x;
    state_out[at + cols] = nx.y;
    state_out[at + 2u * cols] = nx.z;
    state_out[at + 3u * cols] = nv.x;
    state_out[at + 4u * cols] = nv.y;
    state_out[at + 5u * cols] = nv.z;
}

// One invocation per column of a row block: workgroups of 64 along a row, one row of
// workgroups a block (a row's last workgroup idles where the columns are not a multiple of 64).
@compute @workgroup_size(64, 1, 1)
fn substep_rows(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x < p.cols && gid.y < LAYERS * p.rows) {
        advance(gid.x, gid.y);
    }
}

// One invocation per node of 64 columns of one row in all four layers (local y = layer), a
// row of workgroups a row: a node's links and tethers read its column's other layers, which
// the same workgroup reads (in the state's order they lie a quarter of the grid apart, and a
// grid larger than the GPU's cache would read them from memory again).
@compute @workgroup_size(64, 4, 1)
fn substep_layers(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_id) li: vec3<u32>) {
    let j = wg.x * 64u + li.x;
    if (j < p.cols && wg.y < p.rows) {
        advance(j, li.y * p.rows + wg.y);
    }
}

// One invocation per node in the state's order, workgroups of 256 over all of them (a
// workgroup may span two rows; only the last one idles in part). The grid of workgroups is
// `groups_x` wide, so more than 65,535 of them fit.
@compute @workgroup_size(256, 1, 1)
fn substep_flat(@builtin(global_invocation_id) gid: vec3<u32>) {
    let node = gid.y * p.groups_x * 256u + gid.x;
    if (node < LAYERS * p.rows * p.cols) {
        advance(node % p.cols, node / p.cols);
    }
}

// The active set's substep: one workgroup a layer (x) and a tile of the list (y), one
// invocation a node of its 8 rows x 16 columns (an edge tile's missing nodes idle): a tile's
// four layers follow one another, as its links and tethers read them. Nodes outside the
// awake tiles are not written: they sleep, and both state buffers hold the same values for
// them.
@compute @workgroup_size(128, 1, 1)
fn substep_tiles(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let t = tiles[wg.y];
    let i = (t / p.tiles_c) * TILE_ROWS + li / TILE_COLS;
    let j = (t % p.tiles_c) * TILE_COLS + li % TILE_COLS;
    if (i < p.rows && j < p.cols) {
        advance(j, wg.x * p.rows + i);
    }
}

// Node (block `b`, column `j`): its forces gathered, its velocity and position advanced.
fn advance(j: u32, b: u32) {
    let l = b / p.rows;
    let i = b % p.rows;
    let x = pos(b, j);
    let v = vel(b, j);
    var f = gathered(b, i, j, x, v);
    if (l == 0u) {
        f += attachment(0u, i, j, x);
    }
    if (l + 1u == LAYERS) {
        f += attachment(1u, i, j, x);
    }
    f += external_force(b * p.cols + j);
    integrate(b, j, x, v, f);
}

// The forces of the node's springs, links and tethers (block `b`, row `i`, column `j`, at `x`
// moving at `v`): all but its attachment and the external forces.
fn gathered(b: u32, i: u32, j: u32, x: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let l = b / p.rows;
    var f = in_layer(b, i, j, x, v);
    // Links: from the layer below, to the layer above.
    if (l > 0u) {
        let bb = b - p.rows;
        f -= spring(pos(bb, j), vel(bb, j), x, v, field(bb, K_LINK, j), field(bb, REST_LINK, j), beta[bb].z);
    }
    if (l + 1u < LAYERS) {
        let bb = b + p.rows;
        f += spring(x, v, pos(bb, j), vel(bb, j), field(b, K_LINK, j), field(b, REST_LINK, j), beta[b].z);
    }
    // The shear tethers of layers 1 and 2; their reactions shared by the column's layer-0 and
    // layer-3 nodes in proportion to where on the line the tethered node sits.
    if (l == 1u || l == 2u) {
        f += tether(l, i, j);
    } else {
        for (var t = 1u; t < LAYERS - 1u; t++) {
            let s = tether(t, i, j);
            let w = field(t * p.rows + i, SHEAR_W, j);
            if (l == 0u) {
                f -= (1.0 - w) * s;
            } else {
                f -= w * s;
            }
        }
    }
    return f;
}

// Layer 0's loads summed by group (`src/models/membrane/anchor_sums.rs`): for each awake
// layer-0 node of a group, the force of its springs, links, tethers and external forces
// (not its attachment, not its own damping), with its weight `u`, its moment about the
// group's point taken where its attachment holds it, and its anchor stiffness. One workgroup
// a group: each invocation sums every 128th member in order, then the invocations' sums are
// added in a fixed tree, so the bytes depend only on the adapter.

// Per group, its first member, and one past the last group's last; then per tile of the
// grid, 1 where it is awake this step (written each step).
@group(0) @binding(8) var<storage, read> group_index: array<u32>;
// Per group its point (x, y, z as f32 bits), then the members, group by group: layer 0's node
// `row * cols + column`, its weight `u` and its anchor stiffness (f32 bits), its group.
@group(0) @binding(9) var<storage, read> items: array<vec4<u32>>;
// Per group: force, weighted force, moment (3 each), stiffness, weighted stiffness, unused.
@group(0) @binding(12) var<storage, read_write> sums: array<f32>;

const SUM_THREADS: u32 = 128u;
const SUM_TERMS: u32 = 12u;
var<workgroup> partial: array<array<f32, 12>, 128>;

fn finite3(v: vec3<f32>) -> bool {
    let e = bitcast<vec3<u32>>(v) & vec3<u32>(0x7f800000u);
    return all(e != vec3<u32>(0x7f800000u));
}

@compute @workgroup_size(128, 1, 1)
fn anchor_sums(
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    let g = wg.x;
    let o = bitcast<vec3<f32>>(items[g].xyz);
    // The awake tiles' flags follow the groups' starts; the members, the groups' points.
    let awake_at = groups.x + 1u;
    var acc: array<f32, 12>;
    for (var k = group_index[g] + li; k < group_index[g + 1u]; k += SUM_THREADS) {
        let item = items[groups.x + k];
        let cell = item.x;
        let u = bitcast<f32>(item.y);
        let stiffness = bitcast<f32>(item.z);
        let i = cell / p.cols;
        let j = cell % p.cols;
        if (group_index[awake_at + (i / TILE_ROWS) * p.tiles_c + j / TILE_COLS] == 0u) {
            continue;
        }
        // Layer 0's row `i` is block `i`.
        let f = gathered(i, i, j, pos(i, j), vel(i, j)) + external_force(cell);
        if (!finite3(f)) {
            continue;
        }
        let at = i * 4u * p.cols + j;
        let goal = vec3<f32>(attach[at + p.cols], attach[at + 2u * p.cols], attach[at + 3u * p.cols]);
        let r = cross(goal - o, f);
        let uf = u * f;
        acc[0] += f.x;
        acc[1] += f.y;
        acc[2] += f.z;
        acc[3] += uf.x;
        acc[4] += uf.y;
        acc[5] += uf.z;
        acc[6] += r.x;
        acc[7] += r.y;
        acc[8] += r.z;
        acc[9] += stiffness;
        acc[10] += u * stiffness;
    }
    partial[li] = acc;
    workgroupBarrier();
    for (var s = SUM_THREADS / 2u; s > 0u; s = s / 2u) {
        if (li < s) {
            for (var c = 0u; c < SUM_TERMS; c++) {
                partial[li][c] += partial[li + s][c];
            }
        }
        workgroupBarrier();
    }
    if (li == 0u) {
        for (var c = 0u; c < SUM_TERMS; c++) {
            sums[g * SUM_TERMS + c] = partial[0][c];
        }
    }
}
