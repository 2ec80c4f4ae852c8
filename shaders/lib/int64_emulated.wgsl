// Exact signed 64-bit integers as two u32 words (low, high), two's complement, for adapters without
// SHADER_INT64. Same functions as int64_native.wgsl; the host prepends one or the other.

alias I64 = vec2<u32>;

// The full 64-bit product of two u32, from 16-bit halves (no partial product overflows).
fn mul_u32_wide(a: u32, b: u32) -> vec2<u32> {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let p11 = a1 * b1;
    let mid = (p00 >> 16u) + (p01 & 0xffffu) + (p10 & 0xffffu);
    return vec2<u32>((p00 & 0xffffu) | (mid << 16u), p11 + (p01 >> 16u) + (p10 >> 16u) + (mid >> 16u));
}

fn i64_neg(a: I64) -> I64 {
    let lo = ~a.x + 1u;
    return I64(lo, ~a.y + select(0u, 1u, lo == 0u));
}

fn i64_from_i32(a: i32) -> I64 {
    return I64(bitcast<u32>(a), select(0u, 0xffffffffu, a < 0));
}

// a * b for |a|, |b| < 2^31.
fn i64_mul(a: i32, b: i32) -> I64 {
    let p = mul_u32_wide(u32(abs(a)), u32(abs(b)));
    return select(p, i64_neg(p), (a < 0) != (b < 0));
}

fn i64_add(a: I64, b: I64) -> I64 {
    let lo = a.x + b.x;
    return I64(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

fn i64_sub(a: I64, b: I64) -> I64 {
    return i64_add(a, i64_neg(b));
}

// a * k, modulo 2^64 (exact while the result fits).
fn i64_scale(a: I64, k: u32) -> I64 {
    let p = mul_u32_wide(a.x, k);
    return I64(p.x, p.y + a.y * k);
}

fn i64_lt(a: I64, b: I64) -> bool {
    let ah = bitcast<i32>(a.y);
    let bh = bitcast<i32>(b.y);
    return ah < bh || (ah == bh && a.x < b.x);
}

// An approximation, for first guesses that exact integer steps then correct.
fn i64_to_f32(a: I64) -> f32 {
    return f32(bitcast<i32>(a.y)) * 4294967296.0 + f32(a.x);
}

fn i64_words(a: I64) -> vec2<u32> {
    return a;
}
