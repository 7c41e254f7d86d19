//! `wheelcal`: see `wheelcal --help`.
fn main() -> std::process::ExitCode {
    wheelcal::cli::main()
}
