//! The `depthor` command line: parses arguments, runs one subcommand, prints an error once.
use clap::Parser;
use std::process::ExitCode;

mod cli;

fn main() -> ExitCode {
    restore_sigpipe();
    match cli::run(cli::Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", cli::one_line(&e));
            ExitCode::from(cli::EXIT_FAILURE)
        }
    }
}

/// Restores the default action of SIGPIPE, which Rust's runtime ignores: with it ignored, a
/// reader that closes the pipe early (`depthor info … | head`) made the next `println!` panic
/// with a backtrace; a command-line tool should end quietly instead, as `cat` does.
#[cfg(unix)]
fn restore_sigpipe() {
    // SAFETY: called first thing in `main`, before any thread exists; `signal` with SIG_DFL only
    // changes this process's disposition of SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Nothing to restore where there is no SIGPIPE.
#[cfg(not(unix))]
fn restore_sigpipe() {}
