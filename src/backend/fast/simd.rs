//! The instruction sets the fast path picks at run time, and bit vectors of 64-bit lanes over them, so
//! that a bit-plane kernel is written once ([`Lanes`]) and compiled three times: 64 pixels a step
//! (portable), 256 (AVX2) and 512 (AVX-512).
//!
//! `OGM_CORNERS_ISA=scalar|avx2|avx512` caps the choice (to compare the kernels, or to rule one out); the
//! command line refuses any other value.

use std::sync::OnceLock;

/// An instruction set a fast kernel is compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// Portable Rust: 64-bit words (SSE2 compares on x86-64, which every x86-64 CPU has).
    Scalar,
    /// AVX2, BMI1 and POPCNT (Haswell, Zen 1 and later): 256-bit vectors.
    Avx2,
    /// AVX-512 F, BW, VL and VBMI, with the AVX2 set (Ice Lake, Sapphire Rapids, Zen 4 and later; not
    /// Skylake-SP, which lacks VBMI and runs the AVX2 kernels): 512-bit vectors, byte compares into mask
    /// registers, byte permutes for table lookups.
    Avx512,
}

/// The environment variable that caps [`Isa::active`].
pub const ISA_ENV: &str = "OGM_CORNERS_ISA";

impl Isa {
    /// Every instruction set, narrowest first.
    pub const ALL: [Isa; 3] = [Isa::Scalar, Isa::Avx2, Isa::Avx512];

    /// Its name, as `OGM_CORNERS_ISA` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Scalar => "scalar",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// The instruction set named `s` (as [`Isa::name`] spells it).
    pub fn parse(s: &str) -> Option<Isa> {
        Isa::ALL.into_iter().find(|i| i.name() == s)
    }

    /// Whether this CPU runs it.
    pub fn supported(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            match self {
                Isa::Scalar => true,
                Isa::Avx2 => has!("avx2") && has!("bmi1") && has!("popcnt"),
                Isa::Avx512 => {
                    Isa::Avx2.supported()
                        && has!("avx512f")
                        && has!("avx512bw")
                        && has!("avx512vl")
                        && has!("avx512vbmi")
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self == Isa::Scalar
        }
    }

    /// The widest instruction set this CPU runs.
    pub fn best() -> Isa {
        *Isa::ALL
            .iter()
            .rev()
            .find(|i| i.supported())
            .unwrap_or(&Isa::Scalar)
    }

    /// This set, or the widest below it that the CPU runs (the sets are nested: each runs where the wider
    /// one does).
    pub fn capped(self) -> Isa {
        self.min(Isa::best())
    }

    /// The cap `OGM_CORNERS_ISA` sets: `Ok(None)` when unset, an error message for a value that names no
    /// instruction set.
    pub fn from_env() -> std::result::Result<Option<Isa>, String> {
        match std::env::var(ISA_ENV) {
            Err(std::env::VarError::NotPresent) => Ok(None),
            Ok(v) if v.is_empty() => Ok(None),
            Ok(v) => Isa::parse(&v)
                .map(Some)
                .ok_or_else(|| format!("{ISA_ENV}={v}: expected one of scalar, avx2, avx512")),
            Err(_) => Err(format!("{ISA_ENV} is not valid UTF-8")),
        }
    }

    /// What the fast path runs: the widest supported instruction set, capped by `OGM_CORNERS_ISA` (an
    /// invalid value caps nothing here; the command line reports it). Read once per process.
    pub fn active() -> Isa {
        static ACTIVE: OnceLock<Isa> = OnceLock::new();
        *ACTIVE.get_or_init(|| match Isa::from_env() {
            Ok(Some(cap)) => cap.capped(),
            _ => Isa::best(),
        })
    }
}

/// The positions of the set bits of `m`, lowest first.
#[inline(always)]
pub fn set_bits(mut m: u64) -> impl Iterator<Item = u32> {
    std::iter::from_fn(move || {
        let j = m.trailing_zeros();
        m &= m.wrapping_sub(1);
        (j < 64).then_some(j)
    })
}

/// A vector of [`Lanes::WORDS`] 64-bit words, each 64 pixels' bits. Methods are `#[inline(always)]`
/// wrappers: inlined into a function compiled for the instruction set, they become its instructions.
pub trait Lanes: Copy {
    /// 64-bit words per vector.
    const WORDS: usize;

    /// The words at `p`.
    ///
    /// # Safety
    /// `p` must point at `WORDS` readable words, and the CPU must have the vector's instruction set.
    unsafe fn load(p: *const u64) -> Self;

    /// Writes the words to `p`.
    ///
    /// # Safety
    /// `p` must point at `WORDS` writable words, and the CPU must have the vector's instruction set.
    unsafe fn store(self, p: *mut u64);

