//! Scene loading end to end on the fixture files of `tests/fixtures/scenes/`: presets,
//! the default output directory, and one test per kind of bad input, each checking that
//! the error is one line naming the file, the key and the reason.

use std::path::{Path, PathBuf};
use std::process::Command;

use ballast::scene::{
    load_scene, load_scene_with_source, Length, Material, RunArgs, Summary, Time, Validate,
    Validator,
};
use serde::Deserialize;

/// A scene struct in the shape every solver defines.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TestScene {
    steps: usize,
    dt: Time,
    material: Material,
    mesh: MeshOptions,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshOptions {
    element_size: Length,
    order: u8,
}

impl Validate for TestScene {
    fn validate(&self, v: &mut Validator) {
        v.check("steps", self.steps > 0, "must be at least 1");
        v.positive("dt", self.dt);
        v.nested("material", &self.material);
        v.nested("mesh", &self.mesh);
    }
}

impl Validate for MeshOptions {
    fn validate(&self, v: &mut Validator) {
        v.positive("element_size", self.element_size);
        v.check("order", matches!(self.order, 1 | 2), "must be 1 or 2");
    }
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/scenes")
        .join(name)
}

/// Loads a fixture that must fail; checks the message is one line naming the file and
/// containing every expected fragment, and returns it.
fn failure(name: &str, preset: Option<&str>, expected: &[&str]) -> String {
    let path = fixture(name);
    let err = load_scene::<TestScene>(&path, preset).expect_err("the scene should be rejected");
    let message = err.to_string();
    assert!(!message.contains('\n'), "not one line: {message:?}");
    assert!(
        message.starts_with(&format!("{}: ", path.display())),
        "does not start with the file name: {message}"
    );
    for fragment in expected {
        assert!(message.contains(fragment), "{message:?} lacks {fragment:?}");
    }
    message
}

#[test]
fn valid_scene_without_preset() {
    let scene: TestScene = load_scene(&fixture("valid_presets.toml"), None).unwrap();
    assert_eq!(scene.steps, 100);
    assert_eq!(scene.dt.si(), 2e-4);
    assert_eq!(scene.material.name, "concrete");
    assert_eq!(scene.material.density.si(), 2350.0);
    assert_eq!(scene.material.young_modulus.si(), 30e9);
    assert_eq!(scene.material.poisson, 0.2);
    assert_eq!(scene.material.shear_viscosity, None);
    assert!((scene.mesh.element_size.si() - 0.010).abs() < 1e-15);
    assert_eq!(scene.mesh.order, 1);
}

#[test]
fn quick_preset_merges_deeply() {
    let (scene, inputs): (TestScene, _) =
        load_scene_with_source(&fixture("valid_presets.toml"), Some("quick")).unwrap();
    assert_eq!(scene.steps, 5);
    assert!((scene.mesh.element_size.si() - 0.025).abs() < 1e-15);
    // Keys of a merged table that the preset does not name keep their base values.
    assert_eq!(scene.mesh.order, 1);
    assert_eq!(scene.material.young_modulus.si(), 30e9);
    // The merged inputs hold the preset's values and no longer the presets.
    assert_eq!(inputs["steps"].as_integer(), Some(5));
    assert_eq!(inputs["mesh"]["element_size"].as_str(), Some("25 mm"));
    assert_eq!(inputs["mesh"]["order"].as_integer(), Some(1));
    assert!(!inputs.contains_key("preset"));

    let paper: TestScene = load_scene(&fixture("valid_presets.toml"), Some("paper")).unwrap();
    assert_eq!(paper.steps, 20000);
    assert_eq!(paper.material.young_modulus.si(), 3.1e10);
    assert_eq!(paper.material.density.si(), 2350.0);
}

