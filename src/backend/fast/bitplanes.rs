//! Classification into bit-planes: one bit per pixel, 64 pixels a word, bit `i` of word `k` is pixel
//! `64 k + i`. The fast twin of [`crate::backend::reference::classify`]: a plane holds the pixels whose state is in a set.
//!
//! The ROS thresholds make each state's set of pixel values an interval (the occupancy probability is
//! monotonic in the value), so a plane is two SIMD compares per 16 pixels; any other set falls back to the
//! 256-entry table, pixel by pixel.

use super::simd::Isa;
use crate::map::states::{CellState, ClassTable};

/// Which pixel values set a plane's bit, derived once from a [`ClassTable`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ValueSet {
    /// No value.
    Empty,
    /// The values `lo..=lo + span`.
    Interval {
        /// Smallest value in the set.
        lo: u8,
        /// Largest value minus smallest.
        span: u8,
    },
    /// Any other set, by value.
    Table(Box<[bool; 256]>),
}

impl ValueSet {
    /// The set of values whose state is in `states`, in its cheapest form.
    pub fn of(classes: &ClassTable, states: &[CellState]) -> Self {
        let member: Vec<bool> = (0..=255u8)
            .map(|v| states.contains(&classes.state(v)))
            .collect();
        Self::from_members(&member)
    }

    /// The set given by membership of each of the 256 values (its cheapest form).
    pub fn from_members(member: &[bool]) -> Self {
        assert_eq!(member.len(), 256, "one flag per byte value");
        let first = member.iter().position(|&m| m);
        let last = member.iter().rposition(|&m| m);
        match (first, last) {
            (Some(lo), Some(hi)) if member[lo..=hi].iter().all(|&m| m) => ValueSet::Interval {
                lo: lo as u8,
                span: (hi - lo) as u8,
            },
            (Some(_), _) => {
                let mut t = Box::new([false; 256]);
                t.copy_from_slice(member);
                ValueSet::Table(t)
            }
            _ => ValueSet::Empty,
        }
    }

    /// Whether `v` is in the set.
    #[inline]
    pub fn contains(&self, v: u8) -> bool {
        match self {
            ValueSet::Empty => false,
            ValueSet::Interval { lo, span } => v.wrapping_sub(*lo) <= *span,
            ValueSet::Table(t) => t[v as usize],
        }
    }
}

/// The OGM detector's two planes' value sets: free pixels, and pixels that set their bit in a neighbour
/// code (occupied, and unknown too with `unknown_as_occupied`). Shared by the fast CPU path and the GPU
/// kernel's parameters.
pub fn ogm_sets(classes: &ClassTable, unknown_as_occupied: bool) -> (ValueSet, ValueSet) {
    let blocking: &[CellState] = if unknown_as_occupied {
        &[CellState::Occupied, CellState::Unknown]
    } else {
        &[CellState::Occupied]
    };
    (
        ValueSet::of(classes, &[CellState::Free]),
        ValueSet::of(classes, blocking),
    )
}

/// Words needed for a row of `width` pixels.
#[inline]
pub fn words(width: usize) -> usize {
    width.div_ceil(64)
}

/// Sets `out` (at least [`words`]`(row.len())` long) to the plane of `set` over `row`; bits past the row's
/// end are zero.
pub fn plane_row(set: &ValueSet, row: &[u8], out: &mut [u64]) {
    let n = words(row.len());
    let out = &mut out[..n];
    match set {
        ValueSet::Empty => out.fill(0),
        ValueSet::Interval { lo, span } => interval_row(*lo, *span, row, out),
        ValueSet::Table(t) => {
            for (word, chunk) in out.iter_mut().zip(row.chunks(64)) {
                *word = chunk
                    .iter()
                    .enumerate()
                    .fold(0u64, |w, (i, &v)| w | (u64::from(t[v as usize]) << i));
            }
        }
    }
}

/// [`plane_row`] of two sets over one row, on the active instruction set ([`plane_rows2_on`]).
pub fn plane_rows2(a: &ValueSet, b: &ValueSet, row: &[u8], out_a: &mut [u64], out_b: &mut [u64]) {
    plane_rows2_on(Isa::active(), a, b, row, out_a, out_b)
}

