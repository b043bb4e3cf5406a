// The particle solver's substep on the GPU for a world of shape-matching clusters (the
// cholecystectomy paper's eqs 1-4): the same algorithm, in the same order, as
// `src/models/particles/mod.rs` (predict, finish) and `shape.rs` (the clusters' goals, then
// every particle through its clusters' springs; the ties and the cloth as `xpbd.rs`). One
// invocation per particle, cluster or constraint; each writes only its own entries (a colour's
// constraints share no particle), nothing is summed across invocations, and the bytes depend
// only on the adapter and its compiler.
//
// One substep: `predict` and `clear_lambdas`; per sweep `match_goals` (a cluster each),
// `shape_particles` (a particle each), the ties, the cloth's edges and its hinges colour by
// colour (`project_stretches`, `project_bends`: a constraint each, constraints of one colour
// sharing no particle), the strands, the contacts between bodies, and `floor`; then `finish`.
// Where the sets and the contacts are scheduled, each is one dispatch of one workgroup
// (`project_scheduled`) running the same projections level by level.
//
// Layouts:
// - x, x0: `vec4(position, inverse mass)`; v, ext: `vec4(velocity or force, 0)`;
// - cluster_info: `(first member, end, bits of sum of m a, 0)`; cluster_state, two a cluster:
//   `(centre, warm)`, `(quaternion x, y, z, w)`;
// - member_index; member_mw: `(m a q, m a)` (the member's mass share times its rest offset,
//   and the share);
// - frames, four a cluster: the rotation's columns, then the centre;
// - offsets: each particle's entries `offsets[i]..offsets[i + 1]`, in cluster order;
//   entries: `(rest offset, bits of the cluster)`; coef: `(beta, 1 / (1 + beta))`; mu: the
//   entry's XPBD multiplier times the particle's inverse mass.

struct Params {
    particles: u32,
    clusters: u32,
    // The substep, 1 / substep, and the point damping's factor `exp(-D dt)` over it.
    dt: f32,
    inv_dt: f32,
    gravity: vec3<f32>,
    keep: f32,
    floor_y: f32,
    // Whether the floor holds the particles (the solver's), and the rotation's iterations.
    floor_on: u32,
    cold_iterations: u32,
    warm_iterations: u32,
    // Multipliers of the stretch and bending constraints (ties, then cloth edges, then hinges).
    lambdas: u32,
}

// One colour of one constraint set: its constraints `first..end` of their buffer, the first's
// multiplier, and the set's compliance.
struct Range {
    first: u32,
    end: u32,
    lambda_base: u32,
    compliance: f32,
}

@group(0) @binding(0) var<uniform> p: Params;
@group(0) @binding(1) var<storage, read_write> x: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> x0: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> v: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> ext: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> offsets: array<u32>;
@group(0) @binding(6) var<storage, read_write> mu: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> cluster_info: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read_write> cluster_state: array<vec4<f32>>;
@group(0) @binding(9) var<storage, read> member_index: array<u32>;
@group(0) @binding(10) var<storage, read> member_mw: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> frames: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read> entries: array<vec4<f32>>;
@group(0) @binding(13) var<storage, read> coef: array<vec2<f32>>;
@group(0) @binding(14) var<uniform> range: Range;
// Stretch constraints: `(a, b, bits of the rest length, 0)`; bending constraints, two each:
// `(a, b, c, d)`, `(bits of the rest angle, 0, 0, 0)`.
@group(0) @binding(15) var<storage, read> stretches: array<vec4<u32>>;
@group(0) @binding(16) var<storage, read> bends: array<vec4<u32>>;
@group(0) @binding(17) var<storage, read_write> lambda: array<f32>;
// Chains solved a run of intact segments at a time (`chain.rs`, `adhesion.rs`), three rows a
// chain: `(first segment, end, first bending spring, end)`, `(bits of the compliance, of the
// weakened breakable segments' compliance, weakened, solves a sweep)`, `(bits of the bending
// springs' compliance, the first segment's multiplier, the first bending spring's, 0)`.
@group(0) @binding(18) var<storage, read> chains: array<vec4<u32>>;
// Segments: `(a, b, bits of the rest length, intact | breakable << 1)`; bending springs:
// `(a, b, bits of the rest length, intact)`.
@group(0) @binding(19) var<storage, read> chain_segs: array<vec4<u32>>;
@group(0) @binding(20) var<storage, read> chain_bends: array<vec4<u32>>;
// Each segment's row of its run's tridiagonal system, two a segment: `(normal, diagonal)`,
// `(coupling with the next, right-hand side, c, d)` (work space).
@group(0) @binding(21) var<storage, read_write> rows: array<vec4<f32>>;
// Candidate pairs of particles of different bodies (`contacts.rs`), by colour.
@group(0) @binding(22) var<storage, read> pairs: array<vec2<u32>>;

