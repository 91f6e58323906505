//! A reader that closes the painter's standard output early
//! (`octopaint check --canonical TRACE | head`).
//!
//! Rust ignores SIGPIPE, so a write to a closed pipe fails and `println!`
//! panics with a backtrace. On Unix the painter restores the default
//! disposition at start, as other command-line tools have it: the process
//! ends quietly at that write, by the signal. Anything it was writing to a
//! file is replaced atomically ([`crate::durable`]), so ending there leaves
//! the old file or the new one, as any other interruption does. Windows has
//! no such signal: there a closed pipe still ends the program with a panic
//! message (docs/windows.md).

/// Let a closed standard output end the process quietly (Unix).
pub fn end_quietly_on_closed_stdout() {
    #[cfg(unix)]
    {
        // SIGPIPE is 13 on Linux and macOS; SIG_DFL is 0.
        const SIGPIPE: i32 = 13;
        const SIG_DFL: usize = 0;
        unsafe extern "C" {
            fn signal(signum: i32, handler: usize) -> usize;
        }
        // SAFETY: called once at the start of main, before any thread
        // exists; restoring the default disposition has no handler to run.
        unsafe {
            signal(SIGPIPE, SIG_DFL);
        }
    }
}
