//! CPU twin of `shaders/harris.wgsl`: the Harris response in exact integers.
//!
//! With k = kn / kd, OpenCV's response det(M) - k tr(M)^2 equals (kd (AC - B^2) - kn (A + C)^2) / kd times a
//! positive constant, so this integer orders and thresholds pixels exactly as the real-valued response does.
//! It needs 64 bits: AC reaches 2^48.

/// Harris scores of a structure tensor (see [`super::structure_tensor`]).
pub fn harris(tensor: &[[i32; 3]], kn: u32, kd: u32) -> Vec<i64> {
    tensor
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (i64::from(a), i64::from(b), i64::from(c));
            i64::from(kd) * (a * c - b * b) - i64::from(kn) * (a + c) * (a + c)
        })
        .collect()
}