// A turn smaller than this ends the rotation's extraction, radians (`shape.rs`).
const ROTATION_TOLERANCE_RAD: f32 = 1e-5;

// Invocations are laid out as `gid.y * 65535 * 64 + gid.x` (the dispatch's x is at most 65,535
// workgroups).
fn index(gid: vec3<u32>) -> u32 {
    return gid.y * 65535u * 64u + gid.x;
}

// Step 1: remember the positions, move every free particle by its velocity after gravity and
// the external forces (the submission's, through each of its substeps), and start the step's
// multipliers at zero.
@compute @workgroup_size(64)
fn predict(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= p.particles {
        return;
    }
    let xi = x[i];
    x0[i] = xi;
    if xi.w > 0.0 {
        let vi = v[i].xyz + p.dt * (p.gravity + ext[i].xyz * xi.w);
        v[i] = vec4<f32>(vi, 0.0);
        x[i] = vec4<f32>(xi.xyz + p.dt * vi, xi.w);
    }
    for (var e = offsets[i]; e < offsets[i + 1u]; e++) {
        mu[e] = vec4<f32>(0.0);
    }
}

fn quat_mul(a: vec4<f32>, b: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(
        a.w * b.xyz + b.w * a.xyz + cross(a.xyz, b.xyz),
        a.w * b.w - dot(a.xyz, b.xyz),
    );
}

fn quat_normalize(q: vec4<f32>) -> vec4<f32> {
    return q * (1.0 / length(q));
}

// The rotation matrix of a unit quaternion, as its columns.
fn quat_cols(q: vec4<f32>) -> array<vec3<f32>, 3> {
    let x2 = q.x + q.x;
    let y2 = q.y + q.y;
    let z2 = q.z + q.z;
    let xx = q.x * x2;
    let xy = q.x * y2;
    let xz = q.x * z2;
    let yy = q.y * y2;
    let yz = q.y * z2;
    let zz = q.z * z2;
    let wx = q.w * x2;
    let wy = q.w * y2;
    let wz = q.w * z2;
    return array<vec3<f32>, 3>(
        vec3<f32>(1.0 - (yy + zz), xy + wz, xz - wy),
        vec3<f32>(xy - wz, 1.0 - (xx + zz), yz + wx),
        vec3<f32>(xz + wy, yz - wx, 1.0 - (xx + yy)),
    );
}

fn finite3(a: vec3<f32>) -> bool {
    // A NaN fails every comparison; an infinity exceeds the largest f32.
    return all(abs(a) <= vec3<f32>(3.4028235e38));
}

