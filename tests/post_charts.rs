//! `ballast-post speed-accuracy` on summaries laid out as ballast-qdem and ballast-fem
//! write them: the table's reference and errors, and the chart files (SVG parsed, PNG
//! signature and size).

use std::path::Path;
use std::process::Command;

const POST: &str = env!("CARGO_BIN_EXE_ballast-post");

fn write_summary(dir: &Path, name: &str, figures: serde_json::Value, wall: f64) {
    let run = dir.join(name);
    std::fs::create_dir_all(&run).unwrap();
    let summary = serde_json::json!({
        "scene": "cantilever_static",
        "inputs": {"material": {"density": "2350 kg/m^3"}},
        "figures": figures,
        "wall_time_s": {"stepping": wall},
    });
    std::fs::write(run.join("summary.json"), summary.to_string()).unwrap();
}

#[test]
fn speed_accuracy_table_and_chart() {
    let dir = tempfile::tempdir().unwrap();
    let volume = 0.132;
    // FEM deflections 1 − 3h² at three meshes (h from the tetra count): the Richardson
    // reference of the two finest is exactly 1 (order 2), so each error is 3h².
    let h = |tetra: f64| (6.0 * 2f64.sqrt() * volume / tetra).cbrt();
    for (i, tetra) in [1000.0, 8000.0, 64000.0].into_iter().enumerate() {
        let hh = h(tetra);
        write_summary(
            dir.path(),
            &format!("fem{i}"),
            serde_json::json!({"command": "static", "tetra": tetra as u64,
                "mass_kg": 2350.0 * volume, "tip_deflection_m": 1.0 - 3.0 * hh * hh}),
            0.1 * (i + 1) as f64,
        );
    }
    write_summary(
        dir.path(),
        "qdem",
        serde_json::json!({"stable_dt_s": 1e-6, "dt_s": 8e-7, "tetra": 8000,
            "volume_m3": volume, "tip_deflection_m": 0.99}),
        5.0,
    );
    let prefix = dir.path().join("out/chart");
    let output = Command::new(POST)
        .args(["speed-accuracy", dir.path().to_str().unwrap(), "--out"])
        .arg(&prefix)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let table = std::fs::read_to_string(prefix.with_extension("md")).unwrap();
    assert!(table.contains("reference 1000000.00000 µm"), "{table}");
    assert!(table.contains("| QDEM dt = 0.80 × stable |"), "{table}");
    assert!(table.contains("| -1.000 % | 5.00 |"), "{table}");
    assert!(
        table.contains("FEM: observed order | | | | 2.00 |"),
        "{table}"
    );
    let svg = std::fs::read_to_string(prefix.with_extension("svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains("tip deflection error vs wall time"));
    let png = std::fs::read(prefix.with_extension("png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(png.len() > 10_000);

    // Nothing to chart: one clear line, non-zero exit.
    let empty = tempfile::tempdir().unwrap();
    let output = Command::new(POST)
        .args(["speed-accuracy", empty.path().to_str().unwrap(), "--out"])
        .arg(&prefix)
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let err = String::from_utf8_lossy(&output.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("no cantilever summary.json"), "{err}");
}
