//! The binaries as a user runs them: `--help`, the run contract, exit codes, one-line
//! errors on bad input, and the mesh gallery's VTK read back by VTK's own reader.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const BINARIES: [(&str, &str); 5] = [
    ("ballast-pack", env!("CARGO_BIN_EXE_ballast-pack")),
    ("ballast-nscd", env!("CARGO_BIN_EXE_ballast-nscd")),
    ("ballast-qdem", env!("CARGO_BIN_EXE_ballast-qdem")),
    ("ballast-fem", env!("CARGO_BIN_EXE_ballast-fem")),
    ("ballast-post", env!("CARGO_BIN_EXE_ballast-post")),
];

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn run(binary: &str, args: &[&str]) -> Output {
    Command::new(binary)
        .args(args)
        .output()
        .expect("cannot start the binary")
}

/// A gallery scene around the cube fixture, written into `dir`.
fn gallery_scene(dir: &Path, mesh: &Path, material_extra: &str) -> PathBuf {
    let scene = dir.join("gallery.toml");
    std::fs::write(
        &scene,
        format!(
            "[[material]]\nname = \"concrete\"\ndensity = \"2350 kg/m^3\"\n\
             young_modulus = \"45 GPa\"\npoisson = 0.167\n{material_extra}\n\
             [[mesh]]\nname = \"cube\"\nfile = {mesh:?}\nmaterial = \"concrete\"\n\
             groups = [\"left\", \"right\"]\n"
        ),
    )
    .unwrap();
    scene
}

#[test]
fn every_binary_explains_itself() {
    for (name, binary) in BINARIES {
        let output = run(binary, &["--help"]);
        assert!(output.status.success(), "{name} --help failed");
        let help = String::from_utf8_lossy(&output.stdout);
        assert!(help.contains("Usage:"), "{name}: {help}");
        assert!(
            help.lines().next().unwrap().len() > 30,
            "{name}: no description"
        );
    }
}

#[test]
fn a_scene_of_another_tool_is_refused_by_its_first_unknown_key() {
    // A QDEM scene given to ballast-pack: one line naming the file and the key.
    let scene = fixture("scenes/valid_presets.toml");
    let scene = scene.to_str().unwrap();
    let output = run(BINARIES[0].1, &[scene]);
    common::assert_one_line_error(&output, 1, &["valid_presets.toml", "unknown key dt"]);
}

/// Bad `[tamping]` keys are one line naming the key as the scene spells it
/// (`tamping.tine_damping`, once), before any packing is read.
#[test]
fn bad_tamping_keys_give_one_line_errors() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tamping.toml");
    for (set, needles) in [
        (
            "tamping.tine_damping=-1",
            ["key tamping.tine_damping:", "critical"],
        ),
        (
            "tamping.tine_stiffness=\"-1 MN/m\"",
            ["key tamping.tine_stiffness:", "positive"],
        ),
        (
            "tamping.tine_stiffness=\"1 MPa\"",
            ["key tamping.tine_stiffness:", "not a stiffness"],
        ),
        (
            "tamping.tine_scale=-1",
            ["key tamping.tine_scale:", "positive"],
        ),
        (
            "tamping.squeeze_time=\"1 ms\"",
            ["key tamping.squeeze_time:", "tamping.ramp"],
        ),
    ] {
        let output = run(
            BINARIES[1].1,
            &[
                scene.to_str().unwrap(),
                "--preset",
                "quick",
                "--set",
                set,
                "--set",
                "packing.file=\"/no/such/packing.toml\"",
            ],
        );
        let line = common::assert_one_line_error(&output, 1, &needles);
        assert!(!line.contains("tamping.tamping"), "{line}");
    }
}

/// The wall time between checkpoints is checked by each tool that checkpoints: a
/// negative time or a length is one line naming the key.
#[test]
fn bad_checkpoint_wall_times_give_one_line_errors() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for (binary, scene, key) in [
        (BINARIES[0].1, "bed.toml", "output.checkpoint_wall_every"),
        (
            BINARIES[1].1,
            "tamping.toml",
            "output.checkpoint_wall_every",
        ),
        (
            BINARIES[2].1,
            "track_impact.toml",
            "track.checkpoint_wall_every",
        ),
    ] {
        let scene = scenes.join(scene);
        for (value, reason) in [("\"-1 min\"", "negative"), ("\"5 m\"", "not a time")] {
            let set = format!("{key}={value}");
            let output = run(
                binary,
                &[scene.to_str().unwrap(), "--preset", "quick", "--set", &set],
            );
            common::assert_one_line_error(&output, 1, &[&format!("key {key}:"), reason]);
        }
    }
}

