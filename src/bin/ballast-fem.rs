//! `ballast-fem`: see `ballast-fem --help`.
use clap::Parser;

fn main() {
    let cli = ballast::cli::FemCli::parse();
    ballast::cli::exit_with("ballast-fem", ballast::cli::run_fem(cli));
}
