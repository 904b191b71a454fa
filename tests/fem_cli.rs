//! `ballast-fem` as a user runs it: the quick cantilever (`--preset h005` of
//! scenes/cantilever_static.toml, h = 0.05 m, 1 549 nodes) static and modes, read back
//! (summary, CSV, VTK by VTK's own reader) and checked against the library core called
//! on the same mesh and against beam theory; a free–free body; per-component fixes; the
//! sleeper on a Winkler bed against the rigid-bounce formula; bad scenes.
//!
//! The meshes come from `make` (meshes/cantilever_h0.05.msh, meshes/sleeper_type3.msh).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ballast::fem::{DofSet, FemModel, LinearElastic, ModeOptions};
use ballast::mesh::{read_msh, TetMesh};
use nalgebra::Vector3;
use serde_json::Value;

const FEM: &str = env!("CARGO_BIN_EXE_ballast-fem");
const SCENE: &str = "scenes/cantilever_static.toml";
const QUICK_MESH: &str = "meshes/cantilever_h0.05.msh";

/// Euler–Bernoulli for the 2.4 × 0.25 × 0.22 m concrete cantilever under 200 N.
const EB_DEFLECTION: f64 = 92.3216e-6;
const EB_FREQUENCY: f64 = 26.9993;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn run(args: &[&str]) -> Output {
    Command::new(FEM)
        .args(args)
        .current_dir(root())
        .output()
        .expect("cannot start ballast-fem")
}

/// Runs `ballast-fem COMMAND SCENE ARGS… --out TMP --threads 2`; returns the directory
/// and the summary.
fn run_ok(command: &str, scene: &str, args: &[&str]) -> (tempfile::TempDir, Value) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap().to_string();
    let mut all = vec![command, scene];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--out", &out, "--threads", "2"]);
    let output = run(&all);
    assert!(
        output.status.success(),
        "ballast-fem {command} {scene}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        output.stdout.is_empty(),
        "ballast-fem writes nothing on stdout"
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    (dir, summary)
}