#[test]
fn run_context_defaults_and_summary() {
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        run: RunArgs,
    }

    let scene = fixture("valid_presets.toml");
    let cli = Cli::try_parse_from([
        "ballast-test".as_ref(),
        scene.as_os_str(),
        "--preset".as_ref(),
        "quick".as_ref(),
    ])
    .unwrap();
    let ctx = cli.run.context().unwrap();
    assert_eq!(ctx.scene_name, "valid_presets");
    assert_eq!(ctx.out_dir, Path::new("results/valid_presets-quick"));

    let (scene, inputs): (TestScene, _) = ctx.load_scene().unwrap();
    assert_eq!(scene.steps, 5);
    let summary = Summary::new(&ctx, &inputs)
        .figure("steps_run", scene.steps)
        .to_json();
    assert_eq!(summary["scene"], "valid_presets");
    assert_eq!(summary["preset"], "quick");
    assert_eq!(summary["inputs"]["mesh"]["element_size"], "25 mm");
    assert_eq!(summary["figures"]["steps_run"], 5);
}

#[test]
fn negative_density() {
    failure(
        "negative_density.toml",
        None,
        &["key material.density: must be positive, got -2350 kg/m^3"],
    );
}

#[test]
fn poisson_ratio_of_one_half() {
    failure(
        "poisson_half.toml",
        None,
        &["key material.poisson:", "less than 0.5, got 0.5"],
    );
}

#[test]
fn unknown_nested_key() {
    failure(
        "unknown_key.toml",
        None,
        &["unknown key material.densty (expected one of: name, density, young_modulus, poisson"],
    );
}

#[test]
fn missing_key() {
    failure(
        "missing_key.toml",
        None,
        &["missing key material.young_modulus"],
    );
}

#[test]
fn wrong_unit() {
    failure(
        "wrong_unit.toml",
        None,
        &["key material.young_modulus: unit \"kg\" is not a pressure (use Pa, kPa, MPa or GPa)"],
    );
}

#[test]
fn nan_value() {
    failure(
        "nan_value.toml",
        None,
        &["key material.density: must be a finite number, got NaN"],
    );
}

#[test]
fn unknown_preset_lists_the_available_ones() {
    failure(
        "valid_presets.toml",
        Some("fast"),
        &["unknown preset \"fast\" (available: paper, quick)"],
    );
}

#[test]
fn bad_value_from_a_preset_names_the_preset() {
    // The base alone is valid.
    load_scene::<TestScene>(&fixture("bad_preset.toml"), None).unwrap();
    failure(
        "bad_preset.toml",
        Some("broken"),
        &[
            "key mesh.element_size: must be positive, got -0.001 m",
            "(with preset broken)",
        ],
    );
}

#[test]
fn syntax_error_gives_the_line() {
    failure("syntax_error.toml", None, &["line 4, column "]);
}

#[test]
fn missing_file() {
    let path = fixture("no_such_scene.toml");
    let err = load_scene::<TestScene>(&path, None).unwrap_err();
    let message = err.to_string();
    assert!(!message.contains('\n'));
    assert!(
        message.starts_with(&format!("{}: ", path.display())),
        "{message}"
    );
    assert!(matches!(err, ballast::Error::Io { .. }));
}

/// Runs in a child process so that the real exit path (`cli::exit_with`) is checked:
/// bad scenes exit with status 1 and one line on stderr, and do not panic.
#[test]
fn bad_scenes_exit_non_zero_with_one_line() {
    if let Ok(name) = std::env::var("BALLAST_SCENE_LOAD_CHILD") {
        let result = load_scene::<TestScene>(&fixture(&name), None).map(|_| ());
        ballast::cli::exit_with("ballast-test", result);
    }
    for name in ["negative_density.toml", "unknown_key.toml"] {
        let output = Command::new(std::env::current_exe().unwrap())
            .args([
                "--exact",
                "bad_scenes_exit_non_zero_with_one_line",
                "--nocapture",
                "--test-threads",
                "1",
            ])
            .env("BALLAST_SCENE_LOAD_CHILD", name)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{name}: {stderr}");
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{name}: {stderr}");
        assert!(lines[0].starts_with("ballast-test: error: "), "{stderr}");
        assert!(lines[0].contains(name), "{stderr}");
    }
}
