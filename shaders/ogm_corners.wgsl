// The OGM corner detector in one pass over the raw map bytes. CPU twin: src/backend/reference/ogm_corners.rs
// (the reference); src/backend/fast/ogm.rs computes the same bit-planes on the CPU.
//
// The pixels' binding and how runs of them are read come from a library prepended to this file:
// shaders/lib/ogm_fetch_runs.wgsl (rows 16-byte aligned: staged bands, aligned maps in device buffers) or
// shaders/lib/ogm_fetch_bytes.wgsl (any offset and row pitch: maps in a caller's device buffer).
//
// `detect`: an invocation owns 32 pixels of a row (eight words, two 16-byte loads) and walks down a strip of
// `params.strip` rows (at most MAX_STRIP; the host takes fewer where a small map would leave the device
// short of workgroups), keeping the free and blocking bit-planes of three rows in registers, so every byte is read
// once (plus two halo rows per strip); the row two below is loaded before the row below is classified, so a
// row's loads are in flight while the invocation works. Classification compares four bytes at a time in
// the form the host derives from the ClassTable (ValueSet) and fixes when it builds the pipeline
// (override constants): a one-sided compare for a state whose values reach 0 or 255 (as the ROS
// thresholds' do), the general interval compare otherwise, or the 256-entry table when a state's values are
// not an interval. The eight neighbour planes are shifts of the blocking planes; the pixels just left and
// right of the 32 are loaded directly and classified alone (no subgroup size is assumed). A bit-sliced count skips every pixel with fewer blocking
// neighbours than the smallest accepted code; the few survivors are looked up in the rule table, derived
// once in Rust and copied to workgroup memory. A workgroup's keypoints go to its scratch region in (y, x)
// order, and it writes its count per row.
// `scatter`: after the device-side scan of those counts (scan.wgsl), each workgroup copies its rows to
// their final list positions, which depend only on the counts: the list is in (y, x) order and
// deterministic, sized exactly, and a workgroup whose keypoints overflow its scratch is reported (status[1])
// for a rerun with more room rather than truncated.
// `finish`: adds the tile's total to the running count (status[0]), which the next tile starts from.

// How the kernel classifies, fixed per pipeline by the host (src/backend/gpu/ogm.rs, DetectForm): TABLE
// looks every value up in the class table; otherwise each state's form is 0 (lo..=lo + span, mod 256),
// 1 (at least lo) or 2 (below lo), with lo and span in the parameters.
override TABLE: bool = false;
override FREE_FORM: u32 = 0u;
override BLK_FORM: u32 = 0u;

const LANES: u32 = 64u;
const MAX_STRIP: u32 = 16u;
const SLOTS: u32 = 1024u; // LANES * MAX_STRIP

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
    strip: u32,      // rows an invocation walks down, 1..=MAX_STRIP
    free_lo: u32,    // the free state's lo (see FREE_FORM), in every byte
    free_span: u32,  // its span, in every byte
    blk_lo: u32,     // the same for the blocking state
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

const H: u32 = 0x80808080u;

// Bits 7, 15, 23, 31: which of the four bytes of `p` lie in lo..=lo + span (mod 256), `lo4` and `span4`
// being lo and span in every byte. Bytewise subtraction, then a bytewise unsigned compare, no carries across
// bytes (Hacker's Delight 2-18); checked against the plain compare for every lo, span and value.
fn in_interval(p: u32, lo4: u32, span4: u32) -> u32 {
    let d = ((p | H) - (lo4 & ~H)) ^ ((p ^ ~lo4) & H);
    let t = (span4 | H) - (d & ~H);
    return ((span4 & ~d) | (~(span4 ^ d) & t)) & H;
}

// Bits 7, 15, 23, 31: which of the four bytes of `p` are at least the byte of `y4` (y in every byte): the
// low seven bits compared by a subtraction that cannot borrow across bytes, the top bit decided apart.
// Checked against the plain compare for every y and value.
fn bytes_at_least(p: u32, y4: u32) -> u32 {
    let d = (p | H) - (y4 & ~H);
    return ((p & ~y4) | (~(p ^ y4) & d)) & H;
}

// The bytes of `p` in a state of form `form` (see FREE_FORM), as bits 7, 15, 23, 31.
fn in_state(p: u32, form: u32, lo4: u32, span4: u32) -> u32 {
    if form == 1u {
        return bytes_at_least(p, lo4);
    }
    if form == 2u {
        return bytes_at_least(p, lo4) ^ H;
    }
    return in_interval(p, lo4, span4);
}

// Bits 7, 15, 23, 31 of `m` gathered to bits 0..3 by one multiply (the partial products never overlap).
fn pack4(m: u32) -> u32 {
    return (m * 0x00204081u) >> 28u;
}