fn f(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn concrete() -> LinearElastic {
    LinearElastic {
        young_modulus: 45e9,
        poisson: 0.167,
        density: 2350.0,
    }
}

fn quick_mesh() -> TetMesh {
    read_msh(&root().join(QUICK_MESH)).unwrap()
}

fn clamp(mesh: &TetMesh) -> DofSet {
    DofSet::clamped(&mesh.group("fixed").unwrap().nodes)
}

/// A field of a VTK file as read back by VTK: (components, values).
fn field(read: &Value, kind: &str, name: &str) -> (u64, Vec<f64>) {
    let array = read[kind]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["name"] == name)
        .unwrap_or_else(|| panic!("no {kind} {name}"));
    let values = array["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| f64::from_bits(b.as_u64().unwrap()))
        .collect();
    (array["components"].as_u64().unwrap(), values)
}

fn scene_file(dir: &Path, name: &str, body: &str) -> PathBuf {
    let mesh = root().join(QUICK_MESH);
    let text = format!(
        "[mesh]\nfile = {mesh:?}\n\n[material]\nname = \"concrete\"\ndensity = \"2350 kg/m^3\"\n\
         young_modulus = \"45 GPa\"\npoisson = 0.167\n\n{body}"
    );
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn static_quick_matches_the_library_and_beam_theory_and_writes_readable_outputs() {
    let (dir, summary) = run_ok("static", SCENE, &["--preset", "h005"]);
    let figures = &summary["figures"];
    let deflection = f(figures, "tip_deflection_m");

    // The same mesh through the library: clamp "fixed", 200 N down spread equally over
    // the nodes of "tip", |u| at the "tip_centre" node. The binary must reproduce it to
    // round-off (same assembly, same ordering, same factorisation).
    let mesh = quick_mesh();
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let tip = &mesh.group("tip").unwrap().nodes;
    let mut loads = vec![Vector3::zeros(); mesh.nodes.len()];
    for &n in tip {
        loads[n as usize] = Vector3::new(0.0, 0.0, -200.0 / tip.len() as f64);
    }
    let solution = model.static_solve(&clamp(&mesh), &loads).unwrap();
    let centre = mesh.group("tip_centre").unwrap().nodes[0] as usize;
    let expected = solution.displacement[centre].norm();
    assert!(
        ((deflection - expected) / expected).abs() < 1e-10,
        "binary {deflection:e} vs library {expected:e}"
    );
    // Beam theory: linear tetra at h = 0.05 m (4–5 elements through the depth) are
    // about 12 % too stiff in bending (shear locking; scenes/cantilever_static.toml),
    // so Euler–Bernoulli (92.32 µm; Timoshenko adds 0.6 %) is met within 15 %, and
    // from below.
    let error = (deflection - EB_DEFLECTION) / EB_DEFLECTION;
    assert!((-0.15..0.0).contains(&error), "{deflection:e}: {error:+.3}");

    // Equilibrium: the supports carry the 200 N.
    let reaction = floats(&figures["reaction_total_N"]);
    assert!((reaction[2] - 200.0).abs() < 1e-6, "{reaction:?}");
    assert!(reaction[0].abs() < 1e-6 && reaction[1].abs() < 1e-6);
    assert_eq!(figures["nodes"], 1549);
    assert_eq!(figures["dofs"], 3 * 1549);
    assert_eq!(
        f(figures, "free_dofs") + f(figures, "fixed_dofs"),
        3.0 * 1549.0
    );
    for phase in [
        "read mesh",
        "assembly",
        "ordering",
        "factorisation",
        "solve",
    ] {
        assert!(
            summary["wall_time_s"][phase].as_f64().unwrap() >= 0.0,
            "{phase}"
        );
    }

    // probes.csv: QDEM's column names, one row, the summary's value.
    let (header, rows) = common::read_csv(&dir.path().join("probes.csv"));
    assert_eq!(
        header,
        ["tip_centre_ux_m", "tip_centre_uy_m", "tip_centre_uz_m"]
    );
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0][2], f(figures, "tip_deflection_z_m"));

    // static.vtu read by VTK: displacement at the probe node equals the probe; stress
    // and von Mises per tetra.
    let vtu = dir.path().join("static.vtu");
    let read = common::read_with_vtk(std::slice::from_ref(&vtu));
    let read = &read[vtu.to_str().unwrap()];
    assert_eq!(read["n_points"], 1549);
    let (components, u) = field(read, "point_data", "displacement_m");
    assert_eq!(components, 3);
    assert_eq!(u[3 * centre + 2], rows[0][2]);
    let (components, stress) = field(read, "cell_data", "stress_Pa");
    assert_eq!(components, 9);
    assert_eq!(stress.len(), 9 * mesh.tets.len());
    let (components, mises) = field(read, "cell_data", "von_mises_Pa");
    assert_eq!(components, 1);
    let max = mises.iter().copied().fold(0.0, f64::max);
    assert_eq!(max, f(figures, "max_von_mises_Pa"));
    // Root bending stress of the beam, M c / I = P L (h/2) / I = 238 kPa: the largest
    // tetra value is of that order.
    let root_stress = 200.0 * 2.4 * 0.11 / (0.25 * 0.22f64.powi(3) / 12.0);
    assert!(max > 0.5 * root_stress && max < 1.5 * root_stress, "{max}");
}

