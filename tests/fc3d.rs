//! FC3D problems written by Siconos (`../shared/fc3d`): every file read in every storage,
//! W checked, NSGS against Siconos's published results, the local Coulomb solver against
//! analytic answers, and the `ballast-nscd fc3d` command line.

use std::path::{Path, PathBuf};
use std::process::Command;

use ballast::fc3d::{self, Fc3dFormat};
use ballast::nscd::coulomb::coulomb_residual_squared;
use ballast::nscd::{
    nlgs, residual, ContactStatus, DelassusBlocks, ErrorCheck, FrictionProblem, LocalCoulomb,
    NlgsOptions, Stopping,
};

/// Siconos 4.4 NSGS's published results on these files, from the reference table of
/// `../shared/fc3d/README.md` ("Reference: Siconos 4.4 NSGS"): contacts, µ, format and
/// the final error at tolerance 1e-8 with a cap of 10 000 sweeps, from r = 0.
const REFERENCE: &[(&str, usize, f64, Fc3dFormat, f64)] = &[
    (
        "Box_Stacks-i0122-82-5.hdf5",
        82,
        0.3,
        Fc3dFormat::FclibGlobal,
        5.0e-09,
    ),
    (
        "BoxesStack1-i100000-32.hdf5.dat",
        52,
        0.7,
        Fc3dFormat::DatBlockSparse,
        2.0e-05,
    ),
    (
        "Capsules-i100-1090.dat",
        276,
        0.7,
        Fc3dFormat::DatBlockSparse,
        9.4e-11,
    ),
    (
        "Capsules-i100-889.dat",
        276,
        0.7,
        Fc3dFormat::DatBlockSparse,
        1.4e-10,
    ),
    (
        "Capsules-i101-404.dat",
        225,
        0.7,
        Fc3dFormat::DatBlockSparse,
        8.6e-09,
    ),
    (
        "Capsules-i103-990.dat",
        275,
        0.7,
        Fc3dFormat::DatBlockSparse,
        4.5e-10,
    ),
    (
        "Capsules-i125-1213.hdf5",
        286,
        0.7,
        Fc3dFormat::FclibLocal,
        2.6e-10,
    ),
    (
        "Confeti-ex03-Fc3D-SBM.dat",
        54,
        0.4,
        Fc3dFormat::DatBlockSparse,
        4.1e-13,
    ),
    ("FC3D_Example1.dat", 3, 0.1, Fc3dFormat::DatDense, 4.7e-18),
    (
        "FC3D_Example1_SBM.dat",
        3,
        0.1,
        Fc3dFormat::DatBlockSparse,
        4.7e-18,
    ),
    (
        "FrictionContact3D_1c.dat",
        1,
        0.1,
        Fc3dFormat::DatDense,
        2.6e-17,
    ),
    (
        "FrictionContact3D_RR_1c.dat",
        1,
        0.6,
        Fc3dFormat::DatDense,
        1.5e-16,
    ),
    (
        "KaplasTower-i1061-4.hdf5.dat",
        570,
        0.3,
        Fc3dFormat::DatBlockSparse,
        1.0e-08,
    ),
    ("NESpheres_10_1.dat", 9, 0.8, Fc3dFormat::DatDense, 2.2e-10),
    ("NESpheres_30_1.dat", 44, 0.8, Fc3dFormat::DatDense, 0.0),
    (
        "OneObject-i100000-316.hdf5.dat",
        25,
        0.3,
        Fc3dFormat::DatBlockSparse,
        1.7e-03,
    ),
    (
        "OneObject-i100000-499.hdf5.dat",
        24,
        0.3,
        Fc3dFormat::DatBlockSparse,
        9.9e-04,
    ),
    (
        "OneObject-i1028-138.hdf5.dat",
        23,
        0.3,
        Fc3dFormat::DatBlockSparse,
        1.4e-09,
    ),
    ("Rover1039.dat", 4, 0.7, Fc3dFormat::DatDense, 3.0e-11),
    ("Rover1040.dat", 5, 0.7, Fc3dFormat::DatDense, 1.5e-11),
    ("Rover1041.dat", 5, 0.7, Fc3dFormat::DatDense, 1.6e-11),
    ("Rover11035.dat", 1, 0.7, Fc3dFormat::DatDense, 0.0),
    ("Rover11211.dat", 1, 0.7, Fc3dFormat::DatDense, 0.0),
    ("Rover3865.dat", 5, 0.7, Fc3dFormat::DatDense, 2.9e-12),
    ("Rover4144.dat", 4, 0.7, Fc3dFormat::DatDense, 3.9e-12),
    ("Rover4396.dat", 2, 0.7, Fc3dFormat::DatDense, 1.3e-14),
    ("Rover4493.dat", 4, 0.7, Fc3dFormat::DatDense, 6.4e-12),
    ("Rover4516.dat", 4, 0.7, Fc3dFormat::DatDense, 7.2e-12),
    ("Rover4609.dat", 5, 0.7, Fc3dFormat::DatDense, 1.5e-11),
    ("Rover4613.dat", 5, 0.7, Fc3dFormat::DatDense, 8.6e-12),
    ("Rover4622.dat", 4, 0.7, Fc3dFormat::DatDense, 7.9e-12),
    ("Rover9770.dat", 5, 0.7, Fc3dFormat::DatDense, 8.2e-12),
    (
        "Spheres-i099-356-679.hdf5",
        356,
        0.7,
        Fc3dFormat::FclibGlobal,
        7.3e-09,
    ),
];