// Steps 1-3 for one cluster (`Cluster::match_goals`): about the last centre, the centre of
// mass and `A = sum m a (x - c) q^T` in one pass over the members in order; the rotation of
// `A`'s polar decomposition from the last one (Müller et al. 2016); the frame of the goals.
@compute @workgroup_size(64)
fn match_goals(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = index(gid);
    if k >= p.clusters {
        return;
    }
    let info = cluster_info[k];
    let mw_sum = bitcast<f32>(info.z);
    let st = cluster_state[2u * k];
    var o = st.xyz;
    let warm = st.w > 0.0;
    if !warm {
        // The body may be anywhere now: the sums about where it is.
        var c = vec3<f32>(0.0);
        for (var m = info.x; m < info.y; m++) {
            c += x[member_index[m]].xyz * member_mw[m].w;
        }
        o = c / mw_sum;
    }
    var sum = vec3<f32>(0.0);
    var ax = vec3<f32>(0.0);
    var ay = vec3<f32>(0.0);
    var az = vec3<f32>(0.0);
    for (var m = info.x; m < info.y; m++) {
        let d = x[member_index[m]].xyz - o;
        let mq = member_mw[m];
        sum += d * mq.w;
        ax += d * mq.x;
        ay += d * mq.y;
        az += d * mq.z;
    }
    let centre = o + sum / mw_sum;
    var q = cluster_state[2u * k + 1u];
    if !(finite3(q.xyz) && abs(q.w) <= 3.4028235e38) {
        q = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    if finite3(ax) && finite3(ay) && finite3(az) {
        var most = p.warm_iterations;
        if !warm {
            most = p.cold_iterations;
        }
        let a = array<vec3<f32>, 3>(ax, ay, az);
        for (var it = 0u; it < most; it++) {
            let r = quat_cols(q);
            var num = vec3<f32>(0.0);
            var den = 0.0;
            for (var c = 0u; c < 3u; c++) {
                num += cross(r[c], a[c]);
                den += dot(r[c], a[c]);
            }
            let omega = num / (abs(den) + 1e-9 * (1.0 + length(num)));
            let angle = length(omega);
            if !(angle > ROTATION_TOLERANCE_RAD) {
                break;
            }
            let turn = quat_normalize(vec4<f32>(0.5 * omega, 1.0));
            q = quat_normalize(quat_mul(turn, q));
        }
    }
    cluster_state[2u * k] = vec4<f32>(centre, 1.0);
    cluster_state[2u * k + 1u] = q;
    let r = quat_cols(q);
    frames[4u * k] = vec4<f32>(r[0], 0.0);
    frames[4u * k + 1u] = vec4<f32>(r[1], 0.0);
    frames[4u * k + 2u] = vec4<f32>(r[2], 0.0);
    frames[4u * k + 3u] = vec4<f32>(centre, 0.0);
}

// Step 4 for one particle: its clusters' zero-length springs one after another in cluster
// order, each as an XPBD constraint `C = x - g` (`d_mu = (g - x - beta mu) / (1 + beta)`),
// then the floor.
@compute @workgroup_size(64)
fn shape_particles(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= p.particles {
        return;
    }
    let xi = x[i];
    if xi.w <= 0.0 {
        return;
    }
    var xa = xi.xyz;
    for (var e = offsets[i]; e < offsets[i + 1u]; e++) {
        let cf = coef[e];
        if cf.y <= 0.0 {
            continue;
        }
        let en = entries[e];
        let k = bitcast<u32>(en.w);
        let g = frames[4u * k].xyz * en.x + frames[4u * k + 1u].xyz * en.y
            + frames[4u * k + 2u].xyz * en.z + frames[4u * k + 3u].xyz;
        let m = mu[e].xyz;
        let d = (g - xa - cf.x * m) * cf.y;
        mu[e] = vec4<f32>(m + d, 0.0);
        xa += d;
    }
    x[i] = vec4<f32>(xa, xi.w);
}

// A step's multipliers back to zero (`begin_step`).
@compute @workgroup_size(64)
fn clear_lambdas(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i < p.lambdas {
        lambda[i] = 0.0;
    }
}

// One colour of stretch constraints, each as `xpbd::project_stretch` (no two share a
// particle, so they run side by side as they would one after another).
@compute @workgroup_size(64)
fn project_stretches(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = range.first + index(gid);
    if k >= range.end {
        return;
    }
    let c = stretches[k];
    stretch_one(c.x, c.y, bitcast<f32>(c.z), range.compliance, range.lambda_base + (k - range.first));
}

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;
// The most a bending projection turns a hinge, radians (`xpbd::MAX_BEND_CORRECTION_RAD`).
const MAX_BEND_CORRECTION_RAD: f32 = 0.02;

// One colour of bending constraints, each as `xpbd::project_bend`: the signed dihedral from
// rest and Bridson et al.'s gradients.
@compute @workgroup_size(64)
fn project_bends(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = range.first + index(gid);
    if k >= range.end {
        return;
    }
    let rest = bitcast<f32>(bends[2u * k + 1u].x);
    bend_one(bends[2u * k], rest, range.compliance, range.lambda_base + (k - range.first));
}

// The bending constraint over particles `ids` of rest angle `rest` and compliance
// `compliance`, its multiplier at `li`.
fn bend_one(ids: vec4<u32>, rest: f32, compliance: f32, li: u32) {
    let a = x[ids.x];
    let b = x[ids.y];
    let pc = x[ids.z];
    let pd = x[ids.w];
    let e = b.xyz - a.xyz;
    let n1 = cross(e, pc.xyz - a.xyz);
    let n2 = cross(pd.xyz - a.xyz, e);
    let e2 = dot(e, e);
    let tiny = 1e-14 * max(e2, 1.17549435e-38);
    if e2 <= 1e-20 || dot(n1, n1) <= tiny || dot(n2, n2) <= tiny {
        return;
    }
    var constraint = atan2(dot(cross(n1, n2), e), dot(n1, n2) * length(e)) - rest;
    if constraint > PI {
        constraint -= TAU;
    } else if constraint < -PI {
        constraint += TAU;
    }
    let len = length(e);
    let eh = e / len;
    let m1 = n1 / dot(n1, n1);
    let m2 = n2 / dot(n2, n2);
    let g0 = -(dot(pc.xyz - b.xyz, eh) * m1 + dot(pd.xyz - b.xyz, eh) * m2);
    let g1 = dot(pc.xyz - a.xyz, eh) * m1 + dot(pd.xyz - a.xyz, eh) * m2;
    let g2 = -len * m1;
    let g3 = -len * m2;
    constraint = clamp(constraint, -MAX_BEND_CORRECTION_RAD, MAX_BEND_CORRECTION_RAD);
    let denom = a.w * dot(g0, g0) + b.w * dot(g1, g1) + pc.w * dot(g2, g2) + pd.w * dot(g3, g3);
    let alpha = compliance / (p.dt * p.dt);
    if denom + alpha <= 1e-12 {
        return;
    }
    let dl = (-constraint - alpha * lambda[li]) / (denom + alpha);
    x[ids.x] = vec4<f32>(a.xyz + g0 * (a.w * dl), a.w);
    x[ids.y] = vec4<f32>(b.xyz + g1 * (b.w * dl), b.w);
    x[ids.z] = vec4<f32>(pc.xyz + g2 * (pc.w * dl), pc.w);
    x[ids.w] = vec4<f32>(pd.xyz + g3 * (pd.w * dl), pd.w);
    lambda[li] += dl;
}

// The floor under every free particle, after a sweep's constraints.
@compute @workgroup_size(64)
fn floor(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= p.particles {
        return;
    }
    let xi = x[i];
    if p.floor_on != 0u && xi.w > 0.0 && xi.y < p.floor_y {
        x[i] = vec4<f32>(xi.x, p.floor_y, xi.z, xi.w);
    }
}

// Step 3: the velocities from what the positions did, less the point damping.
@compute @workgroup_size(64)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= p.particles {
        return;
    }
    v[i] = vec4<f32>((x[i].xyz - x0[i].xyz) * p.inv_dt * p.keep, 0.0);
}