#[test]
fn modes_quick_are_positive_increasing_and_match_the_library() {
    let (dir, summary) = run_ok("modes", SCENE, &["--preset", "h005"]);
    let figures = &summary["figures"];
    let frequencies = floats(&figures["frequencies_hz"]);
    assert_eq!(frequencies.len(), 4);
    assert!(frequencies[0] > 0.0);
    assert!(
        frequencies.windows(2).all(|w| w[1] >= w[0]),
        "{frequencies:?}"
    );
    assert_eq!(f(figures, "first_frequency_hz"), frequencies[0]);
    assert_eq!(figures["rigid_body_modes_skipped"], 0);

    // The library on the same mesh and clamp (consistent mass, default options).
    let mesh = quick_mesh();
    let model = FemModel::new(&mesh.nodes, &mesh.tets, concrete()).unwrap();
    let modes = model
        .modes(&clamp(&mesh), 4, None, &ModeOptions::default())
        .unwrap();
    for (binary, library) in frequencies.iter().zip(&modes.frequencies_hz) {
        assert!(
            ((binary - library) / library).abs() < 1e-10,
            "{binary} vs {library}"
        );
    }
    // Euler–Bernoulli 27.00 Hz: the stiff coarse tetra put the first mode 6 % above it.
    let error = (frequencies[0] - EB_FREQUENCY) / EB_FREQUENCY;
    assert!((0.0..0.10).contains(&error), "{error:+.3}");
    // Shapes: vertical bending first (the beam is less deep, 0.22 m, than wide,
    // 0.25 m), then lateral bending; the clamped first modes have no node.
    let kinds: Vec<&str> = figures["modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["shape"]["kind"].as_str().unwrap())
        .collect();
    assert_eq!(&kinds[..2], ["vertical_bending", "lateral_bending"]);
    assert_eq!(figures["modes"][0]["shape"]["centreline_sign_changes"], 0);

    // frequencies.csv and the mode shapes, read by VTK: one frame per mode, normalised
    // to max |u| = 1.
    let (header, rows) = common::read_csv(&dir.path().join("frequencies.csv"));
    assert_eq!(header, ["mode", "frequency_hz"]);
    assert_eq!(rows.len(), 4);
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[0], (i + 1) as f64);
        assert_eq!(row[1], frequencies[i]);
    }
    let pvd = dir.path().join("modes.pvd");
    let read = common::read_with_vtk(std::slice::from_ref(&pvd));
    let frames = read[pvd.to_str().unwrap()]["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 4);
    for frame in frames {
        let (components, u) = field(&frame["frame"], "point_data", "displacement_m");
        assert_eq!(components, 3);
        let max = u
            .chunks(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .fold(0.0, f64::max);
        assert!((max - 1.0).abs() < 1e-12, "{max}");
    }
    // The clamped nodes do not move.
    let (_, u) = field(&frames[0]["frame"], "point_data", "displacement_m");
    for &n in &mesh.group("fixed").unwrap().nodes {
        assert_eq!(&u[3 * n as usize..3 * n as usize + 3], [0.0; 3]);
    }
}

#[test]
fn both_gives_the_static_and_modes_results_in_one_process_on_one_factor() {
    let (_s, statics) = run_ok("static", SCENE, &["--preset", "h005"]);
    let (_m, modes) = run_ok("modes", SCENE, &["--preset", "h005"]);
    let (dir, both) = run_ok("both", SCENE, &["--preset", "h005"]);
    let figures = &both["figures"];
    assert_eq!(figures["command"], "both");
    // The same system, ordering and factor as the separate runs: identical figures.
    assert_eq!(
        figures["tip_deflection_m"],
        statics["figures"]["tip_deflection_m"]
    );
    assert_eq!(
        figures["reaction_total_N"],
        statics["figures"]["reaction_total_N"]
    );
    assert_eq!(
        figures["frequencies_hz"],
        modes["figures"]["frequencies_hz"]
    );
    // The clamped cantilever's modes run with shift 0, i.e. on the factor of K that the
    // static solve computed (FemSystem keeps it): one factorisation in the process.
    assert_eq!(f(figures, "eigen_shift_rad2_per_s2"), 0.0);
    for file in ["static.vtu", "probes.csv", "modes.pvd", "frequencies.csv"] {
        assert!(dir.path().join(file).is_file(), "{file}");
    }
    for mode in 1..=4 {
        let frame = dir.path().join(format!("modes/mode_{mode:02}.vtu"));
        assert!(frame.is_file(), "{}", frame.display());
    }
}

#[test]
fn a_free_body_gives_six_rigid_modes_that_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(dir.path(), "free.toml", "[fem]\nmodes = 3\n");
    let (_out, summary) = run_ok("modes", scene.to_str().unwrap(), &[]);
    let figures = &summary["figures"];
    assert_eq!(figures["rigid_body_modes_skipped"], 6);
    let rigid = floats(&figures["rigid_body_frequencies_hz"]);
    let elastic = floats(&figures["frequencies_hz"]);
    assert_eq!(rigid.len(), 6);
    assert_eq!(elastic.len(), 3);
    // Rigid modes at round-off level, elastic ones well above: the free–free first
    // bending mode of the beam is (4.730 / 1.875)² ≈ 6.36 × the clamped one.
    assert!(
        rigid.iter().all(|r| r.abs() < 1e-3 * elastic[0]),
        "{rigid:?}"
    );
    assert!(elastic.windows(2).all(|w| w[1] >= w[0]));
    let ratio = elastic[0] / EB_FREQUENCY;
    assert!((6.0..7.2).contains(&ratio), "{elastic:?}");
    assert!(figures["rigid_body_note"]
        .as_str()
        .unwrap()
        .contains("rigid-body modes"));

    // A static solve of the free body is refused in one line naming the file and key.
    let refused = dir.path().join("refused");
    let output = run(&[
        "static",
        scene.to_str().unwrap(),
        "--out",
        refused.to_str().unwrap(),
    ]);
    assert_one_line_error(&output, &[scene.to_str().unwrap(), "key fix"]);
}