    /// Bitwise and.
    fn and(self, o: Self) -> Self;
    /// Bitwise or.
    fn or(self, o: Self) -> Self;
    /// Bitwise exclusive or.
    fn xor(self, o: Self) -> Self;
    /// `self & !o`.
    fn and_not(self, o: Self) -> Self;
    /// All ones.
    fn ones() -> Self;
    /// Each word's bits one place up (bit x holds bit x - 1), the lowest bit taken from the top bit of
    /// the word below in `prev` (the vector one word lower in memory).
    fn left_neighbour(self, prev: Self) -> Self;
    /// Each word's bits one place down (bit x holds bit x + 1), the top bit taken from the lowest bit of
    /// the word above in `next` (the vector one word higher in memory).
    fn right_neighbour(self, next: Self) -> Self;
    /// Whether every bit is zero.
    fn is_zero(self) -> bool;
    /// Bit `i` set when word `i` is not zero.
    fn nonzero_words(self) -> u32;
}

impl Lanes for u64 {
    const WORDS: usize = 1;
    #[inline(always)]
    unsafe fn load(p: *const u64) -> Self {
        // SAFETY: one readable word at `p` (the caller's promise).
        unsafe { p.read_unaligned() }
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut u64) {
        // SAFETY: one writable word at `p` (the caller's promise).
        unsafe { p.write_unaligned(self) }
    }
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        self & o
    }
    #[inline(always)]
    fn or(self, o: Self) -> Self {
        self | o
    }
    #[inline(always)]
    fn xor(self, o: Self) -> Self {
        self ^ o
    }
    #[inline(always)]
    fn and_not(self, o: Self) -> Self {
        self & !o
    }
    #[inline(always)]
    fn ones() -> Self {
        !0
    }
    #[inline(always)]
    fn left_neighbour(self, prev: Self) -> Self {
        (self << 1) | (prev >> 63)
    }
    #[inline(always)]
    fn right_neighbour(self, next: Self) -> Self {
        (self >> 1) | (next << 63)
    }
    #[inline(always)]
    fn is_zero(self) -> bool {
        self == 0
    }
    #[inline(always)]
    fn nonzero_words(self) -> u32 {
        u32::from(self != 0)
    }
}