/// [`plane_row`] of two sets over one row with the instruction set `isa` (which the CPU must run: the
/// caller checked [`Isa::supported`]): with two intervals, both planes from one pass over the row's bytes.
pub fn plane_rows2_on(
    isa: Isa,
    a: &ValueSet,
    b: &ValueSet,
    row: &[u8],
    out_a: &mut [u64],
    out_b: &mut [u64],
) {
    #[cfg(target_arch = "x86_64")]
    if let (ValueSet::Interval { lo: la, span: sa }, ValueSet::Interval { lo: lb, span: sb }) =
        (a, b)
    {
        let (n, full) = (words(row.len()), row.len() / 64);
        type Words2 = unsafe fn((u8, u8), (u8, u8), &[u8], &mut [u64], &mut [u64]);
        let kernel: Option<Words2> = match isa {
            Isa::Avx512 => Some(avx512::interval_words2),
            Isa::Avx2 => Some(avx2::interval_words2),
            Isa::Scalar => None,
        };
        let done = kernel.is_some();
        if let Some(kernel) = kernel {
            debug_assert!(isa.supported());
            // SAFETY: the caller checked that the CPU runs `isa`, all the kernel needs.
            unsafe {
                kernel(
                    (*la, *sa),
                    (*lb, *sb),
                    row,
                    &mut out_a[..full],
                    &mut out_b[..full],
                )
            };
        }
        if done {
            if full < n {
                out_a[full] = interval_scalar(*la, *sa, &row[full * 64..]);
                out_b[full] = interval_scalar(*lb, *sb, &row[full * 64..]);
            }
            return;
        }
    }
    let _ = isa;
    plane_row_portable(a, row, out_a);
    plane_row_portable(b, row, out_b);
}

/// [`plane_row`] without AVX2: SSE2 compares on x86-64 (every x86-64 CPU has them), plain Rust elsewhere.
pub fn plane_row_portable(set: &ValueSet, row: &[u8], out: &mut [u64]) {
    let n = words(row.len());
    match *set {
        ValueSet::Interval { lo, span } => interval_row_portable(lo, span, row, &mut out[..n]),
        _ => plane_row(set, row, out),
    }
}

/// The plane of `lo..=lo+span` over a row: AVX2 where the CPU has it, else [`interval_row_portable`].
fn interval_row(lo: u8, span: u8, row: &[u8], out: &mut [u64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        let full = row.len() / 64;
        // SAFETY: the CPU has AVX2, checked just above.
        unsafe { avx2::interval_words(lo, span, row, &mut out[..full]) };
        if full < out.len() {
            out[full] = interval_scalar(lo, span, &row[full * 64..]);
        }
        return;
    }
    interval_row_portable(lo, span, row, out)
}

/// The plane of `lo..=lo+span` over a row (`out` one word per 64 pixels): SSE2 on x86-64, plain Rust
/// elsewhere and for the tail.
fn interval_row_portable(lo: u8, span: u8, row: &[u8], out: &mut [u64]) {
    let full = row.len() / 64;
    for (word, chunk) in out[..full].iter_mut().zip(row.chunks_exact(64)) {
        #[cfg(target_arch = "x86_64")]
        {
            *word = sse2::interval64(lo, span, chunk.try_into().expect("64 bytes"));
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            *word = interval_scalar(lo, span, chunk);
        }
    }
    if full < out.len() {
        out[full] = interval_scalar(lo, span, &row[full * 64..]);
    }
}