// One stretch constraint `a - b` of rest length `rest` as `xpbd::project_stretch`, its
// multiplier at `li`.
fn stretch_one(a: u32, b: u32, rest: f32, compliance: f32, li: u32) {
    let xa = x[a];
    let xb = x[b];
    let wsum = xa.w + xb.w;
    if wsum == 0.0 {
        return;
    }
    let d = xa.xyz - xb.xyz;
    let len = length(d);
    if len <= 1.1920929e-7 {
        return;
    }
    let n = d / len;
    let alpha = compliance / (p.dt * p.dt);
    let dl = (-(len - rest) - alpha * lambda[li]) / (wsum + alpha);
    x[a] = vec4<f32>(xa.xyz + n * (xa.w * dl), xa.w);
    x[b] = vec4<f32>(xb.xyz - n * (xb.w * dl), xb.w);
    lambda[li] += dl;
}

// Segments `lo..hi` of a chain, consecutive and intact, solved together as
// `chain::solve_chain`: the run's XPBD step is tridiagonal, solved exactly by the Thomas
// algorithm (forward elimination, then back substitution applying each change).
fn solve_run(lo: u32, hi: u32, compliance: f32, weak: f32, weakened: bool, lambda_at: u32) {
    let inv_dt2 = 1.0 / (p.dt * p.dt);
    for (var j = lo; j < hi; j++) {
        let g = chain_segs[j];
        let comp = seg_compliance(g.w, compliance, weak, weakened);
        if hi - lo == 1u {
            stretch_one(g.x, g.y, bitcast<f32>(g.z), comp, lambda_at + j);
            return;
        }
        let xa = x[g.x];
        let xb = x[g.y];
        let d = xa.xyz - xb.xyz;
        let len = length(d);
        let alpha = comp * inv_dt2;
        var normal = vec3<f32>(0.0);
        var rhs = 0.0;
        if len > 1.1920929e-7 {
            normal = d / len;
            rhs = -(len - bitcast<f32>(g.z)) - alpha * lambda[lambda_at + j];
        }
        rows[2u * j] = vec4<f32>(normal, (xa.w + xb.w) * dot(normal, normal) + alpha);
        rows[2u * j + 1u] = vec4<f32>(0.0, rhs, 0.0, 0.0);
    }
    for (var j = lo; j < hi; j++) {
        var off = 0.0;
        if j + 1u < hi {
            off = -x[chain_segs[j].y].w * dot(rows[2u * j].xyz, rows[2u * j + 2u].xyz);
        }
        rows[2u * j + 1u].x = off;
    }
    var c_prev = 0.0;
    var d_prev = 0.0;
    var off_prev = 0.0;
    for (var j = lo; j < hi; j++) {
        let pivot = rows[2u * j].w - off_prev * c_prev;
        if !(pivot > 0.0) {
            return;
        }
        let r = rows[2u * j + 1u];
        let c = r.x / pivot;
        let dd = (r.y - off_prev * d_prev) / pivot;
        rows[2u * j + 1u] = vec4<f32>(r.x, r.y, c, dd);
        c_prev = c;
        d_prev = dd;
        off_prev = r.x;
    }
    var next = 0.0;
    for (var j = hi; j > lo; j--) {
        let k = j - 1u;
        let r = rows[2u * k + 1u];
        let dl = r.w - r.z * next;
        next = dl;
        lambda[lambda_at + k] += dl;
        let g = chain_segs[k];
        let normal = rows[2u * k].xyz;
        let xa = x[g.x];
        x[g.x] = vec4<f32>(xa.xyz + normal * (xa.w * dl), xa.w);
        let xb = x[g.y];
        x[g.y] = vec4<f32>(xb.xyz - normal * (xb.w * dl), xb.w);
    }
}

