// Signed 64-bit integers on adapters with SHADER_INT64. Same functions as int64_emulated.wgsl; the host
// prepends one or the other.

alias I64 = i64;

fn i64_from_i32(a: i32) -> I64 {
    return i64(a);
}

fn i64_mul(a: i32, b: i32) -> I64 {
    return i64(a) * i64(b);
}

fn i64_add(a: I64, b: I64) -> I64 {
    return a + b;
}

fn i64_sub(a: I64, b: I64) -> I64 {
    return a - b;
}

fn i64_scale(a: I64, k: u32) -> I64 {
    return a * i64(k);
}

fn i64_lt(a: I64, b: I64) -> bool {
    return a < b;
}

fn i64_to_f32(a: I64) -> f32 {
    return f32(a);
}

fn i64_words(a: I64) -> vec2<u32> {
    return vec2<u32>(u32(a & 0xffffffffli), u32((a >> 32u) & 0xffffffffli));
}
