//! CPU twin of `shaders/gaussian_blur.wgsl`: OpenCV's bit-exact 3x3 Gaussian blur of an 8-bit image.
//!
//! OpenCV blurs 8-bit images in fixed point: the 1-D kernel is rounded to 8 fractional bits (sum 256), the
//! 3x3 sum is exact, and the result is rounded once: `(sum + 2^15) >> 16`. Borders reflect without repeating
//! the edge pixel (BORDER_REFLECT_101).

use crate::map::MapImage;

/// OpenCV's BORDER_REFLECT_101 for an index at most `n - 1` outside [0, n).
#[inline]
pub fn reflect101(i: i64, n: i64) -> i64 {
    if n == 1 {
        0
    } else if i < 0 {
        -i
    } else if i >= n {
        2 * n - 2 - i
    } else {
        i
    }
}

/// The fixed-point kernel [side, centre, side] (sum 256) for `sigma`, as OpenCV rounds it.
pub fn gaussian_kernel(sigma: f64) -> [u32; 3] {
    let side = (-1.0 / (2.0 * sigma * sigma)).exp();
    let side = (256.0 * side / (1.0 + 2.0 * side)).round() as u32;
    [side, 256 - 2 * side, side]
}

/// The blurred image, row-major.
pub fn gaussian_blur(image: &MapImage, kernel: [u32; 3]) -> Vec<u8> {
    let (w, h) = (i64::from(image.width()), i64::from(image.height()));
    let mut out = Vec::with_capacity(image.len());
    for y in 0..h {
        for x in 0..w {
            let mut sum = 0u32;
            for (j, kj) in kernel.iter().enumerate() {
                let yy = reflect101(y + j as i64 - 1, h) as u32;
                for (i, ki) in kernel.iter().enumerate() {
                    let xx = reflect101(x + i as i64 - 1, w) as u32;
                    sum += kj * ki * u32::from(image.get(xx, yy));
                }
            }
            out.push(((sum + (1 << 15)) >> 16) as u8);
        }
    }
    out
}