fn fc3d_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/fc3d");
    assert!(
        dir.is_dir(),
        "{}: the FC3D problems are missing (shared/ must sit beside the repository)",
        dir.display()
    );
    dir
}

fn read(name: &str) -> (FrictionProblem, Fc3dFormat) {
    let path = fc3d_dir().join(name);
    fc3d::read(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_file_is_read_with_its_size_format_and_friction() {
    let mut on_disk: Vec<String> = std::fs::read_dir(fc3d_dir())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".dat") || n.ends_with(".hdf5"))
        .collect();
    on_disk.sort_by_key(|n| n.to_lowercase());
    let mut known: Vec<String> = REFERENCE.iter().map(|r| r.0.to_string()).collect();
    known.sort_by_key(|n| n.to_lowercase());
    assert_eq!(on_disk, known, "the problem set changed: update REFERENCE");
    for &(name, contacts, mu, format, _) in REFERENCE {
        let (problem, found) = read(name);
        assert_eq!(found, format, "{name}");
        assert_eq!(problem.contact_count(), contacts, "{name}");
        assert!(problem.friction.iter().all(|&m| m == mu), "{name}: µ");
        let mut u = vec![0.0; 3 * contacts];
        problem
            .delassus
            .affine(&vec![0.0; 3 * contacts], &problem.free_velocity, &mut u);
        assert_eq!(u, problem.free_velocity, "{name}: W 0 + q");
    }
}

/// The symmetric part's smallest and largest eigenvalues, and ‖W − Wᵀ‖_max / ‖W‖_max.
fn spectrum(w: &DelassusBlocks) -> (f64, f64, f64) {
    let n = 3 * w.contact_count();
    let dense = nalgebra::DMatrix::from_row_slice(n, n, &w.to_dense());
    let asymmetry = (&dense - dense.transpose()).amax() / dense.amax();
    let symmetric = (&dense + dense.transpose()) * 0.5;
    let eigen = symmetric.symmetric_eigenvalues();
    (eigen.min(), eigen.max(), asymmetry)
}

#[test]
fn w_is_symmetric_positive_semi_definite_on_small_problems() {
    for &(name, contacts, ..) in REFERENCE.iter().filter(|r| r.1 <= 90) {
        let (problem, _) = read(name);
        let (low, high, asymmetry) = spectrum(&problem.delassus);
        // Symmetric to rounding, except the Rover and OneObject files, whose W is written
        // asymmetric by up to 1.2e-4 of its largest entry.
        assert!(asymmetry < 2e-4, "{name}: ‖W − Wᵀ‖ / ‖W‖ = {asymmetry:e}");
        // Positive semi-definite up to the rounding of the files' values.
        assert!(
            high > 0.0 && low >= -1e-6 * high,
            "{name} ({contacts}): λ in [{low:e}, {high:e}]"
        );
    }
}

