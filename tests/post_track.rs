//! `ballast-post train-load` and `ballast-post spectra`, run as a user runs them: the
//! train-load CSV against the Zimmermann influence line (peak times and values, the
//! impulse W·a/v of each wheel, the roughness RMS, byte-for-byte reproducibility), and
//! the spectra of synthetic sensor records with known answers (two tones, a velocity
//! proportional to the load), the output files and the one-line errors.

mod common;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::assert_one_line_error;

const POST: &str = env!("CARGO_BIN_EXE_ballast-post");

fn post(args: &[&str]) -> Output {
    Command::new(POST).args(args).output().unwrap()
}

fn assert_ok(output: &Output) -> String {
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).to_string()
}

/// Columns of a numeric CSV file: (header, columns).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut columns = vec![Vec::new(); header.len()];
    for line in lines {
        for (column, value) in columns.iter_mut().zip(line.split(',')) {
            column.push(value.parse::<f64>().unwrap());
        }
    }
    (header, columns)
}

fn column<'a>(csv: &'a (Vec<String>, Vec<Vec<f64>>), name: &str) -> &'a [f64] {
    let i = csv.0.iter().position(|h| h == name).unwrap_or_else(|| {
        panic!("no column {name} in {:?}", csv.0);
    });
    &csv.1[i]
}

/// Default train (5 cars): axle offsets behind the first axle, m.
fn default_axle_offsets() -> Vec<f64> {
    (0..5)
        .flat_map(|c| [0.0, 2.1, 13.8, 15.9].map(|d| 20.0 * c as f64 + d))
        .collect()
}

const V: f64 = 115.0 / 3.6; // default speed, m/s
const WHEEL: f64 = 60e3; // half the default 120 kN axle load, N
const A: f64 = 0.6; // sleeper spacing, m
const L: f64 = 0.8; // characteristic length, m

