//! The `rigcal` command line. Errors reach the user through `anyhow` here and nowhere else.

#![warn(missing_docs)]
#![deny(clippy::unwrap_used)]

mod cli;

fn main() -> std::process::ExitCode {
    end_quietly_on_a_closed_pipe();
    cli::main()
}

/// Rust ignores SIGPIPE, so `rigcal … | head` would panic on its next print once `head` has
/// gone; with the default action restored it ends quietly, like other Unix tools.
#[cfg(unix)]
fn end_quietly_on_a_closed_pipe() {
    // SAFETY: called first in `main`, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn end_quietly_on_a_closed_pipe() {}
