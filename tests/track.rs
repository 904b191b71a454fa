//! Issue #8: the QDEM track-impact scene end to end, as `make track` runs it — the
//! quick bed from ballast-pack, a train load from ballast-post, ballast-qdem on the
//! quick preset, the spectra — with the files read back (VTK by VTK itself).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use common::{assert_one_line_error, figure, read_csv, read_with_vtk};
use serde_json::Value;

const PACK: &str = env!("CARGO_BIN_EXE_ballast-pack");
const QDEM: &str = env!("CARGO_BIN_EXE_ballast-qdem");
const POST: &str = env!("CARGO_BIN_EXE_ballast-post");

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn ok(output: Output, what: &str) -> Output {
    assert!(
        output.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

/// The quick bed and the train load, made once (in `target/tmp`, replaced every test run).
fn inputs() -> &'static (PathBuf, PathBuf) {
    static INPUTS: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    INPUTS.get_or_init(|| {
        let dir = common::shared_dir("track-inputs");
        ok(
            Command::new(PACK)
                .arg(root().join("scenes/bed.toml"))
                .args(["--preset", "impact-quick", "--out"])
                .arg(dir.join("bed"))
                .output()
                .unwrap(),
            "ballast-pack --preset impact-quick",
        );
        let load = dir.join("train_load.csv");
        ok(
            Command::new(POST)
                .args([
                    "train-load",
                    "--cars",
                    "1",
                    "--lead-in-m",
                    "1.885",
                    "--duration-s",
                    "0.2",
                    "--out",
                ])
                .arg(&load)
                .output()
                .unwrap(),
            "ballast-post train-load",
        );
        (dir.join("bed/packing.toml"), load)
    })
}

fn qdem(out: &Path, extra: &[String]) -> Command {
    let (packing, load) = inputs();
    let mut c = Command::new(QDEM);
    c.arg(root().join("scenes/track_impact.toml"))
        .args(["--preset", "quick", "--set"])
        .arg(format!("track.packing=\"{}\"", packing.display()))
        .arg("--set")
        .arg(format!("track.loads=\"{}\"", load.display()))
        .args(extra)
        .arg("--out")
        .arg(out);
    c
}

/// The quick preset, run once.
fn quick() -> &'static Path {
    static RUN: OnceLock<PathBuf> = OnceLock::new();
    RUN.get_or_init(|| {
        let dir = common::shared_dir("track-quick");
        ok(
            qdem(&dir, &[]).output().unwrap(),
            "ballast-qdem track quick",
        );
        dir
    })
}

fn args(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

fn figures(dir: &Path) -> Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    serde_json::from_str::<Value>(&text).unwrap()["figures"].clone()
}

