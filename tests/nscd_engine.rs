//! The NSCD engine's acceptance scenes through `ballast-nscd`, quick presets: each run's
//! `summary.json` figure against its analytic or physical bound, plus the output files
//! (VTK grains and contacts, residuals CSV) read back, and one-line errors on bad input.
//!
//! `drop_box` needs the stone meshes of `make meshes` (meshes/stones/stone_*.msh).

mod common;

use common::figure;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

const NSCD: &str = env!("CARGO_BIN_EXE_ballast-nscd");

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs a scene's quick preset into `out` and returns its figures.
fn run_quick(scene: &str, out: &Path) -> Value {
    run_quick_with(scene, &[], out)
}

/// Runs a scene's quick preset with extra arguments (`--set`, `--threads`) into `out`
/// and returns its figures.
fn run_quick_with(scene: &str, args: &[&str], out: &Path) -> Value {
    let output = Command::new(NSCD)
        .arg(root().join("scenes").join(scene))
        .args(["--preset", "quick"])
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .expect("ballast-nscd runs");
    assert!(
        output.status.success(),
        "{scene} {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let summary: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(summary["preset"], "quick");
    summary["figures"].clone()
}

/// Runs `ballast-nscd SCENE --out OUT` and returns what it did (for bad scenes).
fn run_scene(scene: &Path, out: &Path) -> std::process::Output {
    Command::new(NSCD)
        .arg(scene)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn incline_block_sticks_below_and_slides_above_the_friction_angle() {
    let dir = tempfile::tempdir().unwrap();
    let f = run_quick("incline.toml", dir.path());
    // a = g (sin 20° − 0.2 cos 20°). The block slides on four corner contacts whose
    // normal impulses sum to m g cos α h exactly once NLGS has converged (tolerance
    // 1e-10), so the acceleration is exact up to that tolerance: 1e-6 leaves room for
    // it and still is 10⁴ times tighter than the 1 % of the acceptance.
    let expected = 9.81 * (20f64.to_radians().sin() - 0.2 * 20f64.to_radians().cos());
    assert!((figure(&f, "slide_acceleration_expected_m_per_s2") - expected).abs() < 1e-12);
    assert!(
        figure(&f, "slide_acceleration_relative_error") < 1e-6,
        "{f}"
    );
    // µ = 0.6 > tan 20°: the sticker stays put (to rounding: 1 nm over 0.2 s).
    assert!(figure(&f, "sticker_displacement_m") < 1e-9, "{f}");
    assert!(figure(&f, "max_interpenetration_m") < 1e-9, "{f}");
    assert_eq!(figure(&f, "unconverged_steps"), 0.0);
}

#[test]
fn cube_stack_stays_at_rest_for_ten_seconds() {
    let dir = tempfile::tempdir().unwrap();
    let f = run_quick("cube_stack.toml", dir.path());
    assert!((figure(&f, "steps") * figure(&f, "dt_s") - 10.0).abs() < 1e-9);
    // Acceptance: every vertex within 1 µm of its start, interpenetration below 1 µm.
    assert!(figure(&f, "max_drift_m") < 1e-6, "{f}");
    assert!(figure(&f, "max_interpenetration_m") < 1e-6, "{f}");
    assert_eq!(figure(&f, "unconverged_steps"), 0.0, "{f}");
    // Read back the outputs: one residual row per step, VTK collections listed.
    let csv = std::fs::read_to_string(dir.path().join("residuals.csv")).unwrap();
    assert!(csv.starts_with("time_s,contacts,warm_started,nlgs_sweeps,nlgs_error,"));
    assert_eq!(csv.lines().count() as f64, figure(&f, "steps") + 1.0);
    // Warm starts: after the first step every contact is found again (persistent ids).
    let second: Vec<f64> = csv
        .lines()
        .nth(2)
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(second[1], 40.0);
    assert_eq!(second[2], 40.0);
    // No DDM: no interface, and nothing measured on it (the last two columns).
    assert!(csv
        .lines()
        .next()
        .unwrap()
        .ends_with(",interface_contacts,interface_mean_interpenetration_m"));
    assert_eq!(second[second.len() - 2..], [0.0, 0.0]);
    // The strongest contact: the floor's four corner contacts carry the ten 2.7 kg
    // cubes, W = 264.87 N in all; each pushes (≥ 0), so the largest lies between W/4
    // and W (a self-stress, or an impulse not divided by the step, would leave it).
    let (header, rows) = common::read_csv(&dir.path().join("residuals.csv"));
    let force = header
        .iter()
        .position(|h| h == "max_contact_force_N")
        .unwrap();
    let weight = 10.0 * 2700.0 * 0.1f64.powi(3) * 9.81;
    for row in rows.iter().skip(1) {
        let f = row[force];
        assert!(
            f >= weight / 4.0 * (1.0 - 1e-6) && f <= weight * (1.0 + 1e-6),
            "strongest contact {f} N against W = {weight} N"
        );
    }
    let grains = std::fs::read_to_string(dir.path().join("grains.pvd")).unwrap();
    assert!(grains.contains("frames/grains_0000.vtu"));
    let vtu = std::fs::read_to_string(dir.path().join("frames/grains_0001.vtu")).unwrap();
    assert!(vtu.contains("velocity_m_per_s") && vtu.contains("Name=\"id\""));
    let contacts = std::fs::read_to_string(dir.path().join("frames/contacts_0001.vtu")).unwrap();
    assert!(contacts.contains("normal_impulse_N_s") && contacts.contains("tangential_impulse_N_s"));
}

#[test]
fn dropped_stones_lose_energy_and_settle_without_sinking() {
    let stones = root().join("meshes/stones");
    assert!(
        stones.join("stone_001.msh").exists(),
        "meshes/stones is missing: run `make meshes` first"
    );
    let dir = tempfile::tempdir().unwrap();
    let f = run_quick("drop_box.toml", dir.path());
    assert_eq!(figure(&f, "dynamic_bodies"), 27.0);
    // ΔKE − W_gravity per step: contacts only dissipate, so ≤ 0 up to the NLGS
    // tolerance; allow 1e-6 of the total work of gravity.
    assert!(figure(&f, "max_energy_rise_relative") <= 1e-6, "{f}");
    // Acceptance: final mean interpenetration below 0.1 % of d50 (measured 6.5e-6;
    // the full 200-stone preset 4.8e-6).
    assert!(
        figure(&f, "final_mean_interpenetration_over_d50") < 1e-3,
        "{f}"
    );
    // And no stone sunk into another: the deepest final overlap is below 0.5 % of d50
    // (measured 8.3e-4 = 33 µm; the full preset 6.0e-4; before the separating-axis
    // narrow phase the full preset ended at 0.197 = 7.8 mm).
    assert!(
        figure(&f, "final_max_interpenetration_over_d50") < 5e-3,
        "{f}"
    );
    // Settling: 99 % of the peak kinetic energy is gone by the end (measured 99.8 %).
    assert!(
        figure(&f, "final_kinetic_energy_J") < 1e-2 * figure(&f, "max_kinetic_energy_J"),
        "{f}"
    );
}

#[test]
fn bad_scenes_are_one_line_errors_naming_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    let base = std::fs::read_to_string(root().join("scenes/incline.toml")).unwrap();
    for (from, to, key) in [
        ("theta = 0.5", "theta = 0.2", "time.theta"),
        ("mu = 0.2", "mu = -1", "friction[0].mu"),
        (
            "material = \"steel\"",
            "material = \"iron\"",
            "plane[0].material",
        ),
        (
            "slider = \"slider\"",
            "slider = \"nobody\"",
            "analysis.slider",
        ),
    ] {
        std::fs::write(&scene, base.replacen(from, to, 1)).unwrap();
        let output = run_scene(&scene, &dir.path().join("out"));
        assert_eq!(output.status.code(), Some(1));
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains("bad.toml") && stderr.contains(key),
            "{key}: {stderr}"
        );
    }
}

