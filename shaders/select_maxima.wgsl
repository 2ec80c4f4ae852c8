// The baselines' selection on the device: every core pixel whose score is positive and at least every
// in-map 8-neighbour's (a 3x3 local maximum), compacted into a list in (y, x) order, and the largest core
// score. CPU twin: src/cpu/select_maxima.rs. The host then applies the thresholds relative to the map's
// maximum (and Shi-Tomasi's minimum distance) to these candidates alone, so only they cross to the host.
//
// Scores are signed 64-bit integers as (low, high) words, over the core grown by one pixel (the score
// region) so that the neighbours of edge pixels are there. `count`: per workgroup of 256 core pixels, the
// candidates and the largest score; the scan (scan.wgsl) turns the counts into list positions;
// `reduce_max`: the largest of the workgroups' maxima; `scatter`: each candidate to its position.

struct Params {
    region_x0: u32, // the score region, map coordinates
    region_y0: u32,
    region_w: u32,
    region_h: u32,
    core_x0: u32,
    core_y0: u32,
    core_w: u32,
    core_h: u32,
    map_w: u32,
    map_h: u32,
    groups_x: u32,
    n_items: u32, // core pixels
    out_start: u32, // list positions written: [out_start, out_end)
    out_end: u32,
    n_groups: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> scores: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read_write> counts: array<u32>;
@group(0) @binding(3) var<storage, read_write> maxes: array<vec2<u32>>;
// x, y, then the score's low and high words.
@group(0) @binding(4) var<storage, read_write> out: array<vec4<u32>>;

var<workgroup> wg_count: atomic<u32>;
var<workgroup> wg_hi: atomic<i32>;
var<workgroup> wg_lo: atomic<u32>;
var<workgroup> wg_max: array<vec2<u32>, 256>;
var<workgroup> wg_bits: array<atomic<u32>, 8>;
var<workgroup> wg_n: u32;

const I64_MIN: vec2<u32> = vec2<u32>(0u, 0x80000000u);

fn gt(a: vec2<u32>, b: vec2<u32>) -> bool {
    return i32(a.y) > i32(b.y) || (a.y == b.y && a.x > b.x);
}

fn score_at(x: u32, y: u32) -> vec2<u32> {
    return scores[(y - params.region_y0) * params.region_w + (x - params.region_x0)];
}

// Whether core pixel i is a candidate; its map coordinates and score.
fn candidate(i: u32) -> vec4<u32> {
    let x = params.core_x0 + i % params.core_w;
    let y = params.core_y0 + i / params.core_w;
    let v = score_at(x, y);
    var keep = gt(v, vec2<u32>(0u, 0u));
    let y0 = select(y - 1u, 0u, y == 0u);
    let x0 = select(x - 1u, 0u, x == 0u);
    let y1 = min(y + 2u, params.map_h);
    let x1 = min(x + 2u, params.map_w);
    for (var ny = y0; ny < y1 && keep; ny++) {
        for (var nx = x0; nx < x1; nx++) {
            if gt(score_at(nx, ny), v) {
                keep = false;
            }
        }
    }
    return vec4<u32>(x, y, select(0u, 1u, keep), 0u);
}

fn group_of(wg: vec3<u32>) -> u32 {
    return wg.y * params.groups_x + wg.x;
}

@compute @workgroup_size(256)
fn count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let group = group_of(wg);
    let i = group * 256u + li;
    if li == 0u {
        atomicStore(&wg_count, 0u);
        atomicStore(&wg_hi, i32(I64_MIN.y));
        atomicStore(&wg_lo, 0u);
    }
    var m = I64_MIN;
    workgroupBarrier();
    if i < params.n_items {
        let c = candidate(i);
        m = score_at(c.x, c.y);
        if c.z != 0u {
            atomicAdd(&wg_count, 1u);
        }
    }
    // The workgroup's largest score by two 32-bit atomics: the high word first, then the low word among
    // the scores with that high word (two barriers, where a tree takes eight).
    atomicMax(&wg_hi, i32(m.y));
    workgroupBarrier();
    if i32(m.y) == atomicLoad(&wg_hi) {
        atomicMax(&wg_lo, m.x);
    }
    workgroupBarrier();
    if li == 0u && group < params.n_groups {
        counts[group] = atomicLoad(&wg_count);
        maxes[group] = vec2<u32>(atomicLoad(&wg_lo), u32(atomicLoad(&wg_hi)));
    }
}

@compute @workgroup_size(256)
fn reduce_max(@builtin(local_invocation_index) li: u32) {
    var m = I64_MIN;
    for (var g = li; g < params.n_groups; g += 256u) {
        if gt(maxes[g], m) {
            m = maxes[g];
        }
    }
    wg_max[li] = m;
    workgroupBarrier();
    for (var d = 128u; d > 0u; d >>= 1u) {
        if li < d && gt(wg_max[li + d], wg_max[li]) {
            wg_max[li] = wg_max[li + d];
        }
        workgroupBarrier();
    }
    if li == 0u {
        maxes[params.n_groups] = wg_max[0];
    }
}

@compute @workgroup_size(256)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let group = group_of(wg);
    if li == 0u {
        var n = 0u;
        if group < params.n_groups {
            // counts[] holds each group's first list position now (the exclusive scan).
            n = counts[group + 1u] - counts[group];
        }
        wg_n = n;
    }
    if workgroupUniformLoad(&wg_n) == 0u {
        return;
    }
    let i = group * 256u + li;
    var c = vec4<u32>(0u);
    if i < params.n_items {
        c = candidate(i);
    }
    // A candidate's rank inside the workgroup, for (y, x) order: the candidates before it, from one bit per
    // invocation (two barriers, no scan).
    if li < 8u {
        atomicStore(&wg_bits[li], 0u);
    }
    workgroupBarrier();
    if c.z != 0u {
        atomicOr(&wg_bits[li / 32u], 1u << (li % 32u));
    }
    workgroupBarrier();
    if c.z != 0u {
        var rank = countOneBits(atomicLoad(&wg_bits[li / 32u]) & ((1u << (li % 32u)) - 1u));
        for (var k = 0u; k < li / 32u; k++) {
            rank += countOneBits(atomicLoad(&wg_bits[k]));
        }
        let p = counts[group] + rank;
        if p >= params.out_start && p < params.out_end {
            let v = score_at(c.x, c.y);
            out[p - params.out_start] = vec4<u32>(c.x, c.y, v.x, v.y);
        }
    }
}
