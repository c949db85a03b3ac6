//! The allocator setting `dynid` runs with (glibc).

/// Keeps freed large buffers in the heap for reuse: identification frees and reallocates
/// megabyte buffers thousands of times, and glibc's default adaptive thresholds turn each reuse
/// into fresh page faults (measured in `docs/bench_identify.md`).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn keep_large_buffers() {
    // SAFETY: `mallopt` only sets two allocator parameters; called before any other thread runs.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn keep_large_buffers() {}