#[test]
fn a_partially_fixed_group_holds_only_its_directions() {
    let dir = tempfile::tempdir().unwrap();
    // Clamped root; the tip held in z only and pushed sideways: u_z = 0 exactly there,
    // u_y free.
    let scene = scene_file(
        dir.path(),
        "partial.toml",
        "[[fix]]\ngroup = \"fixed\"\n\n[[fix]]\ngroup = \"tip\"\ndirections = \"z\"\n\n\
         [[load]]\ngroup = \"tip\"\nforce = [\"0 N\", \"500 N\", \"-200 N\"]\n\n\
         [[probe]]\nname = \"tip_centre\"\ngroup = \"tip_centre\"\n",
    );
    let (out, summary) = run_ok("static", scene.to_str().unwrap(), &[]);
    let figures = &summary["figures"];
    let probe = &figures["probes"]["tip_centre"];
    assert_eq!(f(probe, "uz_m"), 0.0);
    assert!(f(probe, "uy_m") > 1e-6, "{probe}");
    // No [analysis]: one displacement figure per probe.
    assert_eq!(
        f(figures, "tip_centre_displacement_m"),
        f(probe, "magnitude_m")
    );
    // The tip support carries the −200 N, the root only the sideways load.
    let reaction = floats(&figures["reaction_total_N"]);
    assert!((reaction[1] + 500.0).abs() < 1e-6 && (reaction[2] - 200.0).abs() < 1e-6);
    let (header, _) = common::read_csv(&out.path().join("probes.csv"));
    assert_eq!(header.len(), 3);
}

#[test]
fn the_sleeper_on_a_winkler_bed_bounces_at_the_rigid_body_frequency() {
    let (_dir, summary) = run_ok(
        "modes",
        "scenes/sleeper_modes.toml",
        &["--preset", "winkler"],
    );
    let figures = &summary["figures"];
    // Normal springs only: sliding in x, y and spinning about z are free.
    assert_eq!(figures["rigid_body_modes_skipped"], 3);
    // Rigid bounce of a 175.8 kg sleeper on 0.48 m² of a 100 MN/m³ bed:
    // f = √(C A / m) / 2π = 83.2 Hz. The sleeper is far stiffer than the bed, so the
    // bounce mode of the elastic model is within 1 % of it.
    let mass = f(figures, "mass_kg");
    let bounce = (1e8 * 0.48 / mass).sqrt() / (2.0 * std::f64::consts::PI);
    let rigid = floats(&figures["vertical_rigid_body_frequencies_hz"]);
    assert_eq!(rigid.len(), 2, "bounce and pitch: {rigid:?}");
    assert!(
        rigid.iter().any(|r| ((r - bounce) / bounce).abs() < 0.01),
        "{rigid:?} vs {bounce}"
    );
    // The first three vertical bending modes follow, in increasing order.
    let bending = floats(&figures["vertical_bending_frequencies_hz"]);
    assert!(bending.len() >= 3, "{bending:?}");
    assert!(bending.windows(2).all(|w| w[1] > w[0]));
    assert!(f(figures, "winkler_total_stiffness_N_per_m") > 0.99 * 1e8 * 0.48);
}

/// Exit status 1, one line on stderr naming every needle, nothing on stdout.
fn assert_one_line_error(output: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "stderr: {stderr}");
    assert_eq!(
        stderr.trim_end().lines().count(),
        1,
        "not one line: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} not in: {stderr}");
    }
    assert!(output.stdout.is_empty());
}

#[test]
fn bad_scenes_give_one_line_errors_naming_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out = out.to_str().unwrap();
    let both = ["static", "modes"].as_slice();
    let cases = [
        (
            "[[fix]]\ngroup = \"nope\"\n",
            vec!["key fix[0].group", "\"nope\"", "cantilever_h0.05.msh"],
            both,
        ),
        (
            "[[fix]]\ngroup = \"fixed\"\n[[load]]\ngroup = \"tipp\"\nforce = [\"0 N\", \"0 N\", \"1 N\"]\n",
            vec!["key load[0].group", "\"tipp\""],
            ["static"].as_slice(),
        ),
        (
            "[[fix]]\ngroup = \"fixed\"\n[fem]\nwinkler = [{ group = \"beam\", stiffness = \"1 MN/m^3\" }]\n",
            vec!["key fem.winkler[0].group", "no surface triangles"],
            both,
        ),
        (
            "[[fix]]\ngroup = \"fixed\"\n[fem]\nmodes = 0\n",
            vec!["key fem.modes"],
            both,
        ),
    ];
    for (i, (body, needles, commands)) in cases.iter().enumerate() {
        let scene = scene_file(dir.path(), &format!("bad{i}.toml"), body);
        let scene = scene.to_str().unwrap();
        for &command in *commands {
            let output = run(&[command, scene, "--out", out]);
            let mut all = needles.clone();
            all.push(scene);
            assert_one_line_error(&output, &all);
        }
    }
    // A missing scene file is named.
    let output = run(&["modes", "no/such/scene.toml"]);
    assert_one_line_error(&output, &["no/such/scene.toml"]);
}
