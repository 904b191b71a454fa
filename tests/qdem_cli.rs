//! `ballast-qdem` as a user runs it: the quick presets of the seed 004 §3 scenes, their
//! summary/CSV/VTK read back (VTK by VTK's own reader), the stable-step refusal and the
//! blow-up stop, and bad scenes.
//!
//! The quick meshes come from `make` (meshes/cantilever_h0.03.msh, _h0.05, _h0.11).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ballast::fem::{DofSet, FemModel, LinearElastic, MassKind, ModeOptions};
use ballast::mesh::read_msh;
use serde_json::Value;

const QDEM: &str = env!("CARGO_BIN_EXE_ballast-qdem");

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn run(args: &[&str]) -> Output {
    run_with(args, &[])
}

/// Runs ballast-qdem with extra environment variables (stderr is a pipe, not a
/// terminal, as in `make`'s logs; the progress interval is the default unless `env`
/// sets it).
fn run_with(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(QDEM)
        .args(args)
        .env_remove("BALLAST_PROGRESS_S")
        .envs(env.iter().copied())
        .current_dir(root())
        .output()
        .expect("cannot start ballast-qdem")
}

/// Runs a scene's quick preset into a temporary directory and returns it with the
/// summary's figures.
fn run_quick(scene: &str) -> (tempfile::TempDir, Value) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap().to_string();
    let output = run(&[scene, "--preset", "quick", "--out", &out, "--threads", "2"]);
    assert!(
        output.status.success(),
        "{scene}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    (dir, summary["figures"].clone())
}

fn f(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

#[test]
fn cantilever_static_quick_matches_the_paper_and_writes_readable_outputs() {
    let (dir, figures) = run_quick("scenes/cantilever_static.toml");
    // Seed 004 §3.1: 91.94 µm at 488 361 tetra. The quick mesh (h = 0.03 m, 24 k
    // linear tetra) is stiffer in bending; the bound for it is 5 %.
    let deflection = f(&figures, "tip_deflection_m");
    assert!(
        (deflection - 91.94045e-6).abs() < 0.05 * 91.94045e-6,
        "{deflection}"
    );
    // Dynamic relaxation has nearly converged: the quick run is short (0.045 s, the
    // critically damped first mode at ω t ≈ 7.6 leaves 0.4 %), so the last 10 % of it
    // moved the tip by less than 1 % — well inside the 5 % this preset is held to.
    assert!(f(&figures, "steady_change_last_10_percent") < 1e-2);
    // dt = "auto" is 0.8 × the stable step.
    let (dt, stable) = (f(&figures, "dt_s"), f(&figures, "stable_dt_s"));
    assert!((dt / stable - 0.8).abs() < 1e-12, "{dt} {stable}");

    // Energy balance: kinetic + strain + dissipated = work, to 1e-4 of the work.
    let (header, rows) = common::read_csv(&dir.path().join("energies.csv"));
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let last = rows.last().unwrap();
    assert!(last[col("external_work_J")] > 0.0);
    assert!(last[col("balance_error_J")].abs() < 1e-4 * last[col("external_work_J")]);
    // At rest the strain energy is half the work of a constant load (Clapeyron); short
    // of rest, strain / work = ½ δ/δ_static, and the quick run's δ is within 0.4 % of
    // static (see above): 0.5 within 3e-3.
    let ratio = last[col("strain_J")] / last[col("external_work_J")];
    assert!((ratio - 0.5).abs() < 3e-3, "{ratio}");

    // The probe series ends on the summary's value.
    let (header, rows) = common::read_csv(&dir.path().join("probes.csv"));
    assert_eq!(
        header,
        [
            "time_s",
            "tip_centre_ux_m",
            "tip_centre_uy_m",
            "tip_centre_uz_m"
        ]
    );
    let last = rows.last().unwrap();
    assert_eq!(last[3], f(&figures, "tip_deflection_z_m"));

    // The VTK series: VTK reads every frame; the last frame's displacement at the tip
    // centre node equals the probe.
    let pvd = dir.path().join("mesh.pvd");
    let read = common::read_with_vtk(std::slice::from_ref(&pvd));
    let frames = read[pvd.to_str().unwrap()]["frames"]
        .as_array()
        .expect("frames")
        .clone();
    assert!(frames.len() >= 2);
    let last_frame = &frames.last().unwrap()["frame"];
    let field = |kind: &str, name: &str| -> Value {
        last_frame[kind]
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["name"] == name)
            .unwrap_or_else(|| panic!("no {kind} {name}"))
            .clone()
    };
    assert_eq!(field("point_data", "displacement_m")["components"], 3);
    assert_eq!(field("point_data", "velocity_m_per_s")["components"], 3);
    assert_eq!(field("cell_data", "stress_Pa")["components"], 9);
    assert_eq!(field("cell_data", "von_mises_Pa")["components"], 1);
    // ballast-qdem writes its nodes in locality order (TetMesh::locality_ordered).
    let mesh = read_msh(&root().join("meshes/cantilever_h0.03.msh"))
        .unwrap()
        .locality_ordered();
    let node = mesh.group("tip_centre").unwrap().nodes[0] as usize;
    let u = &field("point_data", "displacement_m")["values"];
    let uz = f64::from_bits(u[3 * node + 2].as_u64().unwrap());
    assert_eq!(uz, last[3]);
}

