// Harris response kd (AC - B^2) - kn (A + C)^2 in exact 64-bit integers. CPU twin: src/cpu/harris.rs.
// One invocation per core pixel.

@group(0) @binding(0) var<uniform> bp: BParams;
@group(0) @binding(1) var<storage, read> tensor: array<vec4<i32>>;
@group(0) @binding(2) var<storage, read_write> scores: array<vec2<u32>>;

@compute @workgroup_size(256)
fn harris(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = item_index(wg, li);
    if i >= bp.n_items {
        return;
    }
    let t = tensor[buf_index(i32(bp.core_x0 + i % bp.core_w), i32(bp.core_y0 + i / bp.core_w))];
    let det = i64_sub(i64_mul(t.x, t.z), i64_mul(t.y, t.y));
    let tr = t.x + t.z;
    scores[i] = i64_words(i64_sub(i64_scale(det, bp.kd), i64_scale(i64_mul(tr, tr), bp.kn)));
}