#[test]
fn driven_box_and_tine_push_blocks_at_their_speed_against_floor_friction() {
    assert!(
        root().join("meshes/tine.msh").exists(),
        "meshes/tine.msh is missing: run `make meshes` first"
    );
    let dir = tempfile::tempdir().unwrap();
    let f = run_quick("push_box.toml", dir.path());
    // Two blocks, a floor, the box and the tine's two convex pieces.
    assert_eq!(figure(&f, "bodies"), 6.0);
    assert_eq!(figure(&f, "dynamic_bodies"), 2.0);
    // Once the tools move at a constant 0.2 m/s (after 0.15 s: 151 steps of the quick
    // run), each block slides at the tool's velocity and the impulse the tool gives it
    // per step is the floor's Coulomb friction µ m g h. The frictionless tool face
    // leaves the floor the whole weight, so this is exact up to the NLGS tolerance
    // (1e-10): 1e-6 is 10⁴ times tighter than the 1 % acceptance (measured 4e-13).
    let expected = 0.5 * 2.7 * 9.81 * 1e-3;
    assert!((figure(&f, "push_block_impulse_expected_N_s") - expected).abs() < 1e-12);
    assert!(
        (figure(&f, "push_small_block_impulse_expected_N_s") - 0.5 * 0.5832 * 9.81e-3).abs()
            < 1e-12
    );
    for name in ["block", "small_block"] {
        assert_eq!(figure(&f, &format!("push_{name}_samples")), 151.0, "{f}");
    }
    assert!(figure(&f, "push_max_impulse_relative_error") < 1e-6, "{f}");
    assert!(figure(&f, "push_max_velocity_relative_error") < 1e-6, "{f}");
    // Driven positions integrate the prescribed velocity table exactly (θ = 0.5,
    // breakpoints on step boundaries): rounding only.
    assert!(figure(&f, "driven_max_position_error_m") < 1e-12, "{f}");
    assert!(figure(&f, "max_interpenetration_m") < 1e-9, "{f}");
    assert_eq!(figure(&f, "unconverged_steps"), 0.0, "{f}");
    // The tools are written to their own VTK collection, moving.
    let pvd = std::fs::read_to_string(dir.path().join("driven.pvd")).unwrap();
    assert!(pvd.contains("frames/driven_0003.vtu"));
    let vtu = std::fs::read_to_string(dir.path().join("frames/driven_0003.vtu")).unwrap();
    assert!(vtu.contains("velocity_m_per_s") && vtu.contains("RangeMax=\"0.2\""));

    // Bad driven-body input: one line naming the file and the key, exit status 1.
    let scene = dir.path().join("bad.toml");
    let base = std::fs::read_to_string(root().join("scenes/push_box.toml"))
        .unwrap()
        .replace(
            "../meshes/tine.msh",
            &root().join("meshes/tine.msh").display().to_string(),
        );
    for (from, to, key) in [
        (
            "size = [\"0.05 m\", \"0.2 m\", \"0.1 m\"]",
            "size = [\"0.05 m\", \"-0.2 m\", \"0.1 m\"]",
            "key box[0].size[1]",
        ),
        (
            "times = [\"0 s\", \"0.1 s\"]",
            "times = [\"0.1 s\", \"0 s\"]",
            "key box[0].velocity",
        ),
        (
            "convex = [\"blade\", \"shank\"]",
            "convex = [\"paddle\"]",
            "key driven[0].convex",
        ),
        ("tine.msh\"", "no_tine.msh\"", "key driven[0].mesh"),
        (
            "pushed = [\"block\", \"small_block\"]",
            "pushed = [\"block\"]",
            "analysis.pushed",
        ),
    ] {
        assert!(base.contains(from), "{from}");
        std::fs::write(&scene, base.replacen(from, to, 1)).unwrap();
        let output = run_scene(&scene, &dir.path().join("out"));
        assert_eq!(output.status.code(), Some(1), "{key}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
        assert!(
            stderr.contains("bad.toml") && stderr.contains(key),
            "{key}: {stderr}"
        );
    }
}

/// Runs drop_box's quick preset with `[ddm]` set by `--set` on `threads` threads.
fn run_drop_box_ddm(driver: &str, threads: usize, out: &Path) -> Value {
    let (driver, threads) = (format!("ddm.driver=\"{driver}\""), threads.to_string());
    let args = [
        "--threads",
        &threads,
        "--set",
        &driver,
        "--set",
        "ddm.slabs=2",
    ];
    run_quick_with("drop_box.toml", &args, out)
}

#[test]
fn ddm_drivers_settle_the_drop_box_and_do_not_depend_on_the_thread_count() {
    // Issue #7: the synchronous DDM (two slabs, subdomains in parallel, then the
    // interface) gives the same run on 1 and 2 threads, step by step (residuals.csv:
    // contacts, sweeps, NLGS error, interpenetration and energies of every step).
    let dir = tempfile::tempdir().unwrap();
    let (one, two, asyn) = (
        dir.path().join("sync-1"),
        dir.path().join("sync-2"),
        dir.path().join("async-2"),
    );
    let f = run_drop_box_ddm("synchronous", 1, &one);
    run_drop_box_ddm("synchronous", 2, &two);
    let residuals = |d: &Path| std::fs::read(d.join("residuals.csv")).unwrap();
    assert!(
        residuals(&one) == residuals(&two),
        "residuals.csv differs between 1 and 2 threads"
    );
    // Both drivers keep drop_box's physical checks (the bounds of the plain test).
    let g = run_drop_box_ddm("asynchronous", 2, &asyn);
    for (driver, f) in [("synchronous", &f), ("asynchronous", &g)] {
        assert!(
            figure(f, "max_energy_rise_relative") <= 1e-6,
            "{driver}: {f}"
        );
        assert!(
            figure(f, "final_mean_interpenetration_over_d50") < 1e-3,
            "{driver}: {f}"
        );
        assert!(
            figure(f, "final_max_interpenetration_over_d50") < 5e-3,
            "{driver}: {f}"
        );
        assert!(
            figure(f, "final_kinetic_energy_J") < 1e-2 * figure(f, "max_kinetic_energy_J"),
            "{driver}: {f}"
        );
    }
    // The interface's own interpenetration (residuals.csv): contacts on Γ while the
    // stones land, some of them overlapping, and a mean over Γ's pushing contacts that
    // no contact's overlap exceeds.
    for (driver, d) in [("synchronous", &two), ("asynchronous", &asyn)] {
        let (header, rows) = common::read_csv(&d.join("residuals.csv"));
        let column = |name: &str| header.iter().position(|h| h == name).unwrap();
        let (n, mean, max) = (
            column("interface_contacts"),
            column("interface_mean_interpenetration_m"),
            column("max_interpenetration_m"),
        );
        assert!(
            rows.iter().any(|r| r[n] > 0.0),
            "{driver}: never a contact on Γ"
        );
        assert!(
            rows.iter().any(|r| r[mean] > 0.0),
            "{driver}: Γ never overlaps"
        );
        for r in &rows {
            assert!(r[mean] >= 0.0 && r[mean] <= r[max], "{driver}: {r:?}");
        }
    }
    // Every grain of the last frame carries its subdomain (0 or 1), read by VTK.
    let frames: Vec<PathBuf> = std::fs::read_dir(two.join("frames"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().contains("grains_"))
        .collect();
    let last = frames.iter().max().unwrap().clone();
    let read = common::read_with_vtk(std::slice::from_ref(&last));
    let grid = &read[last.to_str().unwrap()];
    let field = grid["cell_data"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["name"] == "subdomain")
        .expect("a subdomain cell field");
    let values: Vec<i64> = field["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap())
        .collect();
    assert_eq!(values.len() as u64, grid["n_cells"].as_u64().unwrap());
    assert!(values.iter().all(|&d| d == 0 || d == 1), "{values:?}");
    assert!(
        values.contains(&0) && values.contains(&1),
        "both slabs hold grains"
    );
}