/// The run is stable, conserves energy, keeps its springs' overlaps physical, loads
/// the sleeper downwards through its rail seats, and samples the sensors at 10 kHz.
#[test]
fn the_quick_track_runs_and_its_sensors_see_the_axle() {
    let dir = quick();
    let f = figures(dir);
    let (packing, _) = inputs();
    let stones = std::fs::read_to_string(packing)
        .unwrap()
        .matches("[[stone]]")
        .count();
    assert_eq!(figure(&f, "stones") as usize, stones);
    assert_eq!(figure(&f, "rigid_stones") as usize, stones);
    assert!(figure(&f, "dt_s") <= figure(&f, "stable_dt_s"));
    // Energy: Verlet with trapezoidal work conserves to O(dt²); the slider and
    // dashpot terms are exact per step. Measured 2.3e-5 of the energy scale (2.6e-4
    // before the rails' hold; 2.8e-3 while the slider was counted as µ f_n times the
    // slip, which missed what a spring at the cone's edge lets go when the normal force
    // falls); 2e-3 fails with that estimate, a sign error or a missed term.
    assert!(figure(&f, "energy_balance_relative") < 2e-3, "{f}");
    // Springs of ~2 GN/m under at most the 2 × 35 kN of one axle: overlaps of µm, far
    // below 0.1 % of the stones' size (the packing's own criterion).
    assert!(
        figure(&f, "max_overlap_m") < 1e-3 * figure(&f, "stone_size_m"),
        "{f}"
    );
    assert!(figure(&f, "peak_memory_mib") > 0.0);
    assert!(figure(&f, "contact_pairs_per_s") > 0.0);

    let (header, rows) = read_csv(&dir.join("sensors.csv"));
    for name in ["S1", "S2", "S3", "B1", "B2", "B3"] {
        for c in ["ux_m", "vz_m_per_s", "az_m_per_s2"] {
            assert!(
                header.contains(&format!("{name}_{c}")),
                "{name}_{c} missing: {header:?}"
            );
        }
    }
    assert_eq!(rows[0][0], 0.0, "the sensors start at the end of settling");
    for w in rows.windows(2) {
        assert!(
            ((w[1][0] - w[0][0]) / 1e-4 - 1.0).abs() < 1e-6,
            "not 10 kHz: {:?}",
            (w[0][0], w[1][0])
        );
    }
    // track.csv: the applied load is the file's, on the same clock (t = 0 at the end
    // of settling; both sampled at 10 kHz, so the maxima over the window coincide).
    let (th, tr) = read_csv(&dir.join("track.csv"));
    let rp1 = th.iter().position(|h| h == "rp1_n").unwrap();
    let end = rows.last().unwrap()[0];
    let applied = tr
        .iter()
        .filter(|r| r[0] >= 0.0)
        .map(|r| r[rp1])
        .fold(0.0, f64::max);
    let (lh, lr) = read_csv(&inputs().1);
    let l1 = lh.iter().position(|h| h == "Rp1").unwrap();
    let given = lr
        .iter()
        .filter(|r| r[0] <= end + 1e-9)
        .map(|r| r[l1])
        .fold(0.0, f64::max);
    assert!(
        (applied / given - 1.0).abs() < 1e-6,
        "applied {applied} N, file {given} N"
    );
    // The quasi-static peak alone is W a / (2L) = 22.5 kN for a 120 kN axle.
    assert!(given > 0.85 * 22.5e3, "peak Rp1 {given} N");

    // The rails hold the sleeper ([rail]: 20 MN/m per seat, along and across the
    // track). The ballast can push it sideways with at most µ × what presses it down,
    // F ≤ 0.577 (Rp1 + Rp2 + its 1.7 kN weight); against the two seats' springs that
    // moves it F / 2k, and turns it by at most F · 1 m (the half sleeper) over the
    // seats' yaw stiffness 2k · 0.566² (the seats' centres at ±0.566 m,
    // geo/sleeper_type3.geo), 1.4 F / k more at a sensor 0.9 m out: 3.4 mm here.
    // Measured 0.62 mm; without the hold the sleeper slid 11.1 mm (S1) in this window.
    let l2 = lh.iter().position(|h| h == "Rp2").unwrap();
    let pressed = lr
        .iter()
        .filter(|r| r[0] <= end + 1e-9)
        .map(|r| r[l1] + r[l2])
        .fold(0.0, f64::max)
        + 1.7e3;
    let bound = 0.577 * pressed * (0.5 + 0.9 / (2.0 * 0.566 * 0.566)) / 20e6;
    let mut moved = 0.0f64;
    for name in ["S1", "S2", "S3"] {
        for c in ["ux_m", "uy_m"] {
            let i = header
                .iter()
                .position(|h| *h == format!("{name}_{c}"))
                .unwrap();
            moved = rows.iter().map(|r| r[i].abs()).fold(moved, f64::max);
        }
    }
    assert!(
        moved < bound,
        "the sleeper moved {moved:.3e} m sideways, beyond the rails' hold bound {bound:.3e} m"
    );
}