// A segment's compliance: a breakable one's is `weak` once its strand is weakened.
fn seg_compliance(flags: u32, compliance: f32, weak: f32, weakened: bool) -> f32 {
    if weakened && (flags & 2u) != 0u {
        return weak;
    }
    return compliance;
}

// A whole strand, segments `lo..hi`, at its equilibrium (`adhesion.rs`, `Whole`): one
// tension-only constraint between its ends of its segments' compliance in series, then its
// interior particles on the line between the ends, each segment stretched by the shared
// tension (evenly spaced when slack); every segment's multiplier is the strand's.
fn whole_strand(lo: u32, hi: u32, compliance: f32, weak: f32, weakened: bool, lambda_at: u32) {
    var total = 0.0;
    var rest = 0.0;
    for (var j = lo; j < hi; j++) {
        total += seg_compliance(chain_segs[j].w, compliance, weak, weakened);
    }
    for (var j = lo; j < hi; j++) {
        rest += bitcast<f32>(chain_segs[j].z);
    }
    let a = chain_segs[lo].x;
    let b = chain_segs[hi - 1u].y;
    let xa = x[a];
    let xb = x[b];
    let wsum = xa.w + xb.w;
    let d = xa.xyz - xb.xyz;
    let len = length(d);
    if wsum > 0.0 && len > 1.1920929e-7 {
        let n = d / len;
        let alpha = total / (p.dt * p.dt);
        let held = lambda[lambda_at + lo];
        let dl = min((-(len - rest) - alpha * held) / (wsum + alpha) + held, 0.0) - held;
        x[a] = vec4<f32>(xa.xyz + n * (xa.w * dl), xa.w);
        x[b] = vec4<f32>(xb.xyz - n * (xb.w * dl), xb.w);
        for (var j = lo; j < hi; j++) {
            lambda[lambda_at + j] = held + dl;
        }
    }
    let pa = x[a].xyz;
    let pb = x[b].xyz;
    let span = distance(pa, pb);
    let excess = span - rest;
    let count = f32(hi - lo);
    var along = 0.0;
    for (var j = lo; j + 1u < hi; j++) {
        let g = chain_segs[j];
        if excess > 0.0 {
            along += bitcast<f32>(g.z) + excess * seg_compliance(g.w, compliance, weak, weakened) / total;
        } else {
            along += span / count;
        }
        var t = 0.0;
        if span > 1.1920929e-7 {
            t = along / span;
        }
        x[g.y] = vec4<f32>(pa + (pb - pa) * t, x[g.y].w);
    }
}

