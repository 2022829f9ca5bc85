//! The `rigcal` command line. Errors reach the user through `anyhow` here and nowhere else.

fn main() -> std::process::ExitCode {
    rigcal::cli::main()
}
