// Trajkovic-Hedley 4-neighbour score: low-resolution candidates (T1), full-resolution measure with the
// interpixel approximation (T2), exact integers. CPU twin: src/cpu/trajkovic.rs (which documents the
// definition). One invocation per core pixel.

@group(0) @binding(0) var<uniform> bp: BParams;
@group(0) @binding(1) var<storage, read> raw: array<u32>;
@group(0) @binding(2) var<storage, read_write> scores: array<vec2<u32>>;

fn f(mx: i32, my: i32) -> i32 {
    let bx = u32(clamp(mx - i32(bp.origin_x), 0, i32(bp.buf_w) - 1));
    let by = u32(clamp(my - i32(bp.origin_y), 0, i32(bp.buf_h) - 1));
    return i32((raw[by * bp.stride + (bx >> 2u)] >> ((bx & 3u) * 8u)) & 0xffu);
}

fn low_res(u: i32, v: i32) -> i32 {
    let w = i32(bp.map_w) - 1;
    let h = i32(bp.map_h) - 1;
    let x0 = min(2 * u, w);
    let x1 = min(2 * u + 1, w);
    let y0 = min(2 * v, h);
    let y1 = min(2 * v + 1, h);
    return (f(x0, y0) + f(x1, y0) + f(x0, y1) + f(x1, y1)) / 4;
}

fn low_res_cornerness(u: i32, v: i32) -> i32 {
    let c = low_res(u, v);
    let ra = (low_res(u + 1, v) - c) * (low_res(u + 1, v) - c) + (low_res(u - 1, v) - c) * (low_res(u - 1, v) - c);
    let rb = (low_res(u, v - 1) - c) * (low_res(u, v - 1) - c) + (low_res(u, v + 1) - c) * (low_res(u, v + 1) - c);
    return min(ra, rb);
}

fn is_candidate(x: i32, y: i32) -> bool {
    let lw = (i32(bp.map_w) + 1) / 2;
    let lh = (i32(bp.map_h) + 1) / 2;
    // Low-resolution pixels whose 2x2 block plus a one-pixel ring holds (x, y), off the low-res border.
    let v0 = max((y - 1) >> 1u, 1);
    let v1 = min((y + 1) >> 1u, lh - 2);
    let u0 = max((x - 1) >> 1u, 1);
    let u1 = min((x + 1) >> 1u, lw - 2);
    for (var v = v0; v <= v1; v++) {
        for (var u = u0; u <= u1; u++) {
            if low_res_cornerness(u, v) > i32(bp.t1) {
                return true;
            }
        }
    }
    return false;
}

fn full_res_score(x: i32, y: i32) -> i32 {
    let c = f(x, y);
    let a = f(x + 1, y);
    let a2 = f(x - 1, y);
    let b = f(x, y - 1);
    let b2 = f(x, y + 1);
    let ra = (a - c) * (a - c) + (a2 - c) * (a2 - c);
    let rb = (b - c) * (b - c) + (b2 - c) * (b2 - c);
    let t2 = i32(bp.t2);
    if min(ra, rb) <= t2 {
        return 0;
    }
    let bm = min((b - a) * (a - c) + (b2 - a2) * (a2 - c), (b - a2) * (a2 - c) + (b2 - a) * (a - c));
    let am = rb - ra - 2 * bm;
    var r = min(ra, rb);
    if bm < 0 && am + bm > 0 {
        // ceil(B^2 / A), B^2 up to 2^35: a float guess corrected by exact 64-bit comparisons.
        let bb = i64_mul(bm, bm);
        var q = i32(ceil(f32(bm) * f32(bm) / f32(am)));
        for (var k = 0; k < 64; k++) {
            if q > 0 && !i64_lt(i64_mul(q - 1, am), bb) {
                q -= 1;
            } else {
                break;
            }
        }
        for (var k = 0; k < 64; k++) {
            if i64_lt(i64_mul(q, am), bb) {
                q += 1;
            } else {
                break;
            }
        }
        r = ra - q;
    }
    return select(0, r, r > t2);
}

@compute @workgroup_size(256)
fn trajkovic(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = item_index(wg, li);
    if i >= bp.n_items {
        return;
    }
    let x = i32(bp.core_x0 + i % bp.core_w);
    let y = i32(bp.core_y0 + i / bp.core_w);
    var s = 0;
    if x >= 1 && y >= 1 && x < i32(bp.map_w) - 1 && y < i32(bp.map_h) - 1 && is_candidate(x, y) {
        s = full_res_score(x, y);
    }
    scores[i] = vec2<u32>(bitcast<u32>(s), select(0u, 0xffffffffu, s < 0));
}