fn train_load(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["train-load", "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let stdout = assert_ok(&post(&args));
    assert!(
        stdout.starts_with("wrote ") && stdout.contains(" rows, "),
        "{stdout}"
    );
    out
}

#[test]
fn quasi_static_train_load_follows_the_influence_line() {
    let dir = tempfile::tempdir().unwrap();
    // 12 m = 15 L before the first and after the last axle: the influence line's tail
    // beyond, ∫ = L e^{-15} |cos 15| ≤ 3e-7 L per wheel and end, is far below the
    // tolerance, so the record holds the whole impulse of every wheel.
    let file = train_load(
        dir.path(),
        "smooth.csv",
        &[
            "--roughness-fraction",
            "0",
            "--lead-in-m",
            "12",
            "--lead-out-m",
            "12",
        ],
    );
    let csv = read_csv(&file);
    assert_eq!(csv.0, ["time_s", "Rp1", "Rp2"]);
    let (t, rp1, rp2) = (
        column(&csv, "time_s"),
        column(&csv, "Rp1"),
        column(&csv, "Rp2"),
    );
    let dt = 1e-4;
    assert!(t.windows(2).all(|w| (w[1] - w[0] - dt).abs() < 1e-12));
    assert_eq!(
        rp1, rp2,
        "no imbalance, no roughness: the two rails are equal"
    );

    // Impulse: ∫Rp1 dt = n_axles · W a / v (∫η dx = 2L). The trapezoid rule on a smooth
    // (C², η''' jumps at x = 0) record decaying to ~0 at both ends errs by O(h⁴) with
    // h = v dt / L = 0.004: ~1e-10; 1e-5 leaves room for the ends' 3e-7.
    let impulse: f64 = rp1.windows(2).map(|w| 0.5 * (w[0] + w[1]) * dt).sum();
    let expected = 20.0 * WHEEL * A / V;
    eprintln!(
        "impulse {impulse} N s, n W a / v = {expected} N s, relative error {:.2e}",
        impulse / expected - 1.0
    );
    assert!(
        (impulse / expected - 1.0).abs() < 1e-5,
        "impulse {impulse} N s, expected {expected}"
    );

    // Peaks: exactly one local maximum per axle above half the single-wheel peak, at the
    // time the axle is over the sleeper, up to the pull of the neighbouring axles: the
    // other axle of the bogie (2.1 m = 2.625 L away) moves the maximum of
    // η(ξ) + η(ξ ∓ 2.625) to ξ = ±0.0417 (found numerically), 1.045 ms at 31.9 m/s; the
    // next car's axle 4.1 m away (slope |η'(5.125)| = 0.011) adds ≤ 0.14 ms and the
    // sampling 0.05 ms: allow 1.5 ms (the axles pass 66 ms apart or more).
    let half = 0.5 * WHEEL * A / (2.0 * L);
    let peaks: Vec<f64> = (1..rp1.len() - 1)
        .filter(|&i| rp1[i] > half && rp1[i] > rp1[i - 1] && rp1[i] >= rp1[i + 1])
        .map(|i| t[i])
        .collect();
    let expected: Vec<f64> = default_axle_offsets()
        .iter()
        .map(|d| (12.0 + d) / V)
        .collect();
    assert_eq!(peaks.len(), expected.len(), "{peaks:?}");
    let worst = peaks
        .iter()
        .zip(&expected)
        .map(|(p, e)| (p - e).abs())
        .fold(0.0, f64::max);
    eprintln!("largest peak-time offset {:.3} ms", 1e3 * worst);
    assert!(worst < 1.5e-3, "peaks {peaks:?}, axles {expected:?}");
}

#[test]
fn isolated_axle_peak_and_imbalance() {
    // One car with its axles ≥ 10 m = 12.5 L apart: the others' influence at a peak is
    // ≤ e^{-12.5} = 4e-6 of it. The peak sample lies within v dt / 2 = 1.6 mm of x = 0,
    // where η = 1 − (x/L)² drops by ≤ 4e-6; assert W a / (2L) to 2e-5.
    let dir = tempfile::tempdir().unwrap();
    let geometry = [
        "--roughness-fraction",
        "0",
        "--cars",
        "1",
        "--car-length-m",
        "60",
        "--bogie-centres-m",
        "30",
        "--axle-base-m",
        "10",
    ];
    let mut args = geometry.to_vec();
    args.extend(["--imbalance", "0.25"]);
    let csv = read_csv(&train_load(dir.path(), "one.csv", &args));
    let (t, rp1, rp2) = (
        column(&csv, "time_s"),
        column(&csv, "Rp1"),
        column(&csv, "Rp2"),
    );
    let single = WHEEL * A / (2.0 * L); // 22.5 kN
    let first = (0..t.len())
        .filter(|&i| t[i] < (4.4 + 5.0) / V)
        .max_by(|&i, &j| rp1[i].total_cmp(&rp1[j]))
        .unwrap();
    assert!((t[first] - 4.4 / V).abs() <= 0.5e-4 + 1e-12, "{}", t[first]);
    assert!(
        (rp1[first] / (1.25 * single) - 1.0).abs() < 2e-5,
        "{}",
        rp1[first]
    );
    assert!(
        (rp2[first] / (0.75 * single) - 1.0).abs() < 2e-5,
        "{}",
        rp2[first]
    );
    for (a, b) in rp1.iter().zip(rp2) {
        assert!((a * 0.75 - b * 1.25).abs() <= 1e-9 * single);
    }
}

#[test]
fn roughness_has_the_requested_rms_and_is_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let smooth = read_csv(&train_load(
        dir.path(),
        "q.csv",
        &["--roughness-fraction", "0"],
    ));
    let rough_file = train_load(dir.path(), "r.csv", &["--seed", "42"]);
    let again = train_load(dir.path(), "r2.csv", &["--seed", "42"]);
    let other = train_load(dir.path(), "r3.csv", &["--seed", "43"]);
    let bytes = std::fs::read(&rough_file).unwrap();
    assert_eq!(
        bytes,
        std::fs::read(&again).unwrap(),
        "same seed, different file"
    );
    assert_ne!(
        bytes,
        std::fs::read(&other).unwrap(),
        "the seed changes nothing"
    );
    let rough = read_csv(&rough_file);
    let t = column(&smooth, "time_s");
    let q = column(&smooth, "Rp1");
    let single = WHEEL * A / (2.0 * L);
    // Samples where one wheel is within 0.2 m of the sleeper (q within 7 % of its
    // peak; the other axle of the bogie adds ≤ 3 %): 20 axles × 126 samples. The noise
    // is band-limited to 50–1500 Hz, so each 12.5 ms stretch holds ~2 · 1450 · 0.0125 ≈
    // 36 independent values, ~720 in all: the RMS estimate scatters by ~1/√(2·720) =
    // 2.6 %, and the ±10 % asked is ~4 standard deviations.
    let near: Vec<usize> = (0..t.len())
        .filter(|&i| {
            default_axle_offsets()
                .iter()
                .any(|d| (V * t[i] - 4.4 - d).abs() < 0.2)
        })
        .collect();
    assert!(near.len() > 2400, "{}", near.len());
    let dynamic = |name: &str| -> Vec<f64> {
        let r = column(&rough, name);
        near.iter().map(|&i| (r[i] - q[i]) / q[i]).collect()
    };
    let (d1, d2) = (dynamic("Rp1"), dynamic("Rp2"));
    let rms = |d: &[f64]| (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    for (name, d) in [("Rp1", &d1), ("Rp2", &d2)] {
        let fraction = rms(d);
        eprintln!(
            "{name}: roughness RMS / quasi-static = {fraction:.4} (asked 0.2) over {} samples",
            d.len()
        );
        assert!(
            (fraction / 0.2 - 1.0).abs() < 0.10,
            "{name}: roughness RMS {fraction} of the quasi-static load, asked 0.2"
        );
    }
    // Independent realisations: correlation of the two rails' noise ~ N(0, 1/√720).
    let corr = d1.iter().zip(&d2).map(|(a, b)| a * b).sum::<f64>()
        / (rms(&d1) * rms(&d2) * d1.len() as f64);
    eprintln!("Rp1/Rp2 roughness correlation {corr:.4}");
    assert!(corr.abs() < 0.15, "Rp1 and Rp2 noise correlated: {corr}");
    // Far from every wheel the roughness vanishes with the quasi-static load.
    let r1 = column(&rough, "Rp1");
    let quiet: Vec<usize> = (0..t.len())
        .filter(|&i| q[i].abs() < 1e-4 * single)
        .collect();
    assert!(!quiet.is_empty());
    for i in quiet {
        assert!(
            (r1[i] - q[i]).abs() < 1e-3 * single,
            "t = {}: {}",
            t[i],
            r1[i]
        );
    }
}

#[test]
fn train_load_bad_values_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let out = out.to_str().unwrap();
    for (args, flag) in [
        (vec!["--speed-km-h", "-5"], "--speed-km-h"),
        (vec!["--sample-rate-hz", "0"], "--sample-rate-hz"),
        (vec!["--cars", "0"], "--cars"),
        (vec!["--roughness-high-hz", "9000"], "--roughness-high-hz"),
        (vec!["--imbalance", "2"], "--imbalance"),
    ] {
        let mut all = vec!["train-load", "--out", out];
        all.extend(args);
        assert_one_line_error(&post(&all), 1, &[flag]);
    }
    assert!(!Path::new(out).exists());
    let spec = dir.path().join("train.toml");
    std::fs::write(&spec, "speed_km_h = 100.0\nwheels = 4\n").unwrap();
    let output = post(&["train-load", "--out", out, "--spec", spec.to_str().unwrap()]);
    assert_one_line_error(&output, 1, &["train.toml", "wheels"]);
}

