//! `ballast-nscd`: see `ballast-nscd --help`.
use clap::Parser;

fn main() {
    let cli = ballast::cli::NscdCli::parse();
    ballast::cli::exit_with("ballast-nscd", ballast::cli::run_nscd(cli));
}
