//! Exclusive prefix sum: the CPU twin of `shaders/scan.wgsl`, which turns per-workgroup keypoint counts into
//! list positions on the device.

/// The exclusive prefix sums of `counts` (entry i is the sum of the entries before it) and their total.
/// Sums wrap at 2^32 as the kernel's do; callers keep totals below that.
pub fn exclusive_scan(counts: &[u32]) -> (Vec<u32>, u32) {
    let mut acc = 0u32;
    let out = counts
        .iter()
        .map(|&c| {
            let v = acc;
            acc = acc.wrapping_add(c);
            v
        })
        .collect();
    (out, acc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefix_sums() {
        assert_eq!(exclusive_scan(&[]), (vec![], 0));
        assert_eq!(exclusive_scan(&[3, 0, 2, 5]), (vec![0, 3, 3, 5], 10));
    }
}
