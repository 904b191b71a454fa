//! Helpers shared by the integration tests: the project's venv Python and VTK read-back.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

/// An empty directory `name` under Cargo's scratch directory for integration tests
/// (`target/tmp`), for outputs several tests read: each test run replaces the last
/// one's, where a kept temporary directory would leave one more in /tmp every run.
pub fn shared_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The venv's Python: `BALLAST_PYTHON`, else `.venv/bin/python` in the crate root.
pub fn python() -> PathBuf {
    let python = match std::env::var_os("BALLAST_PYTHON") {
        Some(path) => PathBuf::from(path),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python"),
    };
    assert!(
        python.exists(),
        "{} not found: run `make setup` to create the project's venv (with the vtk wheel), \
         or set BALLAST_PYTHON to a Python that can `import vtk`",
        python.display()
    );
    python
}

/// Runs tests/vtk_read.py on `files` and returns its JSON, keyed by path.
pub fn read_with_vtk(files: &[PathBuf]) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/vtk_read.py");
    let output = Command::new(python())
        .arg(&script)
        .args(files)
        .output()
        .expect("cannot run the venv's python");
    assert!(
        output.status.success(),
        "vtk_read.py failed ({}):\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).expect("vtk_read.py printed invalid JSON")
}

/// Asserts a failed run: the given exit status, exactly one line on stderr that names
/// every `needle`, no panic, and nothing on stdout.
pub fn assert_one_line_error(output: &Output, status: i32, needles: &[&str]) -> String {
    let stderr = assert_one_line_failure(output, status, needles);
    assert!(output.stdout.is_empty(), "unexpected stdout on error");
    stderr
}

/// [`assert_one_line_error`] for a run that failed after it had started (and printed
/// its progress on stdout).
pub fn assert_one_line_failure(output: &Output, status: i32, needles: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).to_string();
    assert_eq!(output.status.code(), Some(status), "stderr: {stderr}");
    assert_eq!(
        stderr.trim_end().lines().count(),
        1,
        "not one line: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    for needle in needles {
        assert!(stderr.contains(needle), "{needle:?} not in: {stderr}");
    }
    stderr
}

/// The number `name` of a summary's `figures`, or a panic naming it.
pub fn figure(figures: &Value, name: &str) -> f64 {
    figures[name]
        .as_f64()
        .unwrap_or_else(|| panic!("figure {name} missing: {figures}"))
}

/// A run killed once and resumed reports two pieces in its summary `figures` — unless
/// the kill fell between writing a checkpoint and its clocks, which the resumed run
/// says on stdout. Whether the pieces were counted.
#[allow(dead_code)]
pub fn assert_two_pieces(figures: &Value, resumed: &Output) -> bool {
    if figures["wall_times_complete"] == true {
        assert_eq!(figures["pieces"], 2, "{figures}");
        true
    } else {
        let out = String::from_utf8_lossy(&resumed.stdout);
        assert!(out.contains("no wall times for step"), "{out}");
        false
    }
}

/// Spawns `command` (its output discarded), waits until it has written `checkpoint`
/// (panics if it ends first, or after 300 s), lets it run `after` longer and returns
/// the running child, for the caller to kill with SIGKILL.
pub fn spawn_until_checkpoint(
    command: &mut Command,
    checkpoint: &Path,
    after: std::time::Duration,
) -> std::process::Child {
    let mut child = command
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while !checkpoint.exists() {
        assert!(started.elapsed().as_secs() < 300, "no checkpoint written");
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before a checkpoint"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(after);
    child
}

/// Runs `command` until it has written `dir/checkpoint.bin`, kills it with SIGKILL
/// and checks it was killed before its end (`end_file`, written last, not there yet).
pub fn kill_at_first_checkpoint(command: &mut Command, dir: &Path, end_file: &str) {
    let mut child = spawn_until_checkpoint(
        command,
        &dir.join("checkpoint.bin"),
        std::time::Duration::ZERO,
    );
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(!dir.join(end_file).exists(), "killed before the end");
}

/// Checks that each of `files` (relative paths) has the same bytes in `dir` as in
/// `whole` (a run left alone), naming the file and what `dir` went through (`after`).
pub fn assert_same_bytes(whole: &Path, dir: &Path, files: &[&str], after: &str) {
    for file in files {
        let (a, b) = (
            std::fs::read(whole.join(file)).unwrap(),
            std::fs::read(dir.join(file)).unwrap(),
        );
        assert!(a == b, "{file} differs after {after}");
    }
}

/// A numeric CSV written by the tools: its header and its rows.
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}
