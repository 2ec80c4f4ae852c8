// Shi-Tomasi score S - ceil(sqrt(D)), S = A + C, D = (A - C)^2 + 4 B^2, exact. CPU twin:
// src/cpu/shi_tomasi.rs. A float square root guesses; exact 64-bit comparisons correct the guess.

@group(0) @binding(0) var<uniform> bp: BParams;
@group(0) @binding(1) var<storage, read> tensor: array<vec4<i32>>;
@group(0) @binding(2) var<storage, read_write> scores: array<vec2<u32>>;

@compute @workgroup_size(256)
fn shi_tomasi(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = item_index(wg, li);
    if i >= bp.n_items {
        return;
    }
    let t = tensor[buf_index(i32(bp.core_x0 + i % bp.core_w), i32(bp.core_y0 + i / bp.core_w))];
    let d = i64_add(i64_mul(t.x - t.z, t.x - t.z), i64_scale(i64_mul(t.y, t.y), 4u));
    var r = i32(ceil(sqrt(max(i64_to_f32(d), 0.0))));
    // D < 2^51, so the guess is within a few units; the bounds only guard against a broken sqrt.
    for (var k = 0; k < 64; k++) {
        if r > 0 && !i64_lt(i64_mul(r - 1, r - 1), d) {
            r -= 1;
        } else {
            break;
        }
    }
    for (var k = 0; k < 64; k++) {
        if i64_lt(i64_mul(r, r), d) {
            r += 1;
        } else {
            break;
        }
    }
    scores[i] = i64_words(i64_from_i32(t.x + t.z - r));
}
