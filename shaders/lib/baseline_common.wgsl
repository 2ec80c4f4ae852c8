// Shared by the baseline kernels: parameters, border reflection and tile addressing. A tile's buffer holds
// the map pixels [origin, origin + buf) (its core plus a halo wherever the map extends); borders reflect in
// map coordinates (OpenCV's BORDER_REFLECT_101), so a tile computes exactly what the whole map would.

struct BParams {
    map_w: u32,
    map_h: u32,
    origin_x: u32,
    origin_y: u32,
    buf_w: u32,
    buf_h: u32,
    stride: u32, // words per row of the packed raw pixels
    core_x0: u32,
    core_y0: u32,
    core_w: u32,
    core_h: u32,
    k_side: u32, // Gaussian kernel [side, centre, side], sum 256
    k_centre: u32,
    kn: u32, // Harris k = kn / kd
    kd: u32,
    t1: u32, // Trajkovic thresholds
    t2: u32,
    groups_x: u32,
    n_items: u32,
    _pad: u32,
}

fn reflect101(i: i32, n: i32) -> i32 {
    if n == 1 {
        return 0;
    }
    if i < 0 {
        return -i;
    }
    if i >= n {
        return 2 * n - 2 - i;
    }
    return i;
}

// Buffer index of map pixel (mx, my); clamped into the buffer (a clamped value only ever feeds halo
// results that no core pixel reads).
fn buf_index(mx: i32, my: i32) -> u32 {
    let bx = clamp(mx - i32(bp.origin_x), 0, i32(bp.buf_w) - 1);
    let by = clamp(my - i32(bp.origin_y), 0, i32(bp.buf_h) - 1);
    return u32(by) * bp.buf_w + u32(bx);
}

fn item_index(wg: vec3<u32>, li: u32) -> u32 {
    return (wg.y * bp.groups_x + wg.x) * 256u + li;
}
