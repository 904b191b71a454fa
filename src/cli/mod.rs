//! Command-line front ends: each binary in `src/bin/` parses its arguments with clap
//! here and calls the library. Nothing in the numerical cores depends on this module.

mod fc3d;
mod post;
mod solvers;

pub use post::{run_post, PostCli, PostCommand};
pub use solvers::{
    run_fem, run_nscd, run_pack, run_qdem, FemCli, FemCommand, NscdCli, NscdCommand, PackCli,
    QdemCli,
};

/// Runs a binary's main function and turns an error into one line on stderr and exit
/// status 1.
pub fn exit_with(program: &str, result: crate::Result<()>) -> ! {
    match result {
        Ok(()) => std::process::exit(0),
        Err(err) => {
            let line = err.to_string().replace('\n', " ");
            eprintln!("{program}: error: {line}");
            std::process::exit(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    #[test]
    fn clap_definitions_are_consistent() {
        super::PostCli::command().debug_assert();
        super::PackCli::command().debug_assert();
        super::NscdCli::command().debug_assert();
        super::QdemCli::command().debug_assert();
        super::FemCli::command().debug_assert();
    }
}
