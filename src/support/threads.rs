//! The worker threads: rayon's global pool, its size taken from `RAYON_NUM_THREADS` as rayon takes it,
//! but capped at a few threads a core. Thousands of workers on a few cores (a number meant for another
//! machine, a typo) cost more in start-up and contention than the work: a two-map merge went from a
//! quarter of a second to a minute.

/// Most workers a core: more only queue behind each other.
pub const THREADS_PER_CORE: usize = 4;

/// The most worker threads on this machine: [`THREADS_PER_CORE`] per core the process may use.
pub fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    cores.saturating_mul(THREADS_PER_CORE)
}

/// Caps rayon's global pool when `RAYON_NUM_THREADS` asks for more than [`max_threads`], before the pool
/// is first used; returns a note saying so, or None when the variable is within bounds (or unset, or not
/// a number: rayon then picks one a core itself). Does nothing once the pool exists.
pub fn cap_pool() -> Option<String> {
    let asked: usize = std::env::var("RAYON_NUM_THREADS")
        .ok()?
        .trim()
        .parse()
        .ok()?;
    let cap = max_threads();
    if asked <= cap {
        return None;
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(cap)
        .build_global()
        .ok()?;
    Some(format!(
        "RAYON_NUM_THREADS={asked} is more than {THREADS_PER_CORE} threads a core ({} cores here); using {cap}",
        cap / THREADS_PER_CORE
    ))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_cap_is_a_few_threads_a_core() {
        let cores = std::thread::available_parallelism().unwrap().get();
        assert_eq!(super::max_threads(), cores * super::THREADS_PER_CORE);
    }
}
