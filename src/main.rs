use clap::Parser;

fn main() -> std::process::ExitCode {
    hdrsynth::device::retain_freed_memory();
    match hdrsynth::cli::run(hdrsynth::cli::Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{}", hdrsynth::cli::error_report(&e));
            std::process::ExitCode::FAILURE
        }
    }
}
