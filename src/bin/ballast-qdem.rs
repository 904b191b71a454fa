//! `ballast-qdem`: see `ballast-qdem --help`.
use clap::Parser;

fn main() {
    let cli = ballast::cli::QdemCli::parse();
    ballast::cli::exit_with("ballast-qdem", ballast::cli::run_qdem(cli));
}
