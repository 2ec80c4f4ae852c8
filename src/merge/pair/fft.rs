//! The aligner's square 2-D FFTs (rustfft, rows then columns) and zero-padded masks.

use std::sync::Arc;

use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};

/// Largest coarse correlation side (the preparation keeps its coarse levels within it).
pub(in crate::merge) const MAX_FFT: usize = 2048;
/// The finest coarse level whose correlation side is at most this is used (and prepared).
pub const FINE_FFT: usize = 256;

/// A square 2-D FFT (rows, then columns), forward or inverse.
pub(in crate::merge) struct Fft2 {
    n: usize,
    fft: Arc<dyn Fft<f32>>,
}

impl Fft2 {
    pub(in crate::merge) fn new(planner: &mut FftPlanner<f32>, n: usize, inverse: bool) -> Self {
        let fft = if inverse {
            planner.plan_fft_inverse(n)
        } else {
            planner.plan_fft_forward(n)
        };
        Fft2 { n, fft }
    }

    /// Transforms `data` (n x n, row-major) in place; `scratch` (as long, any content) is overwritten.
    /// The transposes go out of place through the cache-blocked `transpose` crate: the in-place swap
    /// they replace cost two to three times the FFTs themselves (a column walk misses the cache on every
    /// element). The same FFTs on the same values: the result is the same to the bit.
    pub(in crate::merge) fn run(&self, data: &mut [Complex32], scratch: &mut [Complex32]) {
        let n = self.n;
        self.fft.process(data);
        transpose::transpose(data, scratch, n, n);
        self.fft.process(scratch);
        transpose::transpose(scratch, data, n, n);
    }
}

/// An n x n buffer of zeros, for [`Fft2::run`]'s scratch or its data.
pub(in crate::merge) fn zeros(n: usize) -> Vec<Complex32> {
    vec![Complex32::new(0.0, 0.0); n * n]
}

/// A `w` x `h` mask at the top-left of an `n` x `n` complex array.
pub(in crate::merge) fn padded(m: &[f32], w: usize, h: usize, n: usize) -> Vec<Complex32> {
    let mut out = zeros(n);
    for y in 0..h {
        for x in 0..w {
            out[y * n + x].re = m[y * w + x];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows then columns, forward, against the 2-D DFT's definition; then back (unnormalised).
    #[test]
    fn the_2d_fft_is_the_dft_and_the_inverse_undoes_it() {
        let n = 16;
        let mut planner = FftPlanner::new();
        let (fwd, inv) = (
            Fft2::new(&mut planner, n, false),
            Fft2::new(&mut planner, n, true),
        );
        let data: Vec<Complex32> = (0..n * n)
            .map(|i| Complex32::new((i * 7 % 13) as f32 - 6.0, (i * 5 % 11) as f32 - 5.0))
            .collect();
        let (mut z, mut scratch) = (data.clone(), vec![Complex32::new(9.0, 9.0); n * n]);
        fwd.run(&mut z, &mut scratch);
        let tau = -2.0 * std::f64::consts::PI / n as f64;
        for (ky, kx) in [(0, 0), (0, 3), (5, 0), (7, 11), (15, 1)] {
            let (mut re, mut im) = (0.0f64, 0.0f64);
            for y in 0..n {
                for x in 0..n {
                    let (s, c) = (tau * (ky * y + kx * x) as f64).sin_cos();
                    let v = data[y * n + x];
                    re += f64::from(v.re) * c - f64::from(v.im) * s;
                    im += f64::from(v.re) * s + f64::from(v.im) * c;
                }
            }
            let got = z[ky * n + kx];
            assert!(
                (f64::from(got.re) - re).abs() < 1e-3,
                "({ky}, {kx}): {got} vs {re}"
            );
            assert!(
                (f64::from(got.im) - im).abs() < 1e-3,
                "({ky}, {kx}): {got} vs {im}"
            );
        }
        inv.run(&mut z, &mut scratch);
        for (a, b) in z.iter().zip(&data) {
            assert!((a / (n * n) as f32 - b).norm() < 1e-4);
        }
    }
}
