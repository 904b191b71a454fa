//! The NLGS sweep's memory behaviour on a synthetic contact problem (`make bench-sweep`):
//! 17 random contacts per body, each between bodies at most 100 apart in the numbering
//! (as in a packed bed renumbered by position), a share of them pressed shut (the rest
//! open and separating), solved by the plain NLGS with a fixed number of sweeps (the
//! sweeps are sequential; only the set-up and the final error measure use rayon's
//! threads). Prints ns per contact and sweep and contact updates/s.
//!
//! ```text
//! cargo run --release --example nlgs_sweep -- BODIES SWEEPS CLOSED_SHARE MU
//! ```

use std::time::Instant;

use ballast::geometry::random::SplitMix;
use ballast::nscd::body_nlgs::{solve, BodyInverses, ContactRow};
use ballast::nscd::{ErrorCheck, NlgsOptions, Stopping};
use nalgebra::{Matrix3, Vector3};

/// Contacts per body (a bed's coordination number is 4–5 stone pairs, each of 3–4
/// contact points).
const PER_BODY: usize = 17;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |k: usize, default: f64| -> f64 {
        args.get(k).map_or(default, |s| {
            s.parse().unwrap_or_else(|_| {
                eprintln!("nlgs_sweep: argument {} ({s}) is not a number", k + 1);
                std::process::exit(2)
            })
        })
    };
    let (bodies, sweeps) = (arg(0, 7000.0) as usize, arg(1, 300.0) as usize);
    let (closed_share, mu) = (arg(2, 0.2), arg(3, 1.0));
    if bodies < 2 || sweeps == 0 {
        eprintln!("nlgs_sweep: needs at least 2 bodies and 1 sweep");
        std::process::exit(2);
    }
    // The project's seeded generator: the same problem on every run.
    let mut random = SplitMix(12345);
    let mut rnd = move || random.next_f64();
    let mut rows = Vec::new();
    for i in 0..bodies {
        for _ in 0..PER_BODY {
            let j = ((i as f64 + (rnd() - 0.5) * 200.0).max(0.0) as usize).min(bodies - 1);
            if j == i {
                continue;
            }
            let n = Vector3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let t = n.cross(&Vector3::new(0.3, 0.7, 0.1)).normalize();
            let s = n.cross(&t);
            let closed = rnd() < closed_share;
            let mut arm = || Vector3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * 0.04;
            let arms = [arm(), arm()];
            rows.push(ContactRow {
                bodies: [i as u32, j as u32],
                frame: [n, t, s],
                arms,
                shift: if closed { -0.01 } else { 0.01 + rnd() },
                mu,
            });
        }
    }
    let inverse_mass = vec![10.0; bodies];
    let inverse_inertia = vec![Matrix3::identity() * 5000.0; bodies];
    let inverses = BodyInverses {
        inverse_mass: &inverse_mass,
        inverse_inertia: &inverse_inertia,
    };
    let mut velocity = vec![Vector3::new(0.0, 0.0, -0.01); bodies];
    let mut angular_velocity = vec![Vector3::zeros(); bodies];
    let mut impulse = vec![[0.0; 3]; rows.len()];
    let options = NlgsOptions {
        stopping: Stopping::Sweeps(sweeps),
        error_check: ErrorCheck::Light { every: usize::MAX },
    };
    let clock = Instant::now();
    solve(
        &rows,
        &inverses,
        &mut velocity,
        &mut angular_velocity,
        &mut impulse,
        &options,
    );
    let seconds = clock.elapsed().as_secs_f64();
    let updates = (rows.len() * sweeps) as f64;
    let carrying = impulse.iter().filter(|r| **r != [0.0; 3]).count();
    println!(
        "nlgs_sweep: {} contacts ({} carry an impulse at the end), {} bodies, {} sweeps, µ = {}: \
         {:.3} s, {:.1} ns a contact and sweep, {:.2e} contact updates/s",
        rows.len(),
        carrying,
        bodies,
        sweeps,
        mu,
        seconds,
        seconds * 1e9 / updates,
        updates / seconds
    );
}