// One colour of chains (`Chains::project`, `Adhesion::project`): each chain's runs of intact
// segments solved together (`solves` times), then its bending springs one by one.
@compute @workgroup_size(64)
fn project_chains(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = range.first + index(gid);
    if k >= range.end {
        return;
    }
    chain_one(k);
}

// Chain `k`: its runs of intact segments, then its bending springs.
fn chain_one(k: u32) {
    let span = chains[3u * k];
    let how = chains[3u * k + 1u];
    let more = chains[3u * k + 2u];
    let compliance = bitcast<f32>(how.x);
    let weak = bitcast<f32>(how.y);
    let weakened = (how.z & 1u) != 0u;
    // The segments' multipliers: segment j's at `lambda_at + j`.
    let lambda_at = more.y - span.x;
    if (how.z & 2u) != 0u {
        whole_strand(span.x, span.y, compliance, weak, weakened, lambda_at);
        return;
    }
    var lo = span.x;
    while lo < span.y {
        if (chain_segs[lo].w & 1u) == 0u {
            lo += 1u;
            continue;
        }
        var hi = lo + 1u;
        while hi < span.y && (chain_segs[hi].w & 1u) != 0u {
            hi += 1u;
        }
        for (var s = 0u; s < how.w; s++) {
            solve_run(lo, hi, compliance, weak, weakened, lambda_at);
        }
        lo = hi;
    }
    let bend_compliance = bitcast<f32>(more.x);
    for (var b = span.z; b < span.w; b++) {
        let c = chain_bends[b];
        if c.w != 0u {
            stretch_one(c.x, c.y, bitcast<f32>(c.z), bend_compliance, more.z + (b - span.z));
        }
    }
}

// One colour of contact pairs (`BodyContacts::project`): a pair closer than two radii
// (`range.compliance` here) is pushed apart, each particle by its inverse mass.
@compute @workgroup_size(64)
fn project_contacts(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = range.first + index(gid);
    if k >= range.end {
        return;
    }
    contact_one(pairs[k], range.compliance);
}

// The pair of particles `pr`, pushed apart closer than `d0`.
fn contact_one(pr: vec2<u32>, d0: f32) {
    let xi = x[pr.x];
    let xj = x[pr.y];
    let ws = xi.w + xj.w;
    if ws <= 0.0 {
        return;
    }
    let d = xi.xyz - xj.xyz;
    let len = length(d);
    if len >= d0 || len <= 1e-12 {
        return;
    }
    let push = d * ((d0 - len) / (len * ws));
    x[pr.x] = vec4<f32>(xi.xyz + push * xi.w, xi.w);
    x[pr.y] = vec4<f32>(xj.xyz - push * xj.w, xj.w);
}

// A sweep's constraints in levels, run by one workgroup (`gpu_schedule.rs`): level by level,
// each invocation taking every `SCHEDULE_GROUP`th item of the level, a storage barrier between
// levels. A level's items share no particle, and items that share one keep their order from
// the colour-by-colour sweep, so the bytes are that sweep's.
//
// schedule: `(levels, the first item's row, 0, 0)`; the level starts four a row (level `l`'s
// items are `start(l)..start(l + 1)`); then two rows an item: `(kind, bits of the compliance or
// the contact's distance, multiplier, bits of the rest length or angle, or the chain)`, then
// the particles it moves.
@group(0) @binding(29) var<storage, read> schedule: array<vec4<u32>>;

const SCHEDULE_GROUP: u32 = 256u;
const KIND_STRETCH: u32 = 0u;
const KIND_BEND: u32 = 1u;
const KIND_CHAIN: u32 = 2u;

fn level_start(l: u32) -> u32 {
    return schedule[1u + l / 4u][l % 4u];
}

