// Transform-scoring kernel of the map merger: per candidate rigid transform, how many points (one map's
// wall pixels) land on target pixels with each of three flags (inside, near a wall, deep in free space).
// CPU twin: src/cpu/merge_score.rs. The landing pixel is the same integer formula,
// ((cos x - sin y + tx + half) >> F, (sin x + cos y + ty + half) >> F), in i32: WGSL defines i32 arithmetic
// as wrapping two's complement and >> on i32 as the arithmetic shift, exactly Rust's wrapping_* and >>,
// and the host's bounds keep every sum below 2^31 anyway. Counts are sums of 0/1, so their order of
// accumulation does not matter and every count is bit-identical to the CPU's.
//
// Dispatch: workgroup_id.y is the transform; the groups along x split the points, each invocation striding
// over them. The target is uploaded in bands of rows: a point counts in the dispatch of the band its
// landing row falls in, and the bands' dispatches add into the same counters.

struct Params {
    // Target width, height and words per row (four flag bytes a word).
    width: u32,
    height: u32,
    stride: u32,
    // The rows this dispatch's flags hold: [band_y0, band_y0 + band_h).
    band_y0: u32,
    band_h: u32,
    // Points in this dispatch's point buffer, and workgroups along x (the invocations' stride).
    n_points: u32,
    groups_x: u32,
    frac_bits: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> flags: array<u32>;
// A point per word: x in the low 16 bits, y in the high 16 (both below 2^15).
@group(0) @binding(2) var<storage, read> points: array<u32>;
// (cos, sin, tx, ty) per transform, fixed point.
@group(0) @binding(3) var<storage, read> transforms: array<vec4<i32>>;
// Inside, near and deep counts per transform.
@group(0) @binding(4) var<storage, read_write> counts: array<atomic<u32>>;

const GROUP: u32 = 256u;

// The workgroup's counts, added to the global ones once, so the global atomics see one add per group.
var<workgroup> group_counts: array<atomic<u32>, 3>;

@compute @workgroup_size(256)
fn merge_score(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if li < 3u {
        atomicStore(&group_counts[li], 0u);
    }
    workgroupBarrier();
    let t = transforms[wg.y];
    let half = 1 << (params.frac_bits - 1u);
    let y0 = i32(params.band_y0);
    let y1 = y0 + i32(params.band_h);
    var inside = 0u;
    var near = 0u;
    var deep = 0u;
    for (var i = wg.x * GROUP + li; i < params.n_points; i += params.groups_x * GROUP) {
        let p = points[i];
        let x = i32(p & 0xffffu);
        let y = i32(p >> 16u);
        let qx = (t.x * x - t.y * y + t.z + half) >> params.frac_bits;
        let qy = (t.y * x + t.x * y + t.w + half) >> params.frac_bits;
        // Outside the band (the host's bands never reach past the target; height guards that too).
        if qx < 0 || u32(qx) >= params.width || qy < y0 || qy >= y1 || u32(qy) >= params.height {
            continue;
        }
        let bx = u32(qx);
        let word = flags[u32(qy - y0) * params.stride + bx / 4u];
        let f = (word >> ((bx % 4u) * 8u)) & 0xffu;
        inside += f & 1u;
        near += (f >> 1u) & 1u;
        deep += (f >> 2u) & 1u;
    }
    if inside != 0u {
        atomicAdd(&group_counts[0], inside);
    }
    if near != 0u {
        atomicAdd(&group_counts[1], near);
    }
    if deep != 0u {
        atomicAdd(&group_counts[2], deep);
    }
    workgroupBarrier();
    if li < 3u {
        let c = atomicLoad(&group_counts[li]);
        if c != 0u {
            atomicAdd(&counts[wg.y * 3u + li], c);
        }
    }
}
