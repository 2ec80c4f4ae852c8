// Corner kernel: the 8-neighbour code of every free pixel, looked up in the rule table.
// CPU twin: src/cpu/ogm_corners.rs. The rule table is derived once in Rust (RuleTable) and uploaded; this
// kernel only indexes it.
//
// Two entry points make the output exact and ordered without atomics on the output:
//   count: each workgroup counts the keypoints of its 1024 pixels (256 words of 4);
//   write: the host turns the counts into offsets and dispatches one workgroup per group that has
//          keypoints (most have none); each writes its keypoints at its offset, ordered inside the group by
//          a prefix sum. Words are row-major, so the list is in (y, x) order. Only list positions in [out_start, out_end) are written, so an output larger than
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
    active_len: u32, // entries of active_groups (write pass)
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> rule_table: array<u32, 256>;
@group(0) @binding(2) var<storage, read> states: array<u32>;
@group(0) @binding(3) var<storage, read_write> counts: array<u32>;
@group(0) @binding(4) var<storage, read> active_groups: array<vec2<u32>>; // (group, first list position)
@group(0) @binding(5) var<storage, read_write> keypoints: array<vec4<u32>>;

var<workgroup> scan: array<u32, 256>;
var<workgroup> group_total: atomic<u32>;

// One bit per pixel, in bit 8k for byte k, when the pixel sets its bit in a neighbour code: occupied (state
// 2, bit 1 of the byte), or unknown (state 1, bit 0) when unknown counts as occupied. Words outside the
// buffer, and the padding bytes past the row's end, are 0: outside the tile's buffer is outside the map,
// because the buffer holds the one-pixel halo wherever the map extends.
fn blocking_word(wx: i32, y: i32) -> u32 {
    if wx < 0 || y < 0 || wx >= i32(params.stride) || y >= i32(params.buf_h) {
        return 0u;
    }
    let s = states[u32(y) * params.stride + u32(wx)];
    let unknown = select(0u, s, params.unknown_as_occupied != 0u);
    let bits = ((s >> 1u) | unknown) & 0x01010101u;
    let valid = params.buf_w - u32(wx) * 4u; // at least 1
    return select(bits & ((1u << (valid * 8u)) - 1u), bits, valid >= 4u);
}

// Six bits: the pixels left of, inside and right of word wx of row y (bit 0 is pixel 4*wx - 1).
fn row_bits(wx: i32, y: i32) -> u32 {
    let l = blocking_word(wx - 1, y);
    let c = blocking_word(wx, y);
    let r = blocking_word(wx + 1, y);
    let packed = (c & 1u) | ((c >> 7u) & 2u) | ((c >> 14u) & 4u) | ((c >> 21u) & 8u);
    return (l >> 24u) | (packed << 1u) | ((r & 1u) << 5u);
}

// What the four pixels of word i need: x and y of its first pixel, its state word, and the blocking bits
// of the rows above, at and below it (see row_bits).
struct Word {
    x0: u32,
    y: u32,
    centre: u32,
    up: u32,
    mid: u32,
    down: u32,
}

fn load_word(i: u32) -> Word {
    let y = i / params.stride;
    let wx = i % params.stride;
    return Word(
        wx * 4u,
        y,
        states[i],
        row_bits(i32(wx), i32(y) - 1),
        row_bits(i32(wx), i32(y)),
        row_bits(i32(wx), i32(y) + 1),
    );
}

// (rule, code) of pixel k of the word; rule 0 for non-keypoints and for pixels outside the core.
fn pixel_rule(w: Word, k: u32) -> vec2<u32> {
    let x = w.x0 + k;
    let free = ((w.centre >> (8u * k)) & 0xffu) == 0u;
    let core = x >= params.core_x0 && x < params.core_x1 && w.y >= params.core_y0 && w.y < params.core_y1;
    if !(free && core) {
        return vec2<u32>(0u, 0u);
    }
    let u = w.up >> k;
    let m = w.mid >> k;
    let d = w.down >> k;
    // Bit order: Q, B, P, A, Q', B', P', A' (clockwise from the top-left), as in src/rules.rs.
    let code = (u & 7u)
        | (((m >> 2u) & 1u) << 3u)
        | (((d >> 2u) & 1u) << 4u)
        | (((d >> 1u) & 1u) << 5u)
        | ((d & 1u) << 6u)
        | ((m & 1u) << 7u);
    return vec2<u32>(rule_table[code], code);
}

fn word_count(w: Word) -> u32 {
    var n = 0u;
    for (var k = 0u; k < 4u; k++) {
        n += select(0u, 1u, pixel_rule(w, k).x != 0u);
    }
    return n;
}

@compute @workgroup_size(256)
fn count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let group = wg.y * params.groups_x + wg.x;
    let i = group * 256u + li;
    var n = 0u;
    if i < params.words {
        n = word_count(load_word(i));
    }
    // One atomic add per invocation that found something: far fewer barriers than a tree reduction,
    // which matters on software adapters where a barrier is a context switch.
    if li == 0u {
        atomicStore(&group_total, 0u);
    }
    workgroupBarrier();
    if n != 0u {
        atomicAdd(&group_total, n);
    }
    workgroupBarrier();
    if li == 0u {
        counts[group] = atomicLoad(&group_total);
    }
}

@compute @workgroup_size(256)
fn write(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let slot = wg.y * params.groups_x + wg.x;
    if slot >= params.active_len {
        return; // the 2D dispatch rounds up
    }
    let entry = active_groups[slot];
    let group = entry.x;
    let i = group * 256u + li;
    var w: Word;
    var n = 0u;
    if i < params.words {
        w = load_word(i);
        n = word_count(w);
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
    var pos = entry.y + scan[li] - n;
    for (var k = 0u; k < 4u; k++) {
        let found = pixel_rule(w, k);
        if found.x != 0u {
            if pos >= params.out_start && pos < params.out_end {
                keypoints[pos - params.out_start] = vec4<u32>(
                    params.origin_x + w.x0 + k,
                    params.origin_y + w.y,
                    found.x,
                    found.y,
                );
            }
            pos += 1u;
        }
    }
}