// A sweep's scheduled constraints: its sets (the vessels, ties, cloth and strands) or its
// contact pairs.
@compute @workgroup_size(256)
fn project_scheduled(@builtin(local_invocation_index) t: u32) {
    let head = schedule[0];
    for (var l = 0u; l < head.x; l++) {
        let end = level_start(l + 1u);
        for (var k = level_start(l) + t; k < end; k += SCHEDULE_GROUP) {
            let it = schedule[head.y + 2u * k];
            let ids = schedule[head.y + 2u * k + 1u];
            let compliance = bitcast<f32>(it.y);
            switch it.x {
                case KIND_STRETCH: {
                    stretch_one(ids.x, ids.y, bitcast<f32>(it.w), compliance, it.z);
                }
                case KIND_BEND: {
                    bend_one(ids, bitcast<f32>(it.w), compliance, it.z);
                }
                case KIND_CHAIN: {
                    chain_one(it.w);
                }
                default: {
                    contact_one(ids.xy, compliance);
                }
            }
        }
        storageBarrier();
    }
}

// The instruments (`contacts.rs`: `ToolPush`, `Grasp`), projected after the strands and before
// the contacts between bodies, hand by hand, each hand either pushing (its instrument's
// generalized cylinders against every particle listed near it at the substep's first sweep) or
// grasping (each held particle pulled by its spring towards its place in the jaw).
//
// - cylinders, seven rows a cylinder (`ToolCylinder::rows`): `(p0, 1 / |a|^2)`,
//   `(p1, on-axis distance)`, `(a, bits of the radius samples)`, `(unit axis, 0)`,
//   `(on-axis direction, 0)`, the samples' `t`, their radii;
// - tool_acc: a pushing hand's, per particle, what it was pushed by this substep over its
//   inverse mass, and 1 if it was pushed in the latest sweep; a grasping hand's, per held
//   particle, its spring's multiplier;
// - near: a pushing hand's list, per particle (1: near);
// - held: `(offset from the jaw, bits of the particle)`;
// - tool_totals, one a hand: the sums over the submission's substeps, and the most particles
//   pushed in a substep's last sweep.
struct Cylinder {
    p0: vec4<f32>,
    p1: vec4<f32>,
    axis: vec4<f32>,
    unit_axis: vec4<f32>,
    on_axis_dir: vec4<f32>,
    t: vec4<f32>,
    r: vec4<f32>,
}

