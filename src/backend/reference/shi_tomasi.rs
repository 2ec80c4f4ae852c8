//! CPU twin of `shaders/shi_tomasi.wgsl`: the minimum eigenvalue of the structure tensor, exactly.
//!
//! OpenCV's cornerMinEigenVal is (A + C)/2 - sqrt(((A - C)/2)^2 + B^2) times a constant, that is half of
//! S - sqrt(D) with S = A + C and D = (A - C)^2 + 4B^2 in integers. The score is floor(S - sqrt(D)) =
//! S - ceil(sqrt(D)): an integer square root, exact on any hardware, so the CPU and GPU agree by
//! construction. It is never negative (S^2 - D = 4(AC - B^2) >= 0).

/// ceil(sqrt(d)) for d >= 0, exactly.
pub fn ceil_sqrt(d: i64) -> i64 {
    let mut r = (d as f64).sqrt().ceil() as i64;
    while r > 0 && (r - 1) * (r - 1) >= d {
        r -= 1;
    }
    while r * r < d {
        r += 1;
    }
    r
}

/// Shi-Tomasi scores of a structure tensor (see [`super::structure_tensor`]).
pub fn shi_tomasi(tensor: &[[i32; 3]]) -> Vec<i64> {
    tensor
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (i64::from(a), i64::from(b), i64::from(c));
            let d = (a - c) * (a - c) + 4 * b * b;
            a + c - ceil_sqrt(d)
        })
        .collect()
}