#[test]
fn cantilever_vibration_quick_matches_the_lumped_mass_fem_frequency() {
    let (_dir, figures) = run_quick("scenes/cantilever_vibration.toml");
    let f_qdem = f(&figures, "first_frequency_hz");
    // The same mesh, the same clamp, the same lumped masses: the first eigenfrequency
    // of ballast-fem's K φ = ω² M φ. Central differences shift a frequency by
    // (ω dt)²/24 ≈ 1e-7 here, and the FFT peak interpolation is good to ≪ 0.1 %
    // (src/signal); 0.2 % leaves room for the little of mode 2 in the record.
    let mesh = read_msh(&root().join("meshes/cantilever_h0.05.msh")).unwrap();
    let model = FemModel::new(
        &mesh.nodes,
        &mesh.tets,
        LinearElastic {
            young_modulus: 45e9,
            poisson: 0.167,
            density: 2350.0,
        },
    )
    .unwrap();
    let fixed = DofSet::clamped(&mesh.group("fixed").unwrap().nodes);
    let options = ModeOptions {
        mass: MassKind::Lumped,
        ..ModeOptions::default()
    };
    let modes = model.modes(&fixed, 2, None, &options).unwrap();
    let f_fem = modes.frequencies_hz[0];
    assert!(
        (f_qdem - f_fem).abs() < 2e-3 * f_fem,
        "QDEM {f_qdem} Hz, FEM {f_fem} Hz"
    );
}

#[test]
fn creep_follows_the_laterally_constrained_closed_form_not_eq14() {
    let (_dir, figures) = run_quick("scenes/creep_recovery.toml");
    let cases = figures["creep"].as_array().unwrap();
    assert_eq!(cases.len(), 2);
    for case in cases {
        let name = case["name"].as_str().unwrap();
        // Relaxation time fitted to the run against 4/3 µ_D / E (constrained) and
        // µ_D / E (eq. 14). On rollers the layer is in uniaxial strain and the
        // constrained form is exact but for inertia (2 %); with the seed's free sides
        // the layer is slightly softer in shear flow (5 %).
        let ratio = f(case, "fitted_over_corrected");
        let bound = if name.ends_with("rollers") {
            0.02
        } else {
            0.05
        };
        assert!((ratio - 1.0).abs() < bound, "{name}: {ratio}");
        assert!(f(case, "fitted_over_eq14") > 1.2, "{name}: the seed's lag");
        // The corrected closed form is much the better description.
        assert!(f(case, "corrected_rms_error") < 0.3 * f(case, "eq14_rms_error"));
    }
}

#[test]
fn damped_vibration_decay_per_viscosity_is_constant_and_near_analytic() {
    let (_dir, figures) = run_quick("scenes/damped_vibration.toml");
    let analytic = f(&figures, "decay_rate_per_viscosity_analytic");
    // (4/3)(π / 0.44 m)² / (2 × 2350 kg/m³).
    assert!((analytic - 0.014462).abs() < 1e-6, "{analytic}");
    // Constant across a fourfold range of µ_D to 3 %; within 5 % of the analytic
    // first-mode rate on the coarse quick mesh (the discrete mode's wavenumber differs
    // from π/2H by the mesh's dispersion).
    assert!(f(&figures, "decay_rate_per_viscosity_max_deviation") < 0.03);
    for case in figures["decay_rate_per_viscosity"].as_array().unwrap() {
        let r = f(case, "decay_rate_per_viscosity");
        assert!((r / analytic - 1.0).abs() < 0.05, "{case}");
        assert!(f(case, "fit_r_squared") > 0.98, "{case}");
    }
}

/// A short cantilever scene on the h = 0.05 m mesh with the given `[qdem]` lines.
fn short_scene(dir: &Path, qdem: &str) -> PathBuf {
    let mesh = root().join("meshes/cantilever_h0.05.msh");
    let scene = dir.join("short.toml");
    std::fs::write(
        &scene,
        format!(
            "[mesh]\nfile = {mesh:?}\n\
             [material]\nname = \"concrete\"\ndensity = \"2350 kg/m^3\"\n\
             young_modulus = \"45 GPa\"\npoisson = 0.167\n\
             [[fix]]\ngroup = \"fixed\"\n\
             [[load]]\ngroup = \"tip\"\nforce = [\"0 N\", \"0 N\", \"-200 N\"]\n\
             [[probe]]\nname = \"tip\"\ngroup = \"tip_centre\"\n\
             [qdem]\n{qdem}\n"
        ),
    )
    .unwrap();
    scene
}

fn stderr_of(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).to_string()
}