#[cfg(target_arch = "x86_64")]
pub use x86::{V256, V512};

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::Lanes;

    /// Four words in an AVX2 register.
    #[derive(Clone, Copy)]
    pub struct V256(__m256i);

    /// Eight words in an AVX-512 register.
    #[derive(Clone, Copy)]
    pub struct V512(__m512i);

    // SAFETY (every method below): these run only inside functions compiled for, and called on, CPUs
    // with the vector's instruction set (the trait's contract); loads and stores are unaligned.
    impl Lanes for V256 {
        const WORDS: usize = 4;
        #[inline(always)]
        unsafe fn load(p: *const u64) -> Self {
            // SAFETY: see above; 4 readable words at `p` (the caller's promise).
            V256(unsafe { _mm256_loadu_si256(p as *const __m256i) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut u64) {
            // SAFETY: see above; 4 writable words at `p` (the caller's promise).
            unsafe { _mm256_storeu_si256(p as *mut __m256i, self.0) }
        }
        #[inline(always)]
        fn and(self, o: Self) -> Self {
            // SAFETY: see above.
            V256(unsafe { _mm256_and_si256(self.0, o.0) })
        }
        #[inline(always)]
        fn or(self, o: Self) -> Self {
            // SAFETY: see above.
            V256(unsafe { _mm256_or_si256(self.0, o.0) })
        }
        #[inline(always)]
        fn xor(self, o: Self) -> Self {
            // SAFETY: see above.
            V256(unsafe { _mm256_xor_si256(self.0, o.0) })
        }
        #[inline(always)]
        fn and_not(self, o: Self) -> Self {
            // SAFETY: see above.
            V256(unsafe { _mm256_andnot_si256(o.0, self.0) })
        }
        #[inline(always)]
        fn ones() -> Self {
            // SAFETY: see above.
            V256(unsafe { _mm256_set1_epi64x(-1) })
        }
        #[inline(always)]
        fn left_neighbour(self, prev: Self) -> Self {
            // SAFETY: see above.
            V256(unsafe {
                _mm256_or_si256(
                    _mm256_slli_epi64::<1>(self.0),
                    _mm256_srli_epi64::<63>(prev.0),
                )
            })
        }
        #[inline(always)]
        fn right_neighbour(self, next: Self) -> Self {
            // SAFETY: see above.
            V256(unsafe {
                _mm256_or_si256(
                    _mm256_srli_epi64::<1>(self.0),
                    _mm256_slli_epi64::<63>(next.0),
                )
            })
        }
        #[inline(always)]
        fn is_zero(self) -> bool {
            // SAFETY: see above.
            unsafe { _mm256_testz_si256(self.0, self.0) == 1 }
        }
        #[inline(always)]
        fn nonzero_words(self) -> u32 {
            // SAFETY: see above.
            unsafe {
                let zero = _mm256_cmpeq_epi64(self.0, _mm256_setzero_si256());
                !(_mm256_movemask_pd(_mm256_castsi256_pd(zero)) as u32) & 0xF
            }
        }
    }

    impl Lanes for V512 {
        const WORDS: usize = 8;
        #[inline(always)]
        unsafe fn load(p: *const u64) -> Self {
            // SAFETY: see above; 8 readable words at `p` (the caller's promise).
            V512(unsafe { _mm512_loadu_si512(p as *const _) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut u64) {
            // SAFETY: see above; 8 writable words at `p` (the caller's promise).
            unsafe { _mm512_storeu_si512(p as *mut _, self.0) }
        }
        #[inline(always)]
        fn and(self, o: Self) -> Self {
            // SAFETY: see above.
            V512(unsafe { _mm512_and_si512(self.0, o.0) })
        }
        #[inline(always)]
        fn or(self, o: Self) -> Self {
            // SAFETY: see above.
            V512(unsafe { _mm512_or_si512(self.0, o.0) })
        }
        #[inline(always)]
        fn xor(self, o: Self) -> Self {
            // SAFETY: see above.
            V512(unsafe { _mm512_xor_si512(self.0, o.0) })
        }
        #[inline(always)]
        fn and_not(self, o: Self) -> Self {
            // SAFETY: see above.
            V512(unsafe { _mm512_andnot_si512(o.0, self.0) })
        }
        #[inline(always)]
        fn ones() -> Self {
            // SAFETY: see above.
            V512(unsafe { _mm512_set1_epi64(-1) })
        }
        #[inline(always)]
        fn left_neighbour(self, prev: Self) -> Self {
            // SAFETY: see above.
            V512(unsafe {
                _mm512_or_si512(
                    _mm512_slli_epi64::<1>(self.0),
                    _mm512_srli_epi64::<63>(prev.0),
                )
            })
        }
        #[inline(always)]
        fn right_neighbour(self, next: Self) -> Self {
            // SAFETY: see above.
            V512(unsafe {
                _mm512_or_si512(
                    _mm512_srli_epi64::<1>(self.0),
                    _mm512_slli_epi64::<63>(next.0),
                )
            })
        }
        #[inline(always)]
        fn is_zero(self) -> bool {
            // SAFETY: see above.
            unsafe { _mm512_test_epi64_mask(self.0, self.0) == 0 }
        }
        #[inline(always)]
        fn nonzero_words(self) -> u32 {
            // SAFETY: see above.
            unsafe { u32::from(_mm512_test_epi64_mask(self.0, self.0)) }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vectors shift bits across their words as the portable words do, on every supported set.
    #[test]
    fn vector_shifts_match_the_portable_words() {
        let words: Vec<u64> = (0..18u64)
            .map(|i| i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (i << 60))
            .collect();
        let want_left: Vec<u64> = (1..17)
            .map(|k| words[k].left_neighbour(words[k - 1]))
            .collect();
        let want_right: Vec<u64> = (1..17)
            .map(|k| words[k].right_neighbour(words[k + 1]))
            .collect();
        #[cfg(target_arch = "x86_64")]
        {
            fn check<V: Lanes>(words: &[u64], left: &[u64], right: &[u64]) {
                let mut got = vec![0u64; 16];
                for k in (1..17).step_by(V::WORDS) {
                    // SAFETY: the caller checked the CPU; k - 1 .. k + 1 + WORDS lie inside `words`.
                    unsafe {
                        let (p, c, n) = (
                            V::load(words.as_ptr().add(k - 1)),
                            V::load(words.as_ptr().add(k)),
                            V::load(words.as_ptr().add(k + 1)),
                        );
                        c.left_neighbour(p).store(got.as_mut_ptr().add(k - 1));
                        assert_eq!(c.is_zero(), words[k..k + V::WORDS].iter().all(|&w| w == 0));
                        let nz = (0..V::WORDS)
                            .filter(|&i| words[k + i] != 0)
                            .fold(0, |m, i| m | 1 << i);
                        assert_eq!(c.nonzero_words(), nz);
                        assert_eq!(c.and_not(c).nonzero_words(), 0);
                        let _ = n;
                    }
                }
                assert_eq!(got, left);
                for k in (1..17).step_by(V::WORDS) {
                    // SAFETY: as above.
                    unsafe {
                        let c = V::load(words.as_ptr().add(k));
                        let n = V::load(words.as_ptr().add(k + 1));
                        c.right_neighbour(n).store(got.as_mut_ptr().add(k - 1));
                    }
                }
                assert_eq!(got, right);
            }
            if Isa::Avx2.supported() {
                check::<V256>(&words, &want_left, &want_right);
            }
            if Isa::Avx512.supported() {
                check::<V512>(&words, &want_left, &want_right);
            }
        }
        assert_eq!(want_left[0], (words[1] << 1) | (words[0] >> 63));
    }

    /// Names round-trip, and the cap never exceeds what the CPU runs.
    #[test]
    fn names_and_the_active_set() {
        for isa in Isa::ALL {
            assert_eq!(Isa::parse(isa.name()), Some(isa));
        }
        assert_eq!(Isa::parse("sse"), None);
        assert!(Isa::active().supported() && Isa::active() <= Isa::best());
        for isa in Isa::ALL {
            assert!(isa.capped().supported() && isa.capped() <= isa);
        }
        assert_eq!(set_bits(0).count(), 0);
        assert_eq!(set_bits(1 << 63 | 5).collect::<Vec<_>>(), [0, 2, 63]);
    }
}