// ---------------------------------------------------------------- spectra

use ballast::post::track_sensors::QUANTITIES;

/// Writes a sensor CSV sampled at `dt` from 0 for `n` samples; `values(sensor, t)` gives
/// the nine quantities of each sensor. `skip` drops one column (header and rows).
fn write_sensors(
    path: &Path,
    names: &[&str],
    n: usize,
    dt: f64,
    values: impl Fn(usize, f64) -> [f64; 9],
    skip: Option<&str>,
) {
    let mut header = vec!["time_s".to_string()];
    for name in names {
        header.extend(QUANTITIES.iter().map(|q| format!("{name}_{q}")));
    }
    let keep: Vec<bool> = header.iter().map(|h| Some(h.as_str()) != skip).collect();
    let pick = |cells: Vec<String>| {
        cells
            .into_iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(c, _)| c)
            .collect::<Vec<_>>()
            .join(",")
    };
    let mut text = pick(header.clone()) + "\n";
    for i in 0..n {
        let t = i as f64 * dt;
        let mut row = vec![format!("{t:?}")];
        for s in 0..names.len() {
            row.extend(values(s, t).iter().map(|v| format!("{v:?}")));
        }
        text += &(pick(row) + "\n");
    }
    std::fs::write(path, text).unwrap();
}