#[test]
fn a_step_above_the_stable_one_is_refused_and_with_force_stops_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let scene = short_scene(dir.path(), "duration = \"2 ms\"\ndt_factor = 1.2");
    let scene = scene.to_str().unwrap();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();

    // Refused: one line naming the file, the key and the stable step.
    let output = run(&[scene, "--out", out]);
    assert_eq!(output.status.code(), Some(1));
    let err = stderr_of(&output);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    for needle in [
        scene,
        "qdem.dt_factor",
        "1.20 × the stable time step",
        "--force",
    ] {
        assert!(err.contains(needle), "{needle:?} not in {err}");
    }

    // Forced: the run starts, blows up and stops with a message naming the stable
    // step; no summary is written.
    let output = run(&[scene, "--out", out, "--force"]);
    assert_eq!(output.status.code(), Some(1));
    let err = stderr_of(&output);
    assert!(!err.contains("panicked"), "{err}");
    let last = err.trim_end().lines().last().unwrap();
    assert!(last.contains("unstable"), "{last}");
    assert!(last.contains("the stable time step is"), "{last}");
    assert!(last.contains("1.20 × stable"), "{last}");
    assert!(!Path::new(out).join("summary.json").exists());
}

#[test]
fn a_step_below_the_stable_one_stays_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let scene = short_scene(
        dir.path(),
        "duration = \"5 ms\"\ndt_factor = 0.9\nframes = 1",
    );
    let out = dir.path().join("out");
    let args = [scene.to_str().unwrap(), "--out", out.to_str().unwrap()];
    // Without a terminal, progress comes as lines; BALLAST_PROGRESS_S = 0 writes one at
    // every update, so this short run has them, with the step count, rate and time left.
    let output = run_with(&args, &[("BALLAST_PROGRESS_S", "0")]);
    assert!(output.status.success(), "{}", stderr_of(&output));
    let err = stderr_of(&output);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("ballast-qdem: step "))
        .collect();
    assert!(lines.len() >= 2, "{err}");
    for line in &lines {
        assert!(line.contains(" steps/s, eta "), "{line}");
    }
    let steps = |line: &str| -> (u64, u64) {
        let field = line["ballast-qdem: step ".len()..]
            .split(' ')
            .next()
            .unwrap();
        let (pos, len) = field.split_once('/').unwrap();
        (pos.parse().unwrap(), len.parse().unwrap())
    };
    let (first, len) = steps(lines[0]);
    let (last, _) = steps(lines[lines.len() - 1]);
    assert!(
        0 < first && first < last && last <= len,
        "{first} {last} {len}"
    );
    // A value that is not a number of seconds: one warning, the run goes on.
    let output = run_with(&args, &[("BALLAST_PROGRESS_S", "soon")]);
    assert!(output.status.success(), "{}", stderr_of(&output));
    let err = stderr_of(&output);
    assert!(
        err.lines()
            .any(|l| l.contains("BALLAST_PROGRESS_S=\"soon\" is not a number of seconds")),
        "{err}"
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let e = &summary["figures"]["final_energies_J"];
    // Undamped step load: kinetic + strain never exceed the work done (energy balance
    // to 1e-4 of the work), and the work is at most twice the static work
    // F δ_static (the tip swings to at most twice its static deflection).
    let work = f(e, "external_work");
    assert!(f(e, "kinetic") + f(e, "strain") <= work * (1.0 + 1e-4));
    assert!(f(e, "balance_error").abs() < 1e-4 * work);
    assert!(work < 2.0 * 200.0 * 2.0 * 92e-6, "{work}");
}

#[test]
fn bad_scenes_give_one_line_errors_naming_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let scene = short_scene(dir.path(), "duration = \"1 ms\"");
    let text = std::fs::read_to_string(&scene).unwrap();
    for (from, to, needles) in [
        (
            "group = \"fixed\"",
            "group = \"clamp\"",
            vec![
                "fix[0].group",
                "no physical group \"clamp\"",
                "cantilever_h0.05.msh",
            ],
        ),
        (
            "duration = \"1 ms\"",
            "duration = \"1 kg\"",
            vec!["qdem.duration", "not a time"],
        ),
        (
            "[[fix]]\ngroup = \"fixed\"\n",
            "[[fix]]\ngroup = \"fixed\"\ndirections = \"xw\"\n",
            vec!["fix[0].directions"],
        ),
        (
            "[qdem]\n",
            "[qdem]\ndamping = { kind = \"viscous\" }\n",
            vec!["qdem.damping.kind", "mass_proportional"],
        ),
    ] {
        let bad = dir.path().join("bad.toml");
        assert!(text.contains(from), "{from}");
        std::fs::write(&bad, text.replace(from, to)).unwrap();
        let output = run(&[
            bad.to_str().unwrap(),
            "--out",
            dir.path().join("o").to_str().unwrap(),
        ]);
        assert_eq!(output.status.code(), Some(1), "{to}");
        let err = stderr_of(&output);
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!err.contains("panicked"), "{err}");
        for needle in needles.iter().chain(&[bad.to_str().unwrap()]) {
            assert!(err.contains(needle), "{needle:?} not in {err}");
        }
    }
}
