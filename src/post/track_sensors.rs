//! The records `ballast-post spectra` reads (seed 004 §4): the track solver's sensor CSV
//! and the rail-seat load CSV.
//!
//! Sensor CSV: `time_s`, then for each sensor NAME the nine columns `NAME_ux_m`,
//! `NAME_uy_m`, `NAME_uz_m`, `NAME_vx_m_per_s` … `NAME_vz_m_per_s`, `NAME_ax_m_per_s2` …
//! `NAME_az_m_per_s2`, sampled uniformly. Columns that fit no sensor are ignored; blank
//! lines and lines starting with `#` are skipped. Load CSV: `time_s,Rp1,Rp2` (N), as
//! `ballast-post train-load` writes it, any sampling.

use std::path::{Path, PathBuf};

use crate::{Error, Result};

/// Relative tolerance on the time step: a record whose steps differ from their mean by
/// more than this is refused (a jitter of 1e-3 of a step is a phase error of
/// 2π · 1e-3 · f · dt: 0.06 % at 1 kHz for 10 kHz sampling, 0.3 % at Nyquist).
pub const STEP_TOLERANCE: f64 = 1e-3;

/// The nine quantities of a sensor, in column order, as column-name suffixes.
pub const QUANTITIES: [&str; 9] = [
    "ux_m",
    "uy_m",
    "uz_m",
    "vx_m_per_s",
    "vy_m_per_s",
    "vz_m_per_s",
    "ax_m_per_s2",
    "ay_m_per_s2",
    "az_m_per_s2",
];

/// A Cartesian component: x along the track, y across (lateral), z up (vertical).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Component {
    /// Along the track.
    X,
    /// Across the track (lateral, seed 004 Figure 8a).
    Y,
    /// Vertical (settlement, Figures 8b–12).
    Z,
}

impl Component {
    /// 0, 1, 2 for x, y, z.
    pub fn index(self) -> usize {
        self as usize
    }

    /// "x", "y" or "z".
    pub fn letter(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }
}

/// One sensor's histories, each `[x, y, z]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Sensor name, e.g. `S2` or `B2`.
    pub name: String,
    /// Displacement, m.
    pub displacement_m: [Vec<f64>; 3],
    /// Velocity, m/s.
    pub velocity_m_per_s: [Vec<f64>; 3],
    /// Acceleration, m/s².
    pub acceleration_m_per_s2: [Vec<f64>; 3],
}

/// A sensor CSV as read: uniform times and the sensors in column order.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorRecord {
    /// The file read.
    pub path: PathBuf,
    /// Sample times, s.
    pub time_s: Vec<f64>,
    /// Mean time step, s.
    pub dt_s: f64,
    /// The sensors, in the order of their first column.
    pub sensors: Vec<Sensor>,
}

/// A rail-seat load CSV (`time_s,Rp1,Rp2`, N) as read; times strictly increasing.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadRecord {
    /// The file read.
    pub path: PathBuf,
    /// Sample times, s.
    pub time_s: Vec<f64>,
    /// Rail seat 1, N.
    pub rp1_n: Vec<f64>,
    /// Rail seat 2, N.
    pub rp2_n: Vec<f64>,
}

/// A CSV of numbers with `time_s` first, column by column (the sensor, load and
/// track records of the track scene).
pub(super) struct Table {
    path: PathBuf,
    header: Vec<String>,
    columns: Vec<Vec<f64>>,
    /// File line number (1-based) of each row.
    lines: Vec<usize>,
}

/// Reads a CSV of finite numbers whose first column is `time_s`, strictly increasing,
/// with at least 2 rows; errors name the file and the line or column.
pub(super) fn read_table(path: &Path) -> Result<Table> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut rows = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'));
    let Some((head_index, head)) = rows.next() else {
        return Err(Error::invalid(path, "empty file, expected a header line"));
    };
    let header: Vec<String> = head.split(',').map(|c| c.trim().to_string()).collect();
    if header[0] != "time_s" {
        return Err(Error::invalid(
            path,
            format!(
                "line {}: first column is \"{}\", expected time_s",
                head_index + 1,
                header[0]
            ),
        ));
    }
    let mut columns = vec![Vec::new(); header.len()];
    let mut lines = Vec::new();
    for (index, line) in rows {
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != header.len() {
            return Err(Error::invalid(
                path,
                format!(
                    "line {}: {} values for {} columns",
                    index + 1,
                    fields.len(),
                    header.len()
                ),
            ));
        }
        for ((field, column), name) in fields.iter().zip(&mut columns).zip(&header) {
            let value: f64 = field
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    Error::invalid(
                        path,
                        format!(
                            "line {}: column {name}: \"{}\" is not a finite number",
                            index + 1,
                            field.trim()
                        ),
                    )
                })?;
            column.push(value);
        }
        lines.push(index + 1);
    }
    if lines.len() < 2 {
        return Err(Error::invalid(
            path,
            format!("{} data rows, at least 2 are needed", lines.len()),
        ));
    }
    let table = Table {
        path: path.to_path_buf(),
        header,
        columns,
        lines,
    };
    if let Some(i) =
        (1..table.lines.len()).find(|&i| table.columns[0][i] <= table.columns[0][i - 1])
    {
        return Err(table.at_row(i, "time_s must be strictly increasing"));
    }
    Ok(table)
}