// Word k of a run (pixels 4k..4k + 3) added to the run's free (x) and blocking (y) planes.
fn add_word(acc: vec2<u32>, p: u32, k: u32) -> vec2<u32> {
    if TABLE {
        var f = 0u;
        var b = 0u;
        for (var i = 0u; i < 4u; i++) {
            let c = wg_class[(p >> (8u * i)) & 0xffu];
            f |= (c & 1u) << i;
            b |= ((c >> 1u) & 1u) << i;
        }
        return acc | vec2<u32>(f << (4u * k), b << (4u * k));
    }
    let f = pack4(in_state(p, FREE_FORM, params.free_lo, params.free_span));
    let b = pack4(in_state(p, BLK_FORM, params.blk_lo, params.blk_span));
    return acc | vec2<u32>(f << (4u * k), b << (4u * k));
}

// Whether the pixel of value `v` (one byte) is blocking.
fn blocking(v: u32) -> u32 {
    if TABLE {
        return (wg_class[v] >> 1u) & 1u;
    }
    let lo = params.blk_lo & 0xffu;
    if BLK_FORM == 1u {
        return u32(v >= lo);
    }
    if BLK_FORM == 2u {
        return u32(v < lo);
    }
    return u32(((v - lo) & 0xffu) <= (params.blk_span & 0xffu));
}

// A row's run as loaded, before classification: its eight words, the bytes just left and right of it, and
// which of those exist (bit 0: the run, 1: left, 2: right).
struct Raw {
    p: array<u32, 8>,
    left: u32,
    right: u32,
    has: u32,
}

fn fetch(lane: u32, y: i32) -> Raw {
    var r: Raw;
    if y < 0 || u32(y) >= params.buf_h || lane >= params.lanes_x {
        return r;
    }
    let at = params.first_byte + u32(y) * params.row_bytes + lane * 32u;
    r.p = run_at(at);
    r.has = 1u;
    if lane > 0u {
        r.left = byte_at(at - 1u);
        r.has |= 2u;
    }
    if lane * 32u + 32u < params.buf_w {
        r.right = byte_at(at + 32u);
        r.has |= 4u;
    }
    return r;
}

// The planes of a loaded run: free and blocking bits, and the blocking bits of the pixels just left and
// right of it (0 outside the buffer: outside the tile's buffer is outside the map).
fn classify(raw: Raw) -> Row {
    var r = Row(0u, 0u, 0u, 0u);
    if raw.has == 0u {
        return r;
    }
    var acc = vec2<u32>(0u);
    acc = add_word(acc, raw.p[0], 0u);
    acc = add_word(acc, raw.p[1], 1u);
    acc = add_word(acc, raw.p[2], 2u);
    acc = add_word(acc, raw.p[3], 3u);
    acc = add_word(acc, raw.p[4], 4u);
    acc = add_word(acc, raw.p[5], 5u);
    acc = add_word(acc, raw.p[6], 6u);
    acc = add_word(acc, raw.p[7], 7u);
    r.free = acc.x;
    r.blk = acc.y;
    // Padding past the row's end is neither free nor blocking (the run's lane is its bits' owner).
    if (raw.has & 4u) == 0u {
        let valid = params.buf_w - (params.buf_w - 1u) / 32u * 32u;
        if valid < 32u {
            let m = (1u << valid) - 1u;
            r.free &= m;
            r.blk &= m;
        }
    }
    if (raw.has & 2u) != 0u {
        r.left = blocking(raw.left);
    }
    if (raw.has & 4u) != 0u {
        r.right = blocking(raw.right);
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
    for (var r = 0u; r < MAX_STRIP; r++) {
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
    let y0 = params.core_y0 + wg.y * params.strip;
    var up = classify(fetch(lane, i32(y0) - 1));
    var mid = classify(fetch(lane, i32(y0)));
    var ahead = fetch(lane, i32(y0) + 1);
    for (var r = 0u; r < params.strip; r++) {
        let y = y0 + r;
        if y >= params.core_y1 {
            break;
        }
        // The row two below, loaded while this one is worked on (the last row of the strip needs none).
        var next: Raw;
        if r + 1u < params.strip {
            next = fetch(lane, i32(y) + 2);
        }
        let down = classify(ahead);
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
        ahead = next;
    }

    workgroupBarrier();
    if li == 0u {
        wg_total = atomicLoad(&wg_fill);
    }
    let total = workgroupUniformLoad(&wg_total);
    var rows = 0u;
    if y0 < params.core_y1 {
        rows = min(params.strip, params.core_y1 - y0);
    }
    let row0 = wg.y * params.strip; // first core row of the strip, counted from core_y0
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
        if li + 1u < MAX_STRIP {
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
    let y0 = params.core_y0 + wg.y * params.strip;
    if y0 >= params.core_y1 {
        return;
    }
    let rows = min(params.strip, params.core_y1 - y0);
    let row0 = wg.y * params.strip;
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