#[test]
fn dense_and_block_sparse_storages_agree() {
    let (dense, _) = read("FC3D_Example1.dat");
    let (sparse, _) = read("FC3D_Example1_SBM.dat");
    assert_eq!(dense, sparse);
}

#[test]
fn nsgs_reaches_what_siconos_reached_within_the_cap() {
    for &(name, contacts, _, _, siconos_error) in REFERENCE {
        let (problem, _) = read(name);
        let mut r = vec![0.0; 3 * contacts];
        let mut u = vec![0.0; 3 * contacts];
        let tolerance = 1e-8;
        let options = NlgsOptions {
            stopping: Stopping::Tolerance {
                tolerance,
                max_sweeps: 10_000,
            },
            ..NlgsOptions::default()
        };
        let report = nlgs::solve(&problem, &mut r, &mut u, &options);
        // The published errors have two digits: 5 % covers their rounding.
        let target = tolerance.max(1.05 * siconos_error);
        assert!(
            report.error <= target,
            "{name}: error {:e} after {} sweeps, Siconos reached {siconos_error:e}",
            report.error,
            report.iterations
        );
        assert!(report.iterations <= 10_000);
        assert_eq!(report.local_fallbacks, 0, "{name}");
        // The report's error is the error of the returned impulse.
        let check = residual::siconos_error(&problem, &r, &mut u);
        assert_eq!(check, report.error, "{name}");
    }
}

#[test]
fn every_sweep_error_check_stops_on_the_first_sweep_below_tolerance() {
    let (problem, _) = read("Capsules-i100-889.dat");
    let n = 3 * problem.contact_count();
    let solve = |options: NlgsOptions| {
        let (mut r, mut u) = (vec![0.0; n], vec![0.0; n]);
        nlgs::solve(&problem, &mut r, &mut u, &options)
    };
    let every = solve(NlgsOptions {
        stopping: Stopping::Tolerance {
            tolerance: 1e-6,
            max_sweeps: 10_000,
        },
        error_check: ErrorCheck::EverySweep,
    });
    assert!(every.converged && every.error <= 1e-6);
    assert_eq!(every.error_evaluations, every.iterations);
    let before = solve(NlgsOptions {
        stopping: Stopping::Sweeps(every.iterations - 1),
        ..NlgsOptions::default()
    });
    assert_eq!(before.iterations, every.iterations - 1);
    assert!(
        before.error > 1e-6,
        "sweep {} was already converged",
        before.iterations
    );
    let light = solve(NlgsOptions::default());
    assert!(light.converged && light.error <= 1e-8);
}

#[test]
fn fixed_sweeps_make_exactly_that_many() {
    let (problem, _) = read("OneObject-i100000-316.hdf5.dat");
    let n = 3 * problem.contact_count();
    let (mut r, mut u) = (vec![0.0; n], vec![0.0; n]);
    let options = NlgsOptions {
        stopping: Stopping::Sweeps(37),
        ..NlgsOptions::default()
    };
    let report = nlgs::solve(&problem, &mut r, &mut u, &options);
    assert_eq!((report.iterations, report.returned_sweep), (37, 37));
    assert_eq!(report.error_evaluations, 1);
    assert!(report.error.is_finite() && report.error > 0.0);
}

fn coulomb_error(w: &[f64; 9], q: [f64; 3], mu: f64, r: [f64; 3]) -> f64 {
    let mut u = q;
    for i in 0..3 {
        for j in 0..3 {
            u[i] += w[3 * i + j] * r[j];
        }
    }
    coulomb_residual_squared(r, u, mu).sqrt()
}