impl Table {
    /// The column `name` (an error naming the file and the header if there is none).
    pub(super) fn column(&self, name: &str) -> Result<Vec<f64>> {
        match self.header.iter().position(|h| h == name) {
            Some(i) => Ok(self.columns[i].clone()),
            None => Err(Error::invalid(
                &self.path,
                format!("no column {name} (header: {})", self.header.join(",")),
            )),
        }
    }

    fn at_row(&self, row: usize, what: &str) -> Error {
        Error::invalid(
            &self.path,
            format!(
                "line {}: time_s = {}: {what}",
                self.lines[row], self.columns[0][row]
            ),
        )
    }
}

/// Reads a sensor CSV (format in the module doc). Errors name the file and the line or
/// column: a missing column of a sensor, a value that is not a number, fewer than 2
/// rows, or a time step that is not uniform (within [`STEP_TOLERANCE`]).
pub fn read_sensors(path: &Path) -> Result<SensorRecord> {
    let table = read_table(path)?;
    let mut names: Vec<String> = Vec::new();
    for column in &table.header[1..] {
        let name = QUANTITIES
            .iter()
            .find_map(|q| column.strip_suffix(q)?.strip_suffix('_'));
        if let Some(name) = name.filter(|n| !n.is_empty() && !names.iter().any(|m| m == n)) {
            names.push(name.to_string());
        }
    }
    if names.is_empty() {
        return Err(Error::invalid(
            path,
            "no sensor columns (expected NAME_ux_m, …, NAME_az_m_per_s2 after time_s)",
        ));
    }
    let mut sensors = Vec::new();
    for name in names {
        let mut q = QUANTITIES
            .iter()
            .map(|q| table.column(&format!("{name}_{q}")))
            .collect::<Result<Vec<_>>>()?
            .into_iter();
        let mut three = || [0, 1, 2].map(|_| q.next().unwrap_or_default());
        sensors.push(Sensor {
            displacement_m: three(),
            velocity_m_per_s: three(),
            acceleration_m_per_s2: three(),
            name,
        });
    }
    let time_s = table.columns[0].clone();
    let n = time_s.len();
    let dt_s = (time_s[n - 1] - time_s[0]) / (n - 1) as f64;
    if let Some(i) = (1..n).find(|&i| {
        let step = time_s[i] - time_s[i - 1];
        (step - dt_s).abs() > STEP_TOLERANCE * dt_s
    }) {
        return Err(table.at_row(
            i,
            &format!(
                "time step {:e} s differs from the mean step {dt_s:e} s (the sampling must be uniform)",
                time_s[i] - time_s[i - 1]
            ),
        ));
    }
    Ok(SensorRecord {
        path: path.to_path_buf(),
        time_s,
        dt_s,
        sensors,
    })
}

/// Reads a rail-seat load CSV `time_s,Rp1,Rp2` (any sampling, times strictly increasing).
pub fn read_load(path: &Path) -> Result<LoadRecord> {
    let table = read_table(path)?;
    Ok(LoadRecord {
        path: path.to_path_buf(),
        time_s: table.columns[0].clone(),
        rp1_n: table.column("Rp1")?,
        rp2_n: table.column("Rp2")?,
    })
}

impl LoadRecord {
    /// The total load Rp1 + Rp2 (and each seat) linearly interpolated at `times`; errors
    /// if a time lies outside the load's time span.
    pub fn resample(&self, times: &[f64]) -> Result<[Vec<f64>; 3]> {
        let (first, last) = (self.time_s[0], self.time_s[self.time_s.len() - 1]);
        let slack = 1e-9 * first.abs().max(last.abs()).max(1.0);
        let (need_a, need_b) = (times[0], times[times.len() - 1]);
        if need_a < first - slack || need_b > last + slack {
            return Err(Error::invalid(
                &self.path,
                format!(
                    "time_s covers {first}–{last} s but the spectral window needs {need_a}–{need_b} s"
                ),
            ));
        }
        let mut rp1 = Vec::with_capacity(times.len());
        let mut rp2 = Vec::with_capacity(times.len());
        let mut j = 0;
        for &t in times {
            while j + 2 < self.time_s.len() && self.time_s[j + 1] < t {
                j += 1;
            }
            let (t0, t1) = (self.time_s[j], self.time_s[j + 1]);
            let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
            rp1.push(self.rp1_n[j] + s * (self.rp1_n[j + 1] - self.rp1_n[j]));
            rp2.push(self.rp2_n[j] + s * (self.rp2_n[j + 1] - self.rp2_n[j]));
        }
        let total = rp1.iter().zip(&rp2).map(|(a, b)| a + b).collect();
        Ok([rp1, rp2, total])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_a_load_and_refuses_an_uncovered_window() {
        let load = LoadRecord {
            path: PathBuf::from("load.csv"),
            time_s: vec![0.0, 1.0, 3.0],
            rp1_n: vec![0.0, 10.0, 30.0],
            rp2_n: vec![1.0, 1.0, 5.0],
        };
        let [rp1, rp2, total] = load.resample(&[0.5, 1.0, 2.0, 3.0]).unwrap();
        assert_eq!(rp1, [5.0, 10.0, 20.0, 30.0]);
        assert_eq!(rp2, [1.0, 1.0, 3.0, 5.0]);
        assert_eq!(total, [6.0, 11.0, 23.0, 35.0]);
        let err = load.resample(&[0.5, 3.5]).unwrap_err().to_string();
        assert!(err.starts_with("load.csv: time_s covers 0–3 s"), "{err}");
    }
}
