//! Helpers for the crate's own tests, below every module so that any may use them.

/// Runs `f` on a pool of `threads` workers (tests comparing the bytes of 1 and 2 threads).
pub(crate) fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(f)
}