#[test]
fn local_solver_take_off_stick_and_slip_analytic() {
    let w = [2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let local = LocalCoulomb::new(&w, 0.5);
    // Take-off: moving apart, no impulse.
    let (r, status) = local.solve([0.3, -5.0, 1.0], &mut [0.0; 2]);
    assert_eq!((r, status), ([0.0; 3], ContactStatus::TakeOff));
    // Stick: r = −W⁻¹q = (1, 0.2, −0.1) inside the cone of µ = 0.5.
    let (r, status) = local.solve([-2.0, -0.2, 0.1], &mut [0.0; 2]);
    assert_eq!(status, ContactStatus::Stick);
    assert!((r[0] - 1.0).abs() < 1e-15 && (r[1] - 0.2).abs() < 1e-15 && (r[2] + 0.1).abs() < 1e-15);
    // Slip: r_N = −q_N / W_NN = 1, r_T = −µ r_N q_T/‖q_T‖ = −0.5 (0.6, 0.8).
    let (r, status) = local.solve([-2.0, 3.0, 4.0], &mut [0.0; 2]);
    assert_eq!(status, ContactStatus::Slip);
    for (x, e) in r.iter().zip([1.0, -0.3, -0.4]) {
        assert!((x - e).abs() < 1e-15, "{r:?}");
    }
}

#[test]
fn local_solver_satisfies_coulomb_to_1e_12_on_random_blocks() {
    // A fixed linear congruential generator: no dependency, same cases every run.
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut statuses = [0usize; 4];
    for _ in 0..20_000 {
        // W = A Aᵀ + 0.05 I: symmetric positive definite with a spread of conditions.
        let a: Vec<f64> = (0..9).map(|_| uniform()).collect();
        let mut w = [0.0; 9];
        for i in 0..3 {
            for j in 0..3 {
                w[3 * i + j] = (0..3).map(|k| a[3 * i + k] * a[3 * j + k]).sum::<f64>();
            }
            w[4 * i] += 0.05;
        }
        let q = [uniform(), 2.0 * uniform(), 2.0 * uniform()];
        let mu = 1.5 * (uniform() + 1.0) / 2.0;
        let (r, status) = LocalCoulomb::new(&w, mu).solve(q, &mut [0.0; 2]);
        statuses[status as usize] += 1;
        let scale = q.iter().map(|x| x.abs()).fold(0.0, f64::max);
        assert!(
            coulomb_error(&w, q, mu, r) <= 1e-12 * scale,
            "W {w:?} q {q:?} µ {mu}: {status:?} {r:?}"
        );
    }
    assert_eq!(statuses[ContactStatus::Fallback as usize], 0);
    assert!(statuses[..3].iter().all(|&n| n > 1000), "{statuses:?}");
}

fn nscd(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_ballast-nscd"))
        .args(args)
        .output()
        .expect("ballast-nscd runs")
}

#[test]
fn cli_prints_one_json_object() {
    let file = fc3d_dir().join("Box_Stacks-i0122-82-5.hdf5");
    let output = nscd(&["fc3d", file.to_str().unwrap(), "--tol", "1e-6", "--json"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = String::from_utf8(output.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "{text}");
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(json["contacts"], 82);
    assert!(json["iterations"].as_u64().unwrap() >= 1);
    assert!(json["error"].as_f64().unwrap() <= 1e-6);
    assert!(json["solver_time_s"].as_f64().unwrap() >= 0.0);
    assert_eq!(json["converged"], true);
}

#[test]
fn cli_prints_a_table_and_reports_errors_in_one_line() {
    let file = fc3d_dir().join("Rover4396.dat");
    let output = nscd(&["fc3d", file.to_str().unwrap(), "--max-iter", "3"]);
    assert!(output.status.success());
    let text = String::from_utf8(output.stdout).unwrap();
    for key in [
        "contacts       2",
        "iterations     3",
        "error",
        "solver time",
    ] {
        assert!(text.contains(key), "{key:?} missing in {text}");
    }
    let output = nscd(&["fc3d", "no/such/file.dat"]);
    assert_eq!(output.status.code(), Some(1));
    let err = String::from_utf8(output.stderr).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("no/such/file.dat"), "{err}");
    let output = nscd(&["fc3d", file.to_str().unwrap(), "--tol=-1"]);
    assert_eq!(output.status.code(), Some(1));
}

#[test]
fn a_truncated_dat_file_is_named_with_the_token() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.dat");
    let text = std::fs::read_to_string(fc3d_dir().join("Rover4396.dat")).unwrap();
    std::fs::write(&path, &text[..text.len() / 2]).unwrap();
    let err = fc3d::read(&path).unwrap_err().to_string();
    assert!(
        err.contains("cut.dat") && err.contains("ends before"),
        "{err}"
    );
}
