// 3x3 Gaussian blur of the 8-bit map, OpenCV's bit-exact fixed point. CPU twin: src/cpu/gaussian_blur.rs.
// One invocation per buffer pixel.

@group(0) @binding(0) var<uniform> bp: BParams;
@group(0) @binding(1) var<storage, read> raw: array<u32>; // four pixels a word, rows of `stride` words
@group(0) @binding(2) var<storage, read_write> blurred: array<u32>;

fn raw_at(mx: i32, my: i32) -> u32 {
    let bx = u32(clamp(mx - i32(bp.origin_x), 0, i32(bp.buf_w) - 1));
    let by = u32(clamp(my - i32(bp.origin_y), 0, i32(bp.buf_h) - 1));
    return (raw[by * bp.stride + (bx >> 2u)] >> ((bx & 3u) * 8u)) & 0xffu;
}

@compute @workgroup_size(256)
fn gaussian_blur(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = item_index(wg, li);
    if i >= bp.n_items {
        return;
    }
    let mx = i32(bp.origin_x + i % bp.buf_w);
    let my = i32(bp.origin_y + i / bp.buf_w);
    let k = array<u32, 3>(bp.k_side, bp.k_centre, bp.k_side);
    var sum = 0u;
    for (var j = 0; j < 3; j++) {
        let yy = reflect101(my + j - 1, i32(bp.map_h));
        for (var m = 0; m < 3; m++) {
            let xx = reflect101(mx + m - 1, i32(bp.map_w));
            sum += k[j] * k[m] * raw_at(xx, yy);
        }
    }
    blurred[i] = (sum + 32768u) >> 16u;
}
