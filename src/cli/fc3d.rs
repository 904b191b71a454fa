//! `ballast-nscd fc3d FILE`: reads a Siconos FC3D problem, solves it by NSGS from r = 0
//! and prints iterations, the Siconos error measure and the solver time (reading not
//! included), as a few lines or, with `--json`, one JSON object.

use std::path::Path;

use crate::nscd::{nlgs, NlgsOptions, Stopping};

/// Solves `file` to `tolerance` with at most `max_sweeps` sweeps and prints the outcome.
pub(super) fn run(file: &Path, tolerance: f64, max_sweeps: usize, json: bool) -> crate::Result<()> {
    if !(tolerance.is_finite() && tolerance >= 0.0) {
        return Err(crate::Error::Message(format!(
            "--tol must be a finite number ≥ 0, not {tolerance}"
        )));
    }
    if max_sweeps == 0 {
        return Err(crate::Error::Message(
            "--max-iter must be at least 1".into(),
        ));
    }
    let (problem, format) = crate::fc3d::read(file)?;
    let contacts = problem.contact_count();
    let mut impulse = vec![0.0; 3 * contacts];
    let mut velocity = vec![0.0; 3 * contacts];
    let options = NlgsOptions {
        stopping: Stopping::Tolerance {
            tolerance,
            max_sweeps,
        },
        ..NlgsOptions::default()
    };
    let report = nlgs::solve(&problem, &mut impulse, &mut velocity, &options);
    let name = file.file_name().map_or_else(
        || file.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    if json {
        let object = serde_json::json!({
            "file": name,
            "format": format.label(),
            "contacts": contacts,
            "tolerance": tolerance,
            "max_iter": max_sweeps,
            "iterations": report.iterations,
            "error": report.error,
            "converged": report.converged,
            "solver_time_s": report.solve_time.as_secs_f64(),
            "error_evaluations": report.error_evaluations,
            "local_fallbacks": report.local_fallbacks,
            "returned_sweep": report.returned_sweep,
        });
        println!("{object}");
    } else {
        println!("file           {name} ({})", format.label());
        println!("contacts       {contacts}");
        println!(
            "iterations     {}{}",
            report.iterations,
            if report.converged {
                ""
            } else {
                " (cap reached)"
            }
        );
        println!(
            "error          {:.3e} (Siconos measure, tolerance {tolerance:.1e})",
            report.error
        );
        println!("solver time    {:.6} s", report.solve_time.as_secs_f64());
    }
    Ok(())
}
