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

    pub(in crate::merge) fn run(&self, data: &mut [Complex32]) {
        let n = self.n;
        self.fft.process(data);
        transpose(data, n);
        self.fft.process(data);
        transpose(data, n);
    }
}

fn transpose(d: &mut [Complex32], n: usize) {
    for i in 0..n {
        for j in i + 1..n {
            d.swap(i * n + j, j * n + i);
        }
    }
}

/// A `w` x `h` mask at the top-left of an `n` x `n` complex array.
pub(in crate::merge) fn padded(m: &[f32], w: usize, h: usize, n: usize) -> Vec<Complex32> {
    let mut out = vec![Complex32::new(0.0, 0.0); n * n];
    for y in 0..h {
        for x in 0..w {
            out[y * n + x].re = m[y * w + x];
        }
    }
    out
}
