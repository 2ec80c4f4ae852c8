// Sobel gradients and their products summed over 3x3, exact integers. CPU twin:
// src/cpu/structure_tensor.rs. One invocation per buffer pixel.

@group(0) @binding(0) var<uniform> bp: BParams;
@group(0) @binding(1) var<storage, read> blurred: array<u32>;
@group(0) @binding(2) var<storage, read_write> tensor: array<vec4<i32>>;

fn px(mx: i32, my: i32) -> i32 {
    return i32(blurred[buf_index(reflect101(mx, i32(bp.map_w)), reflect101(my, i32(bp.map_h)))]);
}

fn sobel(x: i32, y: i32) -> vec2<i32> {
    let gx = (px(x + 1, y - 1) - px(x - 1, y - 1)) + 2 * (px(x + 1, y) - px(x - 1, y))
        + (px(x + 1, y + 1) - px(x - 1, y + 1));
    let gy = (px(x - 1, y + 1) - px(x - 1, y - 1)) + 2 * (px(x, y + 1) - px(x, y - 1))
        + (px(x + 1, y + 1) - px(x + 1, y - 1));
    return vec2<i32>(gx, gy);
}

@compute @workgroup_size(256)
fn structure_tensor(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = item_index(wg, li);
    if i >= bp.n_items {
        return;
    }
    let mx = i32(bp.origin_x + i % bp.buf_w);
    let my = i32(bp.origin_y + i / bp.buf_w);
    var t = vec4<i32>(0, 0, 0, 0);
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let g = sobel(reflect101(mx + dx, i32(bp.map_w)), reflect101(my + dy, i32(bp.map_h)));
            t += vec4<i32>(g.x * g.x, g.x * g.y, g.y * g.y, 0);
        }
    }
    tensor[i] = t;
}
