// Corner kernel: the 8-neighbour code of every free pixel, looked up in the rule table.
// CPU twin: src/cpu/ogm_corners.rs. The rule table is derived once in Rust (RuleTable) and uploaded; this
// kernel only indexes it.
//
// Two entry points make the output exact and ordered without atomics on the output:
//   count: each workgroup counts the keypoints of its 1024 pixels (256 words of 4);
//   write: after the host has turned the counts into offsets, each workgroup writes its keypoints at its
//          offset, ordered inside the workgroup by a prefix sum. Words are row-major, so the list is in
//          (y, x) order. Only list positions in [out_start, out_end) are written, so an output larger than
//          one buffer binding is produced in several passes rather than truncated.

struct Params {
    buf_w: u32,
    buf_h: u32,
    stride: u32,
    words: u32,
    core_x0: u32, // the tile's own pixels, in buffer coordinates; the rest is the one-pixel halo
    core_y0: u32,
    core_x1: u32,
    core_y1: u32,
    origin_x: u32, // map coordinates of buffer pixel (0, 0)
    origin_y: u32,
    unknown_as_occupied: u32,
    groups_x: u32,
    out_start: u32,
    out_end: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> rule_table: array<u32, 256>;
@group(0) @binding(2) var<storage, read> states: array<u32>;
@group(0) @binding(3) var<storage, read_write> counts: array<u32>;
@group(0) @binding(4) var<storage, read> offsets: array<u32>;
@group(0) @binding(5) var<storage, read_write> keypoints: array<vec4<u32>>;

var<workgroup> scan: array<u32, 256>;

fn state_at(x: u32, y: u32) -> u32 {
    return (states[y * params.stride + (x >> 2u)] >> ((x & 3u) * 8u)) & 0xffu;
}

// 1 when the neighbour at (x + dx, y + dy) sets its bit. The buffer holds every in-map neighbour of a core
// pixel (the halo), so a neighbour outside the buffer is outside the map: not occupied.
fn blocks(x: u32, y: u32, dx: i32, dy: i32) -> u32 {
    let nx = i32(x) + dx;
    let ny = i32(y) + dy;
    if nx < 0 || ny < 0 || nx >= i32(params.buf_w) || ny >= i32(params.buf_h) {
        return 0u;
    }
    let s = state_at(u32(nx), u32(ny));
    return select(0u, 1u, s == 2u || (s == 1u && params.unknown_as_occupied != 0u));
}

// (rule, code) of buffer pixel (x, y); rule 0 when it is no keypoint or not a core pixel.
fn pixel_rule(x: u32, y: u32) -> vec2<u32> {
    if x < params.core_x0 || x >= params.core_x1 || y < params.core_y0 || y >= params.core_y1 {
        return vec2<u32>(0u, 0u);
    }
    if state_at(x, y) != 0u {
        return vec2<u32>(0u, 0u);
    }
    // Bit order: Q, B, P, A, Q', B', P', A' (clockwise from the top-left), as in src/rules.rs.
    let code = blocks(x, y, -1, -1)
        | (blocks(x, y, 0, -1) << 1u)
        | (blocks(x, y, 1, -1) << 2u)
        | (blocks(x, y, 1, 0) << 3u)
        | (blocks(x, y, 1, 1) << 4u)
        | (blocks(x, y, 0, 1) << 5u)
        | (blocks(x, y, -1, 1) << 6u)
        | (blocks(x, y, -1, 0) << 7u);
    return vec2<u32>(rule_table[code], code);
}

@compute @workgroup_size(256)
fn count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let group = wg.y * params.groups_x + wg.x;
    let i = group * 256u + li;
    var n = 0u;
    if i < params.words {
        let y = i / params.stride;
        let x0 = (i % params.stride) * 4u;
        for (var k = 0u; k < 4u; k++) {
            n += select(0u, 1u, pixel_rule(x0 + k, y).x != 0u);
        }
    }
    scan[li] = n;
    workgroupBarrier();
    for (var s = 128u; s > 0u; s >>= 1u) {
        if li < s {
            scan[li] += scan[li + s];
        }
        workgroupBarrier();
    }
    if li == 0u {
        counts[group] = scan[0];
    }
}

@compute @workgroup_size(256)
fn write(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let group = wg.y * params.groups_x + wg.x;
    let i = group * 256u + li;
    var found: array<vec2<u32>, 4>;
    var n = 0u;
    var y = 0u;
    var x0 = 0u;
    if i < params.words {
        y = i / params.stride;
        x0 = (i % params.stride) * 4u;
        for (var k = 0u; k < 4u; k++) {
            found[k] = pixel_rule(x0 + k, y);
            n += select(0u, 1u, found[k].x != 0u);
        }
    }
    // Inclusive prefix sum of n over the workgroup (Hillis-Steele).
    scan[li] = n;
    workgroupBarrier();
    for (var off = 1u; off < 256u; off <<= 1u) {
        let v = select(0u, scan[select(0u, li - off, li >= off)], li >= off);
        workgroupBarrier();
        scan[li] += v;
        workgroupBarrier();
    }
    if n == 0u {
        return;
    }
    var pos = offsets[group] + scan[li] - n;
    for (var k = 0u; k < 4u; k++) {
        if found[k].x != 0u {
            if pos >= params.out_start && pos < params.out_end {
                keypoints[pos - params.out_start] = vec4<u32>(
                    params.origin_x + x0 + k,
                    params.origin_y + y,
                    found[k].x,
                    found[k].y,
                );
            }
            pos += 1u;
        }
    }
}