/// Seed 004 §4.1: the settlement "decrease[s] as the frictional coefficient µc of the
/// ballast particle increases from 0.57 to 1.73". The quick bed is packed with the
/// run's own contact spheres, so it starts at rest and settles under the axle by
/// sliding at its contacts: with µ = 1.73 on every contact it settles less than with
/// the scene's 0.577. Measured on this bed with the rails' hold: −0.70 against
/// −0.48 mm under the first axle. Over six beds (`make track-mu-ensemble`) the order
/// held under the first axle in 6 of 6 (sign test p = 0.016, µ = 1.73 settling a third
/// as much on average, the closest pair 7 % apart), so the test asks for the order:
/// it fails if friction stops mattering or turns the other way. (Without the hold the
/// sleeper slid off the stones and this bed gave −2.93 against −0.37 mm.)
#[test]
fn the_bed_settles_less_under_higher_friction() {
    let low = figures(quick());
    // At rest when the load starts: the sleeper sinks at under 2 mm/s (measured
    // 0.84 mm/s, 1.04 mm/s since the bed's release runs 0.1 s; the bed read periodic,
    // its end walls gone, sank at 5.6 mm/s, and a bed packed as rounded hulls at
    // 44 mm/s).
    let sinking = figure(&low, "sleeper_velocity_after_settling_m_per_s");
    assert!(sinking.abs() < 2e-3, "{low}");
    let dir = common::shared_dir("track-mu-1.73");
    let mu: Vec<String> = ["ballast_ballast", "ballast_sleeper", "base"]
        .iter()
        .flat_map(|k| ["--set".to_string(), format!("friction.{k}=1.73")])
        .collect();
    ok(
        qdem(&dir, &mu).output().unwrap(),
        "ballast-qdem track quick, µ = 1.73",
    );
    let high = figures(&dir);
    let (s_low, s_high) = (
        figure(&low, "sleeper_settlement_m"),
        figure(&high, "sleeper_settlement_m"),
    );
    assert!(
        s_low < 0.0 && s_low < s_high,
        "settlement µ = 0.577: {s_low} m, µ = 1.73: {s_high} m"
    );
    // `ballast-post track-compare` puts the two side by side: each run's settlement as
    // its summary has it, the reference's own spectrum difference 0, the two frictions,
    // and the charts.
    let prefix = dir.join("friction");
    ok(
        Command::new(POST)
            .arg("track-compare")
            .arg(quick())
            .arg(&dir)
            .arg("--out")
            .arg(&prefix)
            .output()
            .unwrap(),
        "ballast-post track-compare",
    );
    let text = std::fs::read_to_string(prefix.with_extension("json")).unwrap();
    let json: Value = serde_json::from_str(&text).unwrap();
    let runs = json["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2, "{json}");
    for (run, (mu, settlement)) in runs.iter().zip([(0.577, s_low), (1.73, s_high)]) {
        assert_eq!(run["friction"].as_f64(), Some(mu), "{run}");
        assert_eq!(
            run["sleeper_settlement_m"].as_f64(),
            Some(settlement),
            "{run}"
        );
    }
    // The settlement passage by passage of the load (the first bogie's axles: one
    // passage or more) adds up to the record's, from the load's start (t = 0) to its last
    // sample, since the record is cut between them. (The summary's is at the last
    // step, up to a sample later.)
    for (run, dir) in runs.iter().zip([quick(), dir.as_path()]) {
        let passages = run["passages"].as_array().expect("passages");
        assert!(!passages.is_empty(), "{run}");
        let sum: f64 = passages
            .iter()
            .map(|p| p["settlement_m"].as_f64().unwrap())
            .sum();
        let (header, rows) = read_csv(&dir.join("track.csv"));
        let column = |name: &str| header.iter().position(|h| h == name).unwrap();
        let (t, s) = (column("time_s"), column("sleeper_settlement_m"));
        let start = rows.iter().find(|r| r[t] >= -1e-9).unwrap()[s];
        let whole = rows.last().unwrap()[s] - start;
        assert!(
            (sum - whole).abs() < 1e-12,
            "passages {sum} m against {whole} m"
        );
    }
    assert_eq!(runs[0]["spectrum_difference"].as_f64(), Some(0.0), "{json}");
    assert!(
        runs[1]["spectrum_difference"].as_f64().unwrap() > 0.0,
        "{json}"
    );
    for suffix in [".md", ".svg", ".png", "_histories.svg", "_histories.png"] {
        let file = PathBuf::from(format!("{}{suffix}", prefix.display()));
        assert!(
            std::fs::metadata(&file)
                .map(|m| m.len() > 0)
                .unwrap_or(false),
            "{}",
            file.display()
        );
    }
}

/// The VTK series read back with VTK: the deformable sleeper's tetra with its fields,
/// the rigid stones' surfaces with their body ids.
#[test]
fn the_track_vtk_reads_back() {
    let dir = quick();
    let f = figures(dir);
    let json = read_with_vtk(&[dir.join("deformable.pvd"), dir.join("rigid.pvd")]);
    let deformable = &json[dir.join("deformable.pvd").to_str().unwrap()];
    let frames = deformable["frames"].as_array().unwrap();
    assert!(frames.len() >= 2);
    let last = &frames.last().unwrap()["frame"];
    assert_eq!(
        last["n_cells"].as_u64().unwrap() as f64,
        figure(&f, "tetra")
    );
    let field_names = |kind: &str| -> Vec<String> {
        last[kind]
            .as_array()
            .unwrap()
            .iter()
            .map(|a| a["name"].as_str().unwrap().to_string())
            .collect()
    };
    let names = field_names("point_data");
    assert!(
        names.iter().any(|n| n == "displacement_m")
            && names.iter().any(|n| n == "velocity_m_per_s"),
        "{names:?}"
    );
    let cells = field_names("cell_data");
    assert!(
        cells.iter().any(|n| n == "von_mises_Pa") && cells.iter().any(|n| n == "body"),
        "{cells:?}"
    );
    let rigid = &json[dir.join("rigid.pvd").to_str().unwrap()];
    let last = &rigid["frames"].as_array().unwrap().last().unwrap()["frame"];
    let body = last["cell_data"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["name"] == "body")
        .unwrap();
    let ids: std::collections::BTreeSet<i64> = body["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_i64().unwrap())
        .collect();
    // Body 0 is the sleeper; every stone is rigid here.
    assert_eq!(ids.len() as f64, figure(&f, "rigid_stones"));
    assert!(!ids.contains(&0));
}

/// `ballast-post spectra` on the run's sensors and load: the report files, one peak
/// list per sensor, and the mobility columns.
#[test]
fn the_spectra_of_the_quick_run() {
    let dir = quick();
    let (_, load) = inputs();
    let prefix = dir.join("spectra");
    ok(
        Command::new(POST)
            .arg("spectra")
            .arg(dir.join("sensors.csv"))
            .arg("--load")
            .arg(load)
            .arg("--out")
            .arg(&prefix)
            .output()
            .unwrap(),
        "ballast-post spectra",
    );
    let text = std::fs::read_to_string(prefix.with_extension("json")).unwrap();
    let json: Value = serde_json::from_str(&text).unwrap();
    for s in ["S1", "S2", "S3", "B1", "B2", "B3"] {
        assert!(json["sensors"][s]["peaks_hz"].is_array(), "{s}: {json}");
    }
    for suffix in [
        "_spectra.csv",
        "_spectra.svg",
        "_spectra.png",
        "_histories.svg",
        "_histories.png",
    ] {
        let file = PathBuf::from(format!("{}{suffix}", prefix.display()));
        assert!(
            std::fs::metadata(&file)
                .map(|m| m.len() > 0)
                .unwrap_or(false),
            "{}",
            file.display()
        );
    }
}

/// The track run's checkpoint by wall time: the short run below with the step count
/// out of reach and a checkpoint every 0.1 s of wall time, killed after the first and
/// resumed with the key changed ("0 s", a run-control key), writes the same sensor and
/// track series and frames as the run left alone.
#[cfg(unix)]
#[test]
fn a_track_run_checkpointed_by_wall_time_resumes_to_the_same_files() {
    let base = tempfile::tempdir().unwrap();
    let short = |wall: &str| {
        args(&[
            "--set",
            "track.settle=\"1 ms\"",
            "--set",
            "track.duration=\"3 ms\"",
            "--set",
            "track.frames=4",
            "--set",
            "track.checkpoint_every=1000000000",
            "--set",
            &format!("track.checkpoint_wall_every=\"{wall}\""),
        ])
    };
    let whole = base.path().join("whole");
    ok(
        qdem(&whole, &short("0 s")).output().unwrap(),
        "short track run",
    );
    let killed = base.path().join("killed");
    common::kill_at_first_checkpoint(&mut qdem(&killed, &short("0.1 s")), &killed, "summary.json");
    let resumed = qdem(&killed, &short("0 s"))
        .arg("--resume")
        .arg(&killed)
        .output()
        .unwrap();
    let resumed = ok(resumed, "resumed track run");
    assert!(String::from_utf8_lossy(&resumed.stdout).contains("resumed from"));
    common::assert_same_bytes(
        &whole,
        &killed,
        &[
            "sensors.csv",
            "track.csv",
            "deformable.pvd",
            "rigid.pvd",
            "frames/rigid_0004.vtu",
        ],
        "a resume from a checkpoint the clock took",
    );
}

/// A short run (1 ms settling, 3 ms loaded, a checkpoint every 1000 steps) gives the
/// same files, byte for byte, on 1 and 2 threads (deterministic contact gather,
/// coloured tetra assembly), and when killed by SIGKILL after a checkpoint and resumed
/// with `--resume` (no CSV row or VTK frame lost or written twice).
#[cfg(unix)]
#[test]
fn the_track_run_does_not_depend_on_the_thread_count_and_resumes_bit_for_bit() {
    let base = tempfile::tempdir().unwrap();
    let short = |threads: &str| {
        args(&[
            "--threads",
            threads,
            "--set",
            "track.settle=\"1 ms\"",
            "--set",
            "track.duration=\"3 ms\"",
            "--set",
            "track.frames=4",
            "--set",
            "track.checkpoint_every=1000",
        ])
    };
    let run = |name: &str, threads: &str| {
        let out = base.path().join(name);
        ok(
            qdem(&out, &short(threads)).output().unwrap(),
            "short track run",
        );
        out
    };
    let whole = run("two", "2");
    let one = run("one", "1");
    let killed = base.path().join("killed");
    let checkpoint = killed.join("checkpoint.bin");
    // Past the checkpoint (rows to cut back), well before the end (2840 more steps).
    let mut child = common::spawn_until_checkpoint(
        &mut qdem(&killed, &short("2")),
        &checkpoint,
        std::time::Duration::from_millis(400),
    );
    assert!(
        child.try_wait().unwrap().is_none(),
        "finished before the kill"
    );
    child.kill().unwrap();
    child.wait().unwrap();
    let resumed = qdem(&killed, &short("2"))
        .arg("--resume")
        .arg(&killed)
        .output()
        .unwrap();
    let resumed = ok(resumed, "resumed track run");
    assert!(String::from_utf8_lossy(&resumed.stdout).contains("resumed from"));
    for file in [
        "sensors.csv",
        "track.csv",
        "deformable.pvd",
        "rigid.pvd",
        "checkpoint.bin",
        "frames/deformable_0004.vtu",
        "frames/rigid_0004.vtu",
    ] {
        let whole = std::fs::read(whole.join(file)).unwrap();
        assert!(
            whole == std::fs::read(one.join(file)).unwrap(),
            "{file} differs between 1 and 2 threads"
        );
        assert!(
            whole == std::fs::read(killed.join(file)).unwrap(),
            "{file} differs after the resume"
        );
    }
    let (a, b) = (figures(&whole), figures(&killed));
    for key in [
        "sleeper_settlement_m",
        "settling_sink_m",
        "kinetic_energy_after_settling_j",
        "max_overlap_m",
        "energy_balance_error_j",
        "final_contacts",
        "list_rebuilds",
    ] {
        assert_eq!(a[key], b[key], "{key} after the resume");
    }
    // The wall times add both pieces up.
    if common::assert_two_pieces(&b, &resumed) {
        assert!(b["run_stepping_s"].as_f64().unwrap() > b["stepping_s"].as_f64().unwrap());
    }
    // Resuming with other arguments, or from a damaged checkpoint, is one line.
    let other = qdem(&killed, &args(&["--set", "track.duration=\"2 ms\""]))
        .arg("--resume")
        .arg(&killed)
        .output()
        .unwrap();
    assert_one_line_error(&other, 1, &["checkpoint.bin", "another scene"]);
    std::fs::write(&checkpoint, b"not a checkpoint").unwrap();
    let damaged = qdem(&killed, &short("2"))
        .arg("--resume")
        .arg(&killed)
        .output()
        .unwrap();
    assert_one_line_error(
        &damaged,
        1,
        &["checkpoint.bin", "not a ballast-qdem track checkpoint"],
    );
}

/// Bad input: a load file with a bad row, a missing packing, a step above the stable
/// one — one line each, naming what is wrong, exit 1.
#[test]
fn bad_track_input_gives_one_line_errors() {
    let base = tempfile::tempdir().unwrap();
    let bad = base.path().join("bad.csv");
    std::fs::write(&bad, "time_s,Rp1,Rp2\n0,0,0\n0.001,x,0\n").unwrap();
    let out = base.path().join("o");
    let set = |kv: String| vec!["--set".to_string(), kv];
    let o = qdem(&out, &set(format!("track.loads=\"{}\"", bad.display())))
        .output()
        .unwrap();
    assert_one_line_error(&o, 1, &["bad.csv", "line 3", "Rp1"]);
    let o = qdem(
        &out,
        &set("track.packing=\"/nonexistent/packing.toml\"".into()),
    )
    .output()
    .unwrap();
    assert_one_line_error(&o, 1, &["/nonexistent/packing.toml"]);
    let o = qdem(&out, &set("rail.lateral=\"-5 MN/m\"".into()))
        .output()
        .unwrap();
    assert_one_line_error(&o, 1, &["track_impact.toml", "rail.lateral"]);
    // A run longer than its load record (0.2 s) would hold the last row: refused.
    let o = qdem(&out, &set("track.duration=\"0.3 s\"".into()))
        .output()
        .unwrap();
    assert_one_line_error(&o, 1, &["train_load.csv", "track.duration", "0.2 s"]);
    // The step is checked once the bodies are built (the report lines come first).
    let o = qdem(&out, &set("track.dt=\"50 us\"".into()))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.trim_end().lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("track.dt") && stderr.contains("stable time step"),
        "{stderr}"
    );
    assert!(
        !out.join("summary.json").exists(),
        "no summary for a refused run"
    );
}

/// A run of a few steps, shorter than writing its first frame, finishes: its stepping
/// time is taken on its own clock without the frame written before it started (that
/// made it negative, and converting it panicked).
#[test]
fn a_run_shorter_than_its_first_frame_finishes() {
    let out = tempfile::tempdir().unwrap();
    let extra = args(&[
        "--set",
        "track.settle=\"0.01 ms\"",
        "--set",
        "track.duration=\"0.01 ms\"",
    ]);
    ok(
        qdem(out.path(), &extra).output().unwrap(),
        "ballast-qdem track, a few steps",
    );
    let text = std::fs::read_to_string(out.path().join("summary.json")).unwrap();
    let summary: Value = serde_json::from_str(&text).unwrap();
    assert!(summary["figures"]["steps"].as_u64().unwrap() > 0, "{text}");
    let stepping = summary["wall_time_s"]["stepping"].as_f64().unwrap();
    assert!(stepping >= 0.0, "stepping {stepping} s");
}
