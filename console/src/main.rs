//! `wheelcal`: see `wheelcal --help`.
fn main() -> std::process::ExitCode {
    one_malloc_arena();
    // The E-stop relay's signal must never end the process (see `wheelcal::stop`).
    wheelcal::stop::install_relay_signal();
    wheelcal::cli::main()
}

/// glibc gives each thread that allocates its own malloc arena and keeps what is freed in
/// it for that thread: `diagnose`'s workers each held several released model runs, so
/// its 120k-row bench peaked at 63-66 MB resident with per-thread arenas and 50-52 MB
/// with one, no slower (BENCHMARKS.md, "Diagnose: whole process on 120,000 rows").
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn one_malloc_arena() {
    // SAFETY: mallopt only sets a parameter of the allocator; it runs before any thread
    // of ours starts. A refusal (return 0) leaves glibc's default, which is only larger.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

/// Other allocators keep their own policy.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn one_malloc_arena() {}
