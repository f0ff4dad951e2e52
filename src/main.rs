use clap::Parser;

fn main() -> anyhow::Result<()> {
    hdrsynth::device::retain_freed_memory();
    hdrsynth::cli::run(hdrsynth::cli::Cli::parse())
}