/// The portable form: one bit per byte of `chunk` (at most 64 bytes).
#[inline]
pub fn interval_scalar(lo: u8, span: u8, chunk: &[u8]) -> u64 {
    chunk.iter().enumerate().fold(0u64, |w, (i, &v)| {
        w | (u64::from(v.wrapping_sub(lo) <= span) << i)
    })
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    /// The bits of the 32 bytes at `p` in the interval (`lo`, `span` broadcast), as
    /// [`super::sse2::interval64`] computes them.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `p` must point at 32 readable bytes.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn bits32(p: *const u8, lo: __m256i, span: __m256i) -> u64 {
        // SAFETY: 32 readable bytes at `p` (the caller's promise); an unaligned load.
        let v = unsafe { _mm256_loadu_si256(p as *const __m256i) };
        let t = _mm256_sub_epi8(v, lo);
        let m = _mm256_cmpeq_epi8(_mm256_min_epu8(t, span), t);
        u64::from(_mm256_movemask_epi8(m) as u32)
    }

    /// The whole 64-pixel words of `row` in the interval `lo..=lo + span` (`out` has one per word).
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub unsafe fn interval_words(lo: u8, span: u8, row: &[u8], out: &mut [u64]) {
        let (lo, span) = (_mm256_set1_epi8(lo as i8), _mm256_set1_epi8(span as i8));
        for (word, chunk) in out.iter_mut().zip(row.chunks_exact(64)) {
            let p = chunk.as_ptr();
            // SAFETY: AVX2 (this function's requirement); 32 bytes at 0 and 32 inside the 64-byte chunk.
            *word = unsafe { bits32(p, lo, span) | (bits32(p.add(32), lo, span) << 32) };
        }
    }

    /// [`interval_words`] of two intervals from one pass over `row`.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub unsafe fn interval_words2(
        (la, sa): (u8, u8),
        (lb, sb): (u8, u8),
        row: &[u8],
        out_a: &mut [u64],
        out_b: &mut [u64],
    ) {
        let (la, sa) = (_mm256_set1_epi8(la as i8), _mm256_set1_epi8(sa as i8));
        let (lb, sb) = (_mm256_set1_epi8(lb as i8), _mm256_set1_epi8(sb as i8));
        for ((wa, wb), chunk) in out_a
            .iter_mut()
            .zip(out_b.iter_mut())
            .zip(row.chunks_exact(64))
        {
            let p = chunk.as_ptr();
            // SAFETY: AVX2 (this function's requirement); 32 bytes at 0 and 32 inside the 64-byte chunk.
            // The second interval's loads hit the cache line the first just read.
            unsafe {
                *wa = bits32(p, la, sa) | (bits32(p.add(32), la, sa) << 32);
                *wb = bits32(p, lb, sb) | (bits32(p.add(32), lb, sb) << 32);
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use std::arch::x86_64::*;

    /// Two intervals' planes over the whole 64-pixel words of `row`: one 64-byte load a word, each
    /// interval a subtract and an unsigned compare straight into a 64-bit mask (the word itself).
    ///
    /// # Safety
    /// The CPU must have AVX-512 F and BW.
    #[target_feature(enable = "avx512f,avx512bw")]
    pub unsafe fn interval_words2(
        (la, sa): (u8, u8),
        (lb, sb): (u8, u8),
        row: &[u8],
        out_a: &mut [u64],
        out_b: &mut [u64],
    ) {
        let (la, sa) = (_mm512_set1_epi8(la as i8), _mm512_set1_epi8(sa as i8));
        let (lb, sb) = (_mm512_set1_epi8(lb as i8), _mm512_set1_epi8(sb as i8));
        for ((wa, wb), chunk) in out_a
            .iter_mut()
            .zip(out_b.iter_mut())
            .zip(row.chunks_exact(64))
        {
            // SAFETY: AVX-512 F and BW (this function's requirement); 64 readable bytes in `chunk`.
            let v = unsafe { _mm512_loadu_si512(chunk.as_ptr() as *const _) };
            *wa = _mm512_cmple_epu8_mask(_mm512_sub_epi8(v, la), sa);
            *wb = _mm512_cmple_epu8_mask(_mm512_sub_epi8(v, lb), sb);
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod sse2 {
    use std::arch::x86_64::*;

    /// 64 membership bits by unsigned range compare: (v - lo) <= span  <=>  min(v - lo, span) == v - lo.
    #[inline]
    pub fn interval64(lo: u8, span: u8, chunk: &[u8; 64]) -> u64 {
        // SAFETY: SSE2 is part of the x86-64 baseline; the loads are unaligned loads inside `chunk`.
        unsafe {
            let lo = _mm_set1_epi8(lo as i8);
            let span = _mm_set1_epi8(span as i8);
            let mut bits = 0u64;
            for q in 0..4 {
                let v = _mm_loadu_si128(chunk.as_ptr().add(16 * q) as *const __m128i);
                let t = _mm_sub_epi8(v, lo);
                let m = _mm_cmpeq_epi8(_mm_min_epu8(t, span), t);
                bits |= u64::from(_mm_movemask_epi8(m) as u16) << (16 * q);
            }
            bits
        }
    }
}
