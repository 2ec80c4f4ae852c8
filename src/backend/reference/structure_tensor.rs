//! CPU twin of `shaders/structure_tensor.wgsl`: 3x3 Sobel gradients of the blurred image and their
//! products summed over a 3x3 window, as OpenCV's cornerHarris / cornerMinEigenVal compute them, but in exact
//! integers (OpenCV's float values are these times a constant scale).

use super::gaussian_blur::reflect101;

/// Sobel (dx, dy) at (x, y) of a `w` x `h` 8-bit image, borders reflected (BORDER_REFLECT_101).
#[inline]
pub fn sobel(img: &[u8], w: i64, h: i64, x: i64, y: i64) -> (i32, i32) {
    let p = |dx: i64, dy: i64| {
        let xx = reflect101(x + dx, w);
        let yy = reflect101(y + dy, h);
        i32::from(img[(yy * w + xx) as usize])
    };
    let gx = (p(1, -1) - p(-1, -1)) + 2 * (p(1, 0) - p(-1, 0)) + (p(1, 1) - p(-1, 1));
    let gy = (p(-1, 1) - p(-1, -1)) + 2 * (p(0, 1) - p(0, -1)) + (p(1, 1) - p(1, -1));
    (gx, gy)
}

/// Per pixel [A, B, C] = the 3x3 window sums of dx*dx, dx*dy, dy*dy, the window's border reflected.
/// |dx|, |dy| <= 1020, so A, C < 2^24 and every value fits an i32. (The GPU kernel recomputes the nine
/// gradients of each window; here they are computed once per pixel first. The sums are the same.)
pub fn structure_tensor(blurred: &[u8], width: u32, height: u32) -> Vec<[i32; 3]> {
    let (w, h) = (i64::from(width), i64::from(height));
    let mut products = Vec::with_capacity(blurred.len());
    for y in 0..h {
        for x in 0..w {
            let (gx, gy) = sobel(blurred, w, h, x, y);
            products.push([gx * gx, gx * gy, gy * gy]);
        }
    }
    let mut out = Vec::with_capacity(blurred.len());
    for y in 0..h {
        for x in 0..w {
            let mut t = [0i32; 3];
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = products[(reflect101(y + dy, h) * w + reflect101(x + dx, w)) as usize];
                    t[0] += q[0];
                    t[1] += q[1];
                    t[2] += q[2];
                }
            }
            out.push(t);
        }
    }
    out
}
