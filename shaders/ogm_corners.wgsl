// The OGM corner detector in one pass over the raw map bytes. CPU twin: src/backend/reference/ogm_corners.rs
// (the reference); src/backend/fast/ogm.rs computes the same bit-planes on the CPU.
//
// The pixels' binding and how runs of them are read come from a library prepended to this file:
// shaders/lib/ogm_fetch_runs.wgsl (rows 16-byte aligned: staged bands, aligned maps in device buffers) or
// shaders/lib/ogm_fetch_bytes.wgsl (any offset and row pitch: maps in a caller's device buffer).
//
// `detect`: an invocation owns 32 pixels of a row (eight words, two 16-byte loads) and walks down a strip of
// STRIP rows, keeping the free and blocking bit-planes of three rows in registers, so every byte is read
// once (plus two halo rows per strip). Classification is the interval compare the host derives from the
// ClassTable (ValueSet), or the 256-entry table when a state's values are not an interval. The eight
// neighbour planes are shifts of the blocking planes; the pixel just left and right of the 32 are loaded
// directly (no subgroup size is assumed). A bit-sliced count skips every pixel with fewer blocking
// neighbours than the smallest accepted code; the few survivors are looked up in the rule table, derived
// once in Rust and copied to workgroup memory. A workgroup's keypoints go to its scratch region in (y, x)
// order, and it writes its count per row.
// `scatter`: after the device-side scan of those counts (scan.wgsl), each workgroup copies its rows to
// their final list positions, which depend only on the counts: the list is in (y, x) order and
// deterministic, sized exactly, and a workgroup whose keypoints overflow its scratch is reported (status[1])
// for a rerun with more room rather than truncated.
// `finish`: adds the tile's total to the running count (status[0]), which the next tile starts from.

const LANES: u32 = 64u;
const STRIP: u32 = 16u;
const SLOTS: u32 = 1024u; // LANES * STRIP

