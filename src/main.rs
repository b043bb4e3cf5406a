//! The `vesalius` command line (see `cli/`).
#![forbid(unsafe_code)]

mod cli;

/// Counts live heap bytes for the profiler's memory figures.
#[global_allocator]
static GLOBAL: &stats_alloc::StatsAlloc<std::alloc::System> = &stats_alloc::INSTRUMENTED_SYSTEM;

fn heap_bytes() -> u64 {
    // stats_alloc books a realloc's growth under bytes_allocated (and its shrinkage under
    // bytes_deallocated) as well as under bytes_reallocated: adding the latter would count
    // every grown Vec twice.
    let s = GLOBAL.stats();
    s.bytes_allocated.saturating_sub(s.bytes_deallocated) as u64
}

fn main() -> std::process::ExitCode {
    vesalius::profiler::set_heap_probe(heap_bytes);
    cli::main()
}
