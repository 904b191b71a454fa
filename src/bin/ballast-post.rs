//! `ballast-post`: see `ballast-post --help`.
use clap::Parser;

fn main() {
    let cli = ballast::cli::PostCli::parse();
    ballast::cli::exit_with("ballast-post", ballast::cli::run_post(cli));
}