struct Params {
    buf_w: u32,      // pixels per buffer row
    buf_h: u32,
    row_bytes: u32,  // bytes from a buffer row to the next in the binding
    lanes_x: u32,    // 32-pixel runs per row
    groups_x: u32,   // workgroups across a row
    core_x0: u32,    // the tile's own pixels, buffer coordinates; the rest is the one-pixel halo
    core_y0: u32,
    core_x1: u32,
    core_y1: u32,
    x_base: u32,     // added to buffer x (map x of buffer column 0)
    y_base: u32,     // added to buffer y (row of buffer row 0, counted from the slab's first row)
    interval: u32,   // 1: free and blocking are value intervals; 0: look values up in the class table
    free_lo: u32,    // the free interval's first value, in every byte
    free_span: u32,  // its length minus one, in every byte
    blk_lo: u32,     // the same for the blocking interval
    blk_span: u32,
    min_bits: u32,   // fewest set bits of an accepted code
    scratch: u32,    // keypoints a workgroup's scratch region holds
    out_start: u32,  // list positions written: [out_start, out_end)
    out_end: u32,
    n_counts: u32,   // (core rows) * groups_x
    first_byte: u32, // the binding's byte of buffer pixel (0, 0)
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// 0..256: the class table (bit 0 free, bit 1 blocking); 256..512: the rule table.
@group(0) @binding(1) var<storage, read> tables: array<u32, 512>;
// Binding 2, the pixels, is declared by the fetch library.
// Per (core row, workgroup column) keypoint counts, then the scan's levels (scan.wgsl).
@group(0) @binding(3) var<storage, read_write> counts: array<u32>;
// Two regions of `scratch` entries per workgroup: as found, and in (y, x) order.
@group(0) @binding(4) var<storage, read_write> found: array<vec2<u32>>;
@group(0) @binding(5) var<storage, read_write> ordered: array<vec2<u32>>;
// 0: keypoints before this tile; 1: the largest workgroup total that overflowed its scratch.
@group(0) @binding(6) var<storage, read_write> status: array<atomic<u32>, 4>;
// The list: x, then y << 8 | code (8 bytes a keypoint; the rule is the table's entry for the code).
@group(0) @binding(7) var<storage, read_write> keypoints: array<vec2<u32>>;

var<workgroup> wg_rules: array<u32, 256>;
var<workgroup> wg_class: array<u32, 256>;
var<workgroup> wg_fill: atomic<u32>;
var<workgroup> wg_total: u32;
var<workgroup> blocks: array<u32, SLOTS>;  // per (row, lane): scratch start << 6 | count
var<workgroup> offsets: array<u32, SLOTS>; // per (row, lane): position in the ordered region
var<workgroup> partial: array<u32, LANES>;

// One row's planes over an invocation's 32 pixels: free, blocking, and the blocking bits of the pixels
// just left and right of them (0 outside the buffer: outside the tile's buffer is outside the map).
struct Row {
    free: u32,
    blk: u32,
    left: u32,
    right: u32,
}

// Bits 0..3: which of the four bytes of `p` lie in lo..=lo + span (mod 256), `lo4` and `span4` being lo and
// span in every byte. Bytewise subtraction, then a bytewise unsigned compare, no carries across bytes
// (Hacker's Delight 2-18); checked against the plain compare for every lo, span and value.
fn in_interval(p: u32, lo4: u32, span4: u32) -> u32 {
    let h = 0x80808080u;
    let d = ((p | h) - (lo4 & ~h)) ^ ((p ^ ~lo4) & h);
    let t = (span4 | h) - (d & ~h);
    let m = (((span4 & ~d) | (~(span4 ^ d) & t)) & h) >> 7u;
    return (m | (m >> 7u) | (m >> 14u) | (m >> 21u)) & 0xfu;
}

// Free bits (0..3) and blocking bits (4..7) of the four pixels of word `p`, pixel k at bit k.
fn classify_word(p: u32) -> u32 {
    if params.interval != 0u {
        return in_interval(p, params.free_lo, params.free_span)
            | (in_interval(p, params.blk_lo, params.blk_span) << 4u);
    }
    var out = 0u;
    for (var k = 0u; k < 4u; k++) {
        let c = wg_class[(p >> (8u * k)) & 0xffu];
        out |= ((c & 1u) << k) | (((c >> 1u) & 1u) << (k + 4u));
    }
    return out;
}

fn load_row(lane: u32, y: i32) -> Row {
    var r = Row(0u, 0u, 0u, 0u);
    if y < 0 || u32(y) >= params.buf_h || lane >= params.lanes_x {
        return r;
    }
    let at = params.first_byte + u32(y) * params.row_bytes + lane * 32u;
    let p = run_at(at);
    let c0 = classify_word(p[0]);
    let c1 = classify_word(p[1]);
    let c2 = classify_word(p[2]);
    let c3 = classify_word(p[3]);
    let c4 = classify_word(p[4]);
    let c5 = classify_word(p[5]);
    let c6 = classify_word(p[6]);
    let c7 = classify_word(p[7]);
    let lo = (c0 & 0xfu) | ((c1 & 0xfu) << 4u) | ((c2 & 0xfu) << 8u) | ((c3 & 0xfu) << 12u)
        | ((c4 & 0xfu) << 16u) | ((c5 & 0xfu) << 20u) | ((c6 & 0xfu) << 24u) | ((c7 & 0xfu) << 28u);
    let hi = (c0 >> 4u) | ((c1 >> 4u) << 4u) | ((c2 >> 4u) << 8u) | ((c3 >> 4u) << 12u)
        | ((c4 >> 4u) << 16u) | ((c5 >> 4u) << 20u) | ((c6 >> 4u) << 24u) | ((c7 >> 4u) << 28u);
    r.free = lo;
    r.blk = hi;
    // Padding past the row's end is neither free nor blocking.
    let x0 = lane * 32u;
    let valid = params.buf_w - x0;
    if valid < 32u {
        let m = (1u << valid) - 1u;
        r.free &= m;
        r.blk &= m;
    }
    // The pixels just left and right of the run: the blocking bit of pixel 0 of a lone byte.
    if lane > 0u {
        r.left = (classify_word(byte_at(at - 1u)) >> 4u) & 1u;
    }
    if x0 + 32u < params.buf_w {
        r.right = (classify_word(byte_at(at + 32u)) >> 4u) & 1u;
    }
    return r;
}

fn full_add(a: u32, b: u32, c: u32) -> vec2<u32> {
    let t = a ^ b;
    return vec2<u32>(t ^ c, (a & b) | (c & t));
}

// The eight neighbour planes: Q, B, P, A, Q', B', P', A' clockwise from the top-left, as in src/rules.rs.
struct Nb {
    q: u32,
    b: u32,
    p: u32,
    a: u32,
    q2: u32,
    b2: u32,
    p2: u32,
    a2: u32,
}

fn neighbours(up: Row, mid: Row, down: Row) -> Nb {
    return Nb(
        (up.blk << 1u) | up.left,
        up.blk,
        (up.blk >> 1u) | (up.right << 31u),
        (mid.blk >> 1u) | (mid.right << 31u),
        (down.blk >> 1u) | (down.right << 31u),
        down.blk,
        (down.blk << 1u) | down.left,
        (mid.blk << 1u) | mid.left,
    );
}

// One step of the comparison of a bit-sliced count with m, from the top bit down.
fn cmp_step(gt_eq: vec2<u32>, bit: u32, c: u32) -> vec2<u32> {
    if bit == 1u {
        return vec2<u32>(gt_eq.x, gt_eq.y & c);
    }
    return vec2<u32>(gt_eq.x | (gt_eq.y & c), gt_eq.y & ~c);
}

// Per pixel, whether at least `m` of the eight neighbour planes are set (a bit-sliced count).
fn at_least(n: Nb, m: u32) -> u32 {
    if m > 8u {
        return 0u;
    }
    let a = full_add(n.q, n.b, n.p);
    let b = full_add(n.a, n.q2, n.b2);
    let c = vec2<u32>(n.p2 ^ n.a2, n.p2 & n.a2);
    let d = full_add(a.x, b.x, c.x);
    let t = full_add(a.y, b.y, c.y);
    let bit1 = t.x ^ d.y;
    let t2 = t.x & d.y;
    var ge = vec2<u32>(0u, 0xffffffffu);
    ge = cmp_step(ge, (m >> 3u) & 1u, t.y & t2);
    ge = cmp_step(ge, (m >> 2u) & 1u, t.y ^ t2);
    ge = cmp_step(ge, (m >> 1u) & 1u, bit1);
    ge = cmp_step(ge, m & 1u, d.x);
    return ge.x | ge.y;
}

fn code_of(n: Nb, j: u32) -> u32 {
    return ((n.q >> j) & 1u)
        | (((n.b >> j) & 1u) << 1u)
        | (((n.p >> j) & 1u) << 2u)
        | (((n.a >> j) & 1u) << 3u)
        | (((n.q2 >> j) & 1u) << 4u)
        | (((n.b2 >> j) & 1u) << 5u)
        | (((n.p2 >> j) & 1u) << 6u)
        | (((n.a2 >> j) & 1u) << 7u);
}

fn group_index(wg: vec3<u32>) -> u32 {
    return wg.y * params.groups_x + wg.x;
}

@compute @workgroup_size(64)
fn detect(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    for (var i = li; i < 256u; i += LANES) {
        wg_class[i] = tables[i];
        wg_rules[i] = tables[256u + i];
    }
    if li == 0u {
        atomicStore(&wg_fill, 0u);
    }
    for (var r = 0u; r < STRIP; r++) {
        blocks[r * LANES + li] = 0u;
    }
    workgroupBarrier();

    let lane = wg.x * LANES + li;
    let x0 = lane * 32u;
    // Core columns of this run.
    var core_mask = 0u;
    if lane < params.lanes_x {
        for (var j = 0u; j < 32u; j++) {
            let x = x0 + j;
            if x >= params.core_x0 && x < params.core_x1 {
                core_mask |= 1u << j;
            }
        }
    }
    let base = group_index(wg) * params.scratch;
    let y0 = params.core_y0 + wg.y * STRIP;
    var up = load_row(lane, i32(y0) - 1);
    var mid = load_row(lane, i32(y0));
    for (var r = 0u; r < STRIP; r++) {
        let y = y0 + r;
        if y >= params.core_y1 {
            break;
        }
        let down = load_row(lane, i32(y) + 1);
        let n = neighbours(up, mid, down);
        let near = n.q | n.b | n.p | n.a | n.q2 | n.b2 | n.p2 | n.a2;
        var cand = 0u;
        if (mid.free & core_mask & near) != 0u {
            cand = mid.free & core_mask & at_least(n, params.min_bits);
        }
        if cand != 0u {
            var hits = 0u;
            var c = cand;
            while c != 0u {
                let j = firstTrailingBit(c);
                c &= c - 1u;
                if wg_rules[code_of(n, j)] != 0u {
                    hits |= 1u << j;
                }
            }
            let k = countOneBits(hits);
            if k != 0u {
                let start = atomicAdd(&wg_fill, k);
                blocks[r * LANES + li] = (start << 6u) | k;
                var at = start;
                while hits != 0u {
                    let j = firstTrailingBit(hits);
                    hits &= hits - 1u;
                    if at < params.scratch {
                        found[base + at] = vec2<u32>(
                            params.x_base + x0 + j,
                            ((params.y_base + y) << 8u) | code_of(n, j),
                        );
                    }
                    at += 1u;
                }
            }
        }
        up = mid;
        mid = down;
    }

    workgroupBarrier();
    if li == 0u {
        wg_total = atomicLoad(&wg_fill);
    }
    let total = workgroupUniformLoad(&wg_total);
    var rows = 0u;
    if y0 < params.core_y1 {
        rows = min(STRIP, params.core_y1 - y0);
    }
    let row0 = wg.y * STRIP; // first core row of the strip, counted from core_y0
    if total == 0u {
        if li < rows {
            counts[(row0 + li) * params.groups_x + wg.x] = 0u;
        }
        return;
    }
    // Exclusive prefix of the (row, lane) counts in row-major order: a lane sums 16 consecutive slots,
    // lane 0 scans the 64 sums, each lane then fills in its slots' positions.
    let per = SLOTS / LANES;
    var s = 0u;
    for (var i = 0u; i < per; i++) {
        s += blocks[li * per + i] & 63u;
    }
    partial[li] = s;
    workgroupBarrier();
    if li == 0u {
        var acc = 0u;
        for (var i = 0u; i < LANES; i++) {
            let v = partial[i];
            partial[i] = acc;
            acc += v;
        }
    }
    workgroupBarrier();
    var acc = partial[li];
    for (var i = 0u; i < per; i++) {
        offsets[li * per + i] = acc;
        acc += blocks[li * per + i] & 63u;
    }
    workgroupBarrier();
    if li < rows {
        let first = offsets[li * LANES];
        var next = total;
        if li + 1u < STRIP {
            next = offsets[(li + 1u) * LANES];
        }
        counts[(row0 + li) * params.groups_x + wg.x] = next - first;
    }
    if total > params.scratch {
        if li == 0u {
            atomicMax(&status[1], total);
        }
        return;
    }
    for (var r = 0u; r < rows; r++) {
        let e = r * LANES + li;
        let b = blocks[e];
        let src_at = base + (b >> 6u);
        let dst_at = base + offsets[e];
        for (var i = 0u; i < (b & 63u); i++) {
            ordered[dst_at + i] = found[src_at + i];
        }
    }
}

@compute @workgroup_size(64)
fn scatter(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let y0 = params.core_y0 + wg.y * STRIP;
    if y0 >= params.core_y1 {
        return;
    }
    let rows = min(STRIP, params.core_y1 - y0);
    let row0 = wg.y * STRIP;
    let before = atomicLoad(&status[0]);
    let base = group_index(wg) * params.scratch;
    var local = 0u;
    for (var r = 0u; r < rows; r++) {
        // counts[] now holds each (row, column)'s first position in the tile's list (the exclusive scan),
        // so an entry's count is the next entry's position minus its own.
        let c = (row0 + r) * params.groups_x + wg.x;
        let first = counts[c];
        let n = counts[c + 1u] - first;
        if n != 0u && local + n <= params.scratch {
            for (var i = li; i < n; i += LANES) {
                let p = before + first + i;
                if p >= params.out_start && p < params.out_end {
                    keypoints[p - params.out_start] = ordered[base + local + i];
                }
            }
        }
        local += n;
    }
}

@compute @workgroup_size(1)
fn finish() {
    // The exclusive scan over n_counts + 1 entries leaves the tile's total in the last.
    atomicAdd(&status[0], counts[params.n_counts]);
}