// One hand's instrument in a sweep: the jaw and the grasp springs' `1 / (k dt^2)`, the hand,
// its cylinders, the items its sums run over (particles or held particles), whether this is a
// substep's first sweep, and how far the instrument is grown (by the particles' radius; for
// the list, by the list's margin too).
struct Tool {
    jaw: vec3<f32>,
    alpha: f32,
    hand: u32,
    cylinders: u32,
    items: u32,
    first: u32,
    grow: f32,
    grow_wide: f32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(23) var<storage, read> cylinders: array<Cylinder>;
@group(0) @binding(24) var<uniform> tool: Tool;
@group(0) @binding(25) var<storage, read_write> tool_acc: array<vec4<f32>>;
@group(0) @binding(26) var<storage, read_write> near: array<u32>;
@group(0) @binding(27) var<storage, read> held: array<vec4<f32>>;
@group(0) @binding(28) var<storage, read_write> tool_totals: array<vec4<f32>>;

// A penetration: the direction out of the instrument, the depth, and whether there is one.
struct Hit {
    dir: vec3<f32>,
    depth: f32,
    found: bool,
}

// The radius of cylinder `c` at `t`, its samples grown by `grow` (`ToolCylinder::radius_at`
// of the inflated cylinder).
fn radius_at(c: u32, t: f32, grow: f32) -> f32 {
    let n = bitcast<u32>(cylinders[c].axis.w);
    var k = 0u;
    while k < n && cylinders[c].t[k] <= t {
        k += 1u;
    }
    if k == 0u {
        return cylinders[c].r[0] + grow;
    }
    if k == n {
        return cylinders[c].r[n - 1u] + grow;
    }
    let t0 = cylinders[c].t[k - 1u];
    let t1 = cylinders[c].t[k];
    let r0 = cylinders[c].r[k - 1u] + grow;
    let r1 = cylinders[c].r[k] + grow;
    return r0 + (r1 - r0) * ((t - t0) / (t1 - t0));
}

// The rectum paper's test of `v` against cylinder `c` grown by `grow`
// (`ToolCylinder::penetration`): the angles at both axis ends, then the distance to the axis
// against the radius there.
fn penetration(c: u32, v: vec3<f32>, grow: f32) -> Hit {
    let miss = Hit(vec3<f32>(0.0), 0.0, false);
    let cy = cylinders[c];
    let s0 = dot(cy.axis.xyz, v - cy.p0.xyz);
    if !(s0 >= 0.0) {
        return miss;
    }
    let s1 = dot(-cy.axis.xyz, v - cy.p1.xyz);
    if !(s1 >= 0.0) {
        return miss;
    }
    let t = clamp(s0 * cy.p0.w, 0.0, 1.0);
    let axis_point = cy.p0.xyz + cy.axis.xyz * t;
    let r = radius_at(c, t, grow);
    let off = v - axis_point;
    let d2 = dot(off, off);
    if !(d2 < r * r) {
        return miss;
    }
    let d = sqrt(d2);
    if d <= cy.p1.w {
        return Hit(cy.on_axis_dir.xyz, r, true);
    }
    let perp = off - cy.unit_axis.xyz * dot(off, cy.unit_axis.xyz);
    let rcp = 1.0 / length(perp);
    var dir = cy.on_axis_dir.xyz;
    if rcp > 0.0 && rcp < 3.4e38 {
        dir = perp * rcp;
    }
    return Hit(dir, r - d, true);
}

// The deepest of the instrument's cylinders `v` is inside (the first on a tie).
fn deepest(v: vec3<f32>, grow: f32) -> Hit {
    var best = Hit(vec3<f32>(0.0), 0.0, false);
    for (var c = 0u; c < tool.cylinders; c++) {
        let hit = penetration(c, v, grow);
        if hit.found && (!best.found || hit.depth > best.depth) {
            best = hit;
        }
    }
    return best;
}

// A pushing hand (`ToolPush::project`): at a substep's first sweep every particle is listed
// if it is inside the instrument grown by the list's margin; then each listed free particle
// inside the grown instrument moves out along the test's direction by its depth.
@compute @workgroup_size(64)
fn push_tool(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = index(gid);
    if i >= tool.items {
        return;
    }
    let xi = x[i];
    var acc = vec4<f32>(0.0);
    if tool.first != 0u {
        near[i] = select(0u, 1u, deepest(xi.xyz, tool.grow_wide).found);
    } else {
        acc = vec4<f32>(tool_acc[i].xyz, 0.0);
    }
    if near[i] != 0u && xi.w > 0.0 {
        let hit = deepest(xi.xyz, tool.grow);
        if hit.found {
            let dx = hit.dir * hit.depth;
            x[i] = vec4<f32>(xi.xyz + dx, xi.w);
            acc = vec4<f32>(acc.xyz + dx / xi.w, 1.0);
        }
    }
    tool_acc[i] = acc;
}

// A grasping hand (`Grasp::project`): each held free particle pulled by its XPBD spring towards
// where it sat in the jaw (its multiplier starting at zero at a substep's first sweep).
@compute @workgroup_size(64)
fn grasp_tool(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = index(gid);
    if k >= tool.items {
        return;
    }
    let h = held[k];
    let i = bitcast<u32>(h.w);
    var l = vec3<f32>(0.0);
    if tool.first == 0u {
        l = tool_acc[k].xyz;
    }
    let xi = x[i];
    if xi.w > 0.0 {
        let c = xi.xyz - (tool.jaw + h.xyz);
        let dl = (-c - tool.alpha * l) / (xi.w + tool.alpha);
        l += dl;
        x[i] = vec4<f32>(xi.xyz + dl * xi.w, xi.w);
    }
    tool_acc[k] = vec4<f32>(l, 0.0);
}

var<workgroup> partial: array<vec4<f32>, 64>;

// One hand's sums after a substep, in a fixed order (one workgroup: invocation `t` sums items
// `t`, `t + 64`, ... in turn, then the first sums the 64 partial sums in turn), added to the
// hand's totals; the count of particles pushed in the last sweep kept at its largest.
@compute @workgroup_size(64)
fn tool_sums(@builtin(local_invocation_index) t: u32) {
    var s = vec4<f32>(0.0);
    for (var i = t; i < tool.items; i += 64u) {
        s += tool_acc[i];
    }
    partial[t] = s;
    workgroupBarrier();
    if t == 0u {
        var total = vec4<f32>(0.0);
        for (var k = 0u; k < 64u; k++) {
            total += partial[k];
        }
        let prev = tool_totals[tool.hand];
        tool_totals[tool.hand] = vec4<f32>(prev.xyz + total.xyz, max(prev.w, total.w));
    }
}