fn two_tones(s: usize, t: f64) -> [f64; 9] {
    // S1 (s = 0): 0.5 and 0.2 m/s²; S2: 2.0 and 0.8 m/s², at 100 and 320 Hz.
    let k = if s == 0 { 0.25 } else { 1.0 };
    let az = k * (2.0 * (2.0 * PI * 100.0 * t).sin() + 0.8 * (2.0 * PI * 320.0 * t).sin());
    let settle = -1e-4 * (1.0 + s as f64) * (1.0 - (-3.0 * t).exp());
    [0.0, 2e-5 * t, settle, 0.0, 0.0, 0.0, 0.0, 0.0, az]
}

#[test]
fn spectra_of_two_tones_peaks_and_parzen_area() {
    let dir = tempfile::tempdir().unwrap();
    let sensors = dir.path().join("sensors.csv");
    write_sensors(&sensors, &["S1", "S2"], 15_000, 1e-4, two_tones, None);
    let prefix = dir.path().join("out/tones");
    // Window 0.25–1.25 s: 10 000 samples, T = 1 s, bins 1 Hz apart, both tones on a bin.
    let stdout = assert_ok(&post(&[
        "spectra",
        sensors.to_str().unwrap(),
        "--out",
        prefix.to_str().unwrap(),
        "--from",
        "0.25",
        "--to",
        "1.25",
    ]));
    assert!(stdout.contains("| S2 | 1 | 100.0 |"), "{stdout}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/tones.json")).unwrap())
            .unwrap();
    assert_eq!(json["bandwidth_hz"], 20.0);
    let window: Vec<f64> = serde_json::from_value(json["window_s"].clone()).unwrap();
    assert!(
        (window[0] - 0.25).abs() < 1e-9 && (window[1] - 1.25).abs() < 1e-9,
        "{window:?}"
    );
    // Parzen height of an on-bin tone: A · Δf · W(0) = A · 1 Hz · 3u/4, u = 280/(151 · 20)
    // s; the kernel's normalisation differs from ∫W = 1 only by its truncation after the
    // 4th zero (~1e-4; the lag window lasts u < 1/Δf, so sampling W at Δf loses nothing).
    let height = |a: f64| a * 0.75 * 280.0 / (151.0 * 20.0);
    for (name, k) in [("S1", 0.25), ("S2", 1.0)] {
        let peaks_hz: Vec<f64> =
            serde_json::from_value(json["sensors"][name]["peaks_hz"].clone()).unwrap();
        let amps: Vec<f64> =
            serde_json::from_value(json["sensors"][name]["peak_amplitudes"].clone()).unwrap();
        eprintln!(
            "{name}: peaks {peaks_hz:?} Hz, heights / (A·Δf·3u/4) = {:.6} {:.6}",
            amps[0] / height(2.0 * k),
            amps[1] / height(0.8 * k)
        );
        assert!(
            (peaks_hz[0] - 100.0).abs() <= 20.0 && (peaks_hz[1] - 320.0).abs() <= 20.0,
            "{name}: {peaks_hz:?}"
        );
        assert!(
            (amps[0] / height(2.0 * k) - 1.0).abs() < 1e-3,
            "{name}: {amps:?}"
        );
        assert!(
            (amps[1] / height(0.8 * k) - 1.0).abs() < 1e-3,
            "{name}: {amps:?}"
        );
    }

    // Area kept: the smoothed bump of the 100 Hz tone integrates to A/T = 2 (m/s²)·Hz.
    // The kernel reaches 8/u = 86 Hz, so 10–190 Hz holds it all and nothing of the 320 Hz
    // tone; bins below 86 Hz have a kernel cut at 0 Hz and renormalised, but there the
    // 100 Hz bump is ≤ 3e-5 of its height: allow 1e-4.
    let csv = read_csv(&dir.path().join("out/tones_spectra.csv"));
    let f = column(&csv, "frequency_hz");
    assert_eq!(f.len(), 1001, "0 to max_hz = 1000 Hz every 1 Hz");
    let s2 = column(&csv, "S2_az_amplitude_m_per_s2");
    let area: f64 = (10..=190).map(|k| s2[k]).sum::<f64>() * (f[1] - f[0]);
    let area_320: f64 = (240..=400).map(|k| s2[k]).sum::<f64>() * (f[1] - f[0]);
    eprintln!(
        "areas / (A/T): {:.3e} {:.3e}",
        area / 2.0 - 1.0,
        area_320 / 0.8 - 1.0
    );
    assert!((area / 2.0 - 1.0).abs() < 1e-4, "area {area}");
    assert!((area_320 / 0.8 - 1.0).abs() < 1e-4, "area {area_320}");

    // The charts.
    for name in ["tones_spectra", "tones_histories"] {
        let svg = std::fs::read_to_string(dir.path().join(format!("out/{name}.svg"))).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
            "{name}"
        );
        let png = std::fs::read(dir.path().join(format!("out/{name}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        assert!(png.len() > 10_000, "{name}: {} bytes", png.len());
    }
    let histories = std::fs::read_to_string(dir.path().join("out/tones_histories.svg")).unwrap();
    assert!(
        histories.contains("vertical displacement uz")
            && histories.contains("lateral displacement uy")
    );
}

#[test]
fn mobility_of_a_velocity_proportional_to_the_load_is_flat() {
    // Load: 60 kN plus 300 tones of 1 kN, 5–1500 Hz every 5 Hz, phases scattered; the
    // velocity at every sensor sample is H times the load at that instant. The load file
    // is sampled at 40 kHz, offset half a sample from the sensor times and longer than
    // the record, so the load is interpolated: linear interpolation midway scales a tone
    // by cos(ω h/2), ≤ 0.3 % low at 1 kHz (h = 25 µs), so |V|/|P| = H within 1 %.
    const H: f64 = 2.5e-9;
    let load = |t: f64| {
        60e3 + (1..=300)
            .map(|j| 1e3 * (2.0 * PI * 5.0 * j as f64 * t + 2.4 * (j * j) as f64).cos())
            .sum::<f64>()
    };
    let dir = tempfile::tempdir().unwrap();
    let sensors = dir.path().join("sensors.csv");
    write_sensors(
        &sensors,
        &["B2"],
        10_000,
        1e-4,
        |_, t| {
            let v = H * load(t);
            [
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                v,
                0.0,
                0.0,
                (2.0 * PI * 50.0 * t).sin(),
            ]
        },
        None,
    );
    let load_file = dir.path().join("load.csv");
    let mut text = String::from("time_s,Rp1,Rp2\n");
    for j in 0..44_000 {
        let t = -0.05 + (j as f64 + 0.5) / 40_000.0;
        let p = load(t);
        text += &format!("{t:?},{:?},{:?}\n", 0.6 * p, 0.4 * p);
    }
    std::fs::write(&load_file, text).unwrap();
    let prefix = dir.path().join("m");
    assert_ok(&post(&[
        "spectra",
        sensors.to_str().unwrap(),
        "--out",
        prefix.to_str().unwrap(),
        "--load",
        load_file.to_str().unwrap(),
    ]));
    let csv = read_csv(&dir.path().join("m_spectra.csv"));
    let f = column(&csv, "frequency_hz");
    let mobility = column(&csv, "B2_mobility_vz_m_per_s_per_N");
    let (rp1, total) = (
        column(&csv, "Rp1_amplitude_N"),
        column(&csv, "load_amplitude_N"),
    );
    let mut worst: f64 = 0.0;
    eprintln!(
        "mobility/H at 20, 500, 1000 Hz: {:.5} {:.5} {:.5}",
        mobility[20] / H,
        mobility[500] / H,
        mobility[1000] / H
    );
    for k in (0..f.len()).filter(|&k| (20.0..=1000.0).contains(&f[k])) {
        worst = worst.max((mobility[k] / H - 1.0).abs());
        assert!((rp1[k] / total[k] - 0.6).abs() < 1e-3, "{} Hz", f[k]);
    }
    eprintln!("mobility: largest |M/H - 1| over 20-1000 Hz = {worst:.2e}");
    assert!(worst < 0.01, "mobility departs from H by {worst}");
}

#[test]
fn spectra_errors_are_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("e");
    let prefix = prefix.to_str().unwrap();
    let missing = dir.path().join("missing.csv");
    write_sensors(
        &missing,
        &["S1", "S2"],
        200,
        1e-4,
        two_tones,
        Some("S2_vz_m_per_s"),
    );
    let output = post(&["spectra", missing.to_str().unwrap(), "--out", prefix]);
    assert_one_line_error(&output, 1, &["missing.csv", "S2_vz_m_per_s"]);

    let good = dir.path().join("good.csv");
    write_sensors(&good, &["S1"], 200, 1e-4, two_tones, None);
    let good = good.to_str().unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["spectra", good, "--out", prefix];
        args.extend_from_slice(extra);
        post(&args)
    };
    assert_one_line_error(
        &run(&["--from", "0.015", "--to", "0.01"]),
        1,
        &["--from", "--to"],
    );
    assert_one_line_error(
        &run(&["--from", "0.01", "--to", "0.01005"]),
        1,
        &["good.csv", "at least 2"],
    );
    assert_one_line_error(&run(&["--bandwidth-hz", "0"]), 1, &["--bandwidth-hz"]);
    assert_one_line_error(&run(&["--max-hz", "6000"]), 1, &["--max-hz", "Nyquist"]);
    let short_load = dir.path().join("short.csv");
    std::fs::write(&short_load, "time_s,Rp1,Rp2\n0.0,1.0,1.0\n0.01,1.0,1.0\n").unwrap();
    assert_one_line_error(
        &run(&["--load", short_load.to_str().unwrap()]),
        1,
        &["short.csv", "covers"],
    );

    let jitter = dir.path().join("jitter.csv");
    let text = std::fs::read_to_string(good).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let row: Vec<&str> = lines[51].split(',').collect();
    let shifted = format!("0.00502,{}", row[1..].join(","));
    lines[51] = shifted;
    std::fs::write(&jitter, lines.join("\n") + "\n").unwrap();
    let output = post(&["spectra", jitter.to_str().unwrap(), "--out", prefix]);
    assert_one_line_error(&output, 1, &["jitter.csv", "line 52", "uniform"]);
    assert!(!Path::new(&format!("{prefix}_spectra.csv")).exists());
}