#[test]
fn a_missing_scene_file_is_named() {
    for (_, binary) in &BINARIES[..3] {
        let output = run(binary, &["no/such/scene.toml"]);
        common::assert_one_line_error(&output, 1, &["no/such/scene.toml"]);
    }
    let output = run(BINARIES[4].1, &["meshes", "no/such/scene.toml"]);
    common::assert_one_line_error(&output, 1, &["no/such/scene.toml"]);
}

#[test]
fn gallery_writes_vtk_that_vtk_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let scene = gallery_scene(dir.path(), &fixture("cube_tet4_100.msh"), "");
    let out = dir.path().join("out");
    let output = run(
        BINARIES[4].1,
        &[
            "meshes",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            "1",
        ],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let table = String::from_utf8_lossy(&output.stdout);
    assert!(
        table.contains("| cube | 45 | 100 | 1.000000 | 2350.00 |"),
        "{table}"
    );

    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let cube = &summary["figures"]["meshes"][0];
    assert_eq!(cube["tets"], 100);
    assert!((cube["volume_m3"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    assert_eq!(summary["inputs"]["mesh"][0]["name"], "cube");
    assert!(summary["wall_time_s"]["read"].as_f64().unwrap() >= 0.0);

    let vtu = out.join("cube.vtu");
    let read = common::read_with_vtk(std::slice::from_ref(&vtu));
    let grid = &read[vtu.to_str().unwrap()];
    assert_eq!(grid["n_points"], 45);
    assert_eq!(grid["n_cells"], 100);
    assert!(grid["cell_types"]
        .as_array()
        .unwrap()
        .iter()
        .all(|t| t == 10));
    let names: Vec<&str> = grid["cell_data"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["part", "volume_m3", "quality"]);
    // The per-tetra volumes VTK reads back add up to the cube's unit volume.
    let volume: f64 = grid["cell_data"][1]["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|bits| f64::from_bits(bits.as_u64().unwrap()))
        .sum();
    assert!((volume - 1.0).abs() < 1e-12, "volume {volume}");
}

#[test]
fn bad_scenes_and_meshes_give_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let post = BINARIES[4].1;
    let cube = fixture("cube_tet4_100.msh");

    // A negative density.
    let scene = dir.path().join("negative.toml");
    std::fs::write(
        &scene,
        std::fs::read_to_string(gallery_scene(dir.path(), &cube, ""))
            .unwrap()
            .replace("2350 kg/m^3", "-2350 kg/m^3"),
    )
    .unwrap();
    let output = run(post, &["meshes", scene.to_str().unwrap()]);
    common::assert_one_line_error(
        &output,
        1,
        &["negative.toml", "material[0].density", "must be positive"],
    );

    // An unknown key.
    let scene = gallery_scene(dir.path(), &cube, "densty = 1.0");
    let output = run(post, &["meshes", scene.to_str().unwrap()]);
    common::assert_one_line_error(&output, 1, &["gallery.toml", "unknown key", "densty"]);

    // A mesh with an inverted tetra: two nodes of the first tetra swapped.
    let text = std::fs::read_to_string(&cube).unwrap();
    let elements = text.find("$Elements").unwrap();
    let mut lines: Vec<String> = text[elements..].lines().map(String::from).collect();
    let tet_line = lines
        .iter()
        .position(|l| l.split_whitespace().count() == 5)
        .unwrap();
    let mut fields: Vec<&str> = lines[tet_line].split_whitespace().collect();
    fields.swap(1, 2);
    let element_tag = fields[0].to_string();
    lines[tet_line] = fields.join(" ");
    let inverted = dir.path().join("inverted.msh");
    std::fs::write(
        &inverted,
        text[..elements].to_string() + &lines.join("\n") + "\n",
    )
    .unwrap();
    let scene = gallery_scene(dir.path(), &inverted, "");
    let output = run(post, &["meshes", scene.to_str().unwrap()]);
    common::assert_one_line_error(
        &output,
        1,
        &[
            "inverted.msh",
            &format!("element {element_tag}"),
            "inverted",
        ],
    );

    // A physical group the scene needs but the mesh lacks.
    let scene = dir.path().join("group.toml");
    std::fs::write(
        &scene,
        std::fs::read_to_string(gallery_scene(dir.path(), &cube, ""))
            .unwrap()
            .replace("\"right\"]", "\"tip\"]"),
    )
    .unwrap();
    let output = run(post, &["meshes", scene.to_str().unwrap()]);
    common::assert_one_line_error(&output, 1, &["cube_tet4_100.msh", "\"tip\"", "missing"]);

    // A missing mesh file.
    let scene = gallery_scene(dir.path(), &dir.path().join("nowhere.msh"), "");
    let output = run(post, &["meshes", scene.to_str().unwrap()]);
    common::assert_one_line_error(&output, 1, &["nowhere.msh"]);
}
