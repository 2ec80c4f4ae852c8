//! The plain streaming read that `bench --bandwidth` measures the detectors against: every byte of a
//! buffer loaded once, in the widest vectors the CPU has, on every core, and folded into one word so that
//! the compiler cannot leave a load out. No detector can read a map faster than this loop does.

use rayon::prelude::*;

use super::simd::Isa;

/// Reads every byte of `bytes` on all of rayon's threads, in as many contiguous chunks as the OGM fast path
/// cuts a map of this size into bands (eight per thread), with the widest loads the CPU has (whatever
/// `OGM_CORNERS_ISA` says: the yardstick stays the machine's), and returns a fold of them (of no meaning;
/// only so that the reads happen).
pub fn read_all(bytes: &[u8]) -> u64 {
    let threads = rayon::current_num_threads().max(1);
    let chunk = bytes.len().div_ceil(threads * 8).max(1 << 16);
    bytes
        .par_chunks(chunk)
        .map(|c| read_chunk(Isa::best(), c))
        .reduce(|| 0, |a, b| a ^ b)
}

/// One thread's read of `bytes` with `isa` (falling back to what the CPU runs).
pub fn read_chunk(isa: Isa, bytes: &[u8]) -> u64 {
    let isa = isa.capped();
    #[cfg(target_arch = "x86_64")]
    match isa {
        // SAFETY: the CPU runs AVX-512 (F), checked by `Isa::capped` above.
        Isa::Avx512 => return unsafe { x86::read_avx512(bytes) },
        // SAFETY: the CPU runs AVX2, as above.
        Isa::Avx2 => return unsafe { x86::read_avx2(bytes) },
        Isa::Scalar => {}
    }
    let _ = isa;
    read_words(bytes)
}

/// The portable read: 8-byte words, four accumulators.
fn read_words(bytes: &[u8]) -> u64 {
    let mut acc = [0u64; 4];
    let mut blocks = bytes.chunks_exact(32);
    for b in &mut blocks {
        for (a, w) in acc.iter_mut().zip(b.chunks_exact(8)) {
            *a ^= u64::from_le_bytes(w.try_into().expect("8 bytes"));
        }
    }
    let tail = blocks
        .remainder()
        .iter()
        .fold(0u64, |a, &b| a.rotate_left(8) ^ u64::from(b));
    acc[0] ^ acc[1] ^ acc[2] ^ acc[3] ^ tail
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    /// 64-byte loads, four accumulators (four loads in flight a step).
    ///
    /// # Safety
    /// The CPU must have AVX-512 F.
    #[target_feature(enable = "avx512f")]
    pub unsafe fn read_avx512(bytes: &[u8]) -> u64 {
        let mut acc = [_mm512_setzero_si512(); 4];
        let mut blocks = bytes.chunks_exact(256);
        for b in &mut blocks {
            for (i, a) in acc.iter_mut().enumerate() {
                // SAFETY: 64 readable bytes at 64 i inside the 256-byte block.
                let v = unsafe { _mm512_loadu_si512(b.as_ptr().add(64 * i) as *const _) };
                *a = _mm512_xor_si512(*a, v);
            }
        }
        let x = _mm512_xor_si512(
            _mm512_xor_si512(acc[0], acc[1]),
            _mm512_xor_si512(acc[2], acc[3]),
        );
        _mm512_reduce_add_epi64(x) as u64 ^ super::read_words(blocks.remainder())
    }

    /// 32-byte loads, four accumulators.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2")]
    pub unsafe fn read_avx2(bytes: &[u8]) -> u64 {
        let mut acc = [_mm256_setzero_si256(); 4];
        let mut blocks = bytes.chunks_exact(128);
        for b in &mut blocks {
            for (i, a) in acc.iter_mut().enumerate() {
                // SAFETY: 32 readable bytes at 32 i inside the 128-byte block.
                let v = unsafe { _mm256_loadu_si256(b.as_ptr().add(32 * i) as *const __m256i) };
                *a = _mm256_xor_si256(*a, v);
            }
        }
        let x = _mm256_xor_si256(
            _mm256_xor_si256(acc[0], acc[1]),
            _mm256_xor_si256(acc[2], acc[3]),
        );
        let mut lanes = [0u64; 4];
        // SAFETY: 32 writable bytes in `lanes`.
        unsafe { _mm256_storeu_si256(lanes.as_mut_ptr() as *mut __m256i, x) };
        lanes.iter().fold(0, |a, b| a ^ b) ^ super::read_words(blocks.remainder())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every instruction set reads every byte: a changed byte anywhere changes the fold of an otherwise
    /// zero buffer.
    #[test]
    fn every_byte_is_read_on_every_set() {
        for isa in Isa::ALL.into_iter().filter(|i| i.supported()) {
            for len in [0usize, 1, 31, 64, 255, 256, 1000] {
                let zero = vec![0u8; len];
                assert_eq!(read_chunk(isa, &zero), 0, "{isa:?} {len}");
                for at in [0, len / 2, len.saturating_sub(1)] {
                    if len == 0 {
                        continue;
                    }
                    let mut b = zero.clone();
                    b[at] = 0x5A;
                    assert_ne!(read_chunk(isa, &b), 0, "{isa:?} {len} byte {at}");
                }
            }
        }
        assert_eq!(read_all(&[]), 0);
        let mut big = vec![0u8; 3 << 20 | 3];
        assert_eq!(read_all(&big), 0);
        big[(3 << 20) - 7] = 1;
        assert_ne!(read_all(&big), 0);
    }
}
