//! `ballast-pack`: see `ballast-pack --help`.
use clap::Parser;

fn main() {
    let cli = ballast::cli::PackCli::parse();
    ballast::cli::exit_with("ballast-pack", ballast::cli::run_pack(cli));
}
