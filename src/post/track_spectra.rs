//! Spectra, peaks and mobility of the track-impact sensors (seed 004 §4, Figures 8–12),
//! from the records of [`super::track_sensors`]:
//! - Parzen-smoothed linear amplitude spectra (20 Hz bandwidth, Figures 9b–11b) of every
//!   sensor's acceleration in one component over a time window, and of the loads;
//! - the mobility (Figure 12): the smoothed spectrum of a sensor's velocity divided by
//!   that of the total input load Rp1 + Rp2, in (m/s)/N;
//! - the peaks of each acceleration spectrum below `max_hz`, ranked by prominence;
//! - the CSV, JSON and charts ([`super::track_charts`]) of `ballast-post spectra`.
//!
//! Spectra use the rectangular window (the record's Fourier amplitude as it is, the
//! convention Parzen smoothing is defined on) and [`crate::signal::amplitude_spectrum`]'s
//! scaling, then [`crate::signal::parzen_smooth`], which keeps the area under a peak: a
//! sinusoid of amplitude A on a bin of a record of length T becomes a bump of area A/T
//! and height ≈ A · (3u/4) / T, u = 280/(151 b).

use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde_json::json;

use super::track_charts::{draw_histories, draw_spectra};
use super::track_sensors::{Component, LoadRecord, SensorRecord};
use crate::signal::{amplitude_spectrum, parzen_smooth, Spectrum, Window};
use crate::{Error, Result};

/// What `ballast-post spectra` computes and how.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectraOptions {
    /// Window start, s (default: the first sample).
    pub from_s: Option<f64>,
    /// Window end, s, exclusive (default: one step after the last sample).
    pub to_s: Option<f64>,
    /// Parzen bandwidth, Hz (20 Hz: seed 004 Figures 9–12).
    pub bandwidth_hz: f64,
    /// Highest frequency written, charted and searched for peaks, Hz (1 kHz: the seed
    /// trusts results below 1 kHz for a 10 kHz record).
    pub max_hz: f64,
    /// Component of acceleration and velocity analysed (z: seed 004 Figures 9–12).
    pub component: Component,
    /// Number of peaks kept per sensor.
    pub peak_count: usize,
}

impl Default for SpectraOptions {
    fn default() -> Self {
        SpectraOptions {
            from_s: None,
            to_s: None,
            bandwidth_hz: 20.0,
            max_hz: 1000.0,
            component: Component::Z,
            peak_count: 5,
        }
    }
}

/// A local maximum of a smoothed spectrum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Its bin's frequency, Hz.
    pub frequency_hz: f64,
    /// Its smoothed amplitude (unit of the spectrum).
    pub amplitude: f64,
    /// Topographic prominence: height above the higher of the two lowest points met on
    /// each side before a higher value (or the end of the searched range).
    pub prominence: f64,
}

/// The spectra of one sensor, on [`TrackSpectra::frequencies_hz`].
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpectra {
    /// Sensor name.
    pub name: String,
    /// Smoothed acceleration spectrum, m/s².
    pub acceleration: Vec<f64>,
    /// Smoothed velocity spectrum, m/s.
    pub velocity: Vec<f64>,
    /// |V(f)| / |P(f)| with P = Rp1 + Rp2, (m/s)/N (seed 004 Figure 12), when a load is
    /// given; NaN where |P| is below 10⁻¹² of its largest value.
    pub mobility: Option<Vec<f64>>,
    /// Peaks of the acceleration spectrum below `max_hz`, most prominent first.
    pub peaks: Vec<Peak>,
}

/// Smoothed load spectra, N.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSpectra {
    /// Rail seat 1.
    pub rp1: Vec<f64>,
    /// Rail seat 2.
    pub rp2: Vec<f64>,
    /// Rp1 + Rp2.
    pub total: Vec<f64>,
}

/// Everything `ballast-post spectra` reports, on frequencies from 0 to `max_hz`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackSpectra {
    /// Component analysed.
    pub component: Component,
    /// Parzen bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// The window actually used, `[first sample, first sample + n dt]`, s.
    pub window_s: [f64; 2],
    /// Samples in the window.
    pub samples: usize,
    /// Bin frequencies, 0 to `max_hz`, spacing `1 / (n dt)`.
    pub frequencies_hz: Vec<f64>,
    /// Per sensor.
    pub sensors: Vec<SensorSpectra>,
    /// The load's spectra, when a load is given.
    pub load: Option<LoadSpectra>,
}

/// The samples of `record` in the window `[from, to)`: those with
/// `from − dt/2 ≤ t < to − dt/2`, so a window on the sampling grid holds `(to − from)/dt`
/// samples and lasts exactly `to − from`. Errors name the flag (`--from`, `--to`).
pub fn window_indices(
    record: &SensorRecord,
    from_s: Option<f64>,
    to_s: Option<f64>,
) -> Result<Range<usize>> {
    let t = &record.time_s;
    let dt = record.dt_s;
    let from = from_s.unwrap_or(t[0]);
    let to = to_s.unwrap_or(t[t.len() - 1] + dt);
    for (flag, v) in [("--from", from), ("--to", to)] {
        if !v.is_finite() {
            return Err(Error::Message(format!("spectra: {flag} {v} is not finite")));
        }
    }
    if from >= to {
        return Err(Error::Message(format!(
            "spectra: --from {from} s must be below --to {to} s"
        )));
    }
    let start = t.partition_point(|&x| x < from - 0.5 * dt);
    let end = t.partition_point(|&x| x < to - 0.5 * dt);
    if end < start + 2 {
        return Err(Error::invalid(
            &record.path,
            format!(
                "the window --from {from} --to {to} s holds {} sample(s), at least 2 are needed (time_s runs {}–{} s)",
                end.saturating_sub(start),
                t[0],
                t[t.len() - 1]
            ),
        ));
    }
    Ok(start..end)
}

/// The rectangular-window linear amplitude spectrum of `samples` (mean removed),
/// smoothed by the Parzen window of `bandwidth_hz`.
pub fn smoothed_spectrum(samples: &[f64], dt: f64, bandwidth_hz: f64) -> Result<Spectrum> {
    parzen_smooth(
        &amplitude_spectrum(samples, dt, Window::Rectangular)?,
        bandwidth_hz,
    )
}

/// The `count` most prominent local maxima of `amplitudes` over the bins with
/// `0 < f ≤ max_hz` (a maximum: higher than the bin before, not lower than the one
/// after; the ends of the range are not maxima), most prominent first.
pub fn find_peaks(
    frequencies_hz: &[f64],
    amplitudes: &[f64],
    max_hz: f64,
    count: usize,
) -> Vec<Peak> {
    let lo = frequencies_hz.partition_point(|&f| f <= 0.0);
    let hi = frequencies_hz.partition_point(|&f| f <= max_hz);
    let a = &amplitudes[lo..hi.max(lo)];
    let mut peaks: Vec<Peak> = (1..a.len().saturating_sub(1))
        .filter(|&k| a[k] > a[k - 1] && a[k] >= a[k + 1])
        .map(|k| {
            let base = |range: &mut dyn Iterator<Item = usize>| {
                let mut low = a[k];
                for j in range {
                    if a[j] > a[k] {
                        break;
                    }
                    low = low.min(a[j]);
                }
                low
            };
            let left = base(&mut (0..k).rev());
            let right = base(&mut (k + 1..a.len()));
            Peak {
                frequency_hz: frequencies_hz[lo + k],
                amplitude: a[k],
                prominence: a[k] - left.max(right),
            }
        })
        .collect();
    peaks.sort_by(|p, q| q.prominence.total_cmp(&p.prominence));
    peaks.truncate(count);
    peaks
}

/// Computes the spectra, mobilities and peaks of `record` (and `load`) over the window
/// of `options`. Errors name the flag or the file: a bad window, bandwidth or `max_hz`
/// (not positive, or above the Nyquist frequency), a load that does not cover the window.
pub fn analyse(
    record: &SensorRecord,
    load: Option<&LoadRecord>,
    options: &SpectraOptions,
) -> Result<TrackSpectra> {
    let nyquist = 0.5 / record.dt_s;
    for (flag, v) in [
        ("--bandwidth-hz", options.bandwidth_hz),
        ("--max-hz", options.max_hz),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(Error::Message(format!(
                "spectra: {flag} {v} must be finite and > 0"
            )));
        }
    }
    if options.max_hz > nyquist * (1.0 + 1e-9) {
        return Err(Error::invalid(
            &record.path,
            format!(
                "--max-hz {} is above the Nyquist frequency {nyquist} Hz of this record",
                options.max_hz
            ),
        ));
    }
    let range = window_indices(record, options.from_s, options.to_s)?;
    let dt = record.dt_s;
    let c = options.component.index();
    let smooth = |x: &[f64]| smoothed_spectrum(x, dt, options.bandwidth_hz);
    // The grid of `amplitude_spectrum` for n samples: k / (n dt), k = 0 … n/2.
    let df = 1.0 / (range.len() as f64 * dt);
    let frequencies: Vec<f64> = (0..=range.len() / 2).map(|k| k as f64 * df).collect();
    let keep = frequencies.partition_point(|&f| f <= options.max_hz * (1.0 + 1e-12));
    let cut = |s: Spectrum| s.amplitudes[..keep].to_vec();
    let load = match load {
        Some(l) => {
            let [rp1, rp2, total] = l.resample(&record.time_s[range.clone()])?;
            Some(LoadSpectra {
                rp1: cut(smooth(&rp1)?),
                rp2: cut(smooth(&rp2)?),
                total: cut(smooth(&total)?),
            })
        }
        None => None,
    };
    let mut sensors = Vec::new();
    for sensor in &record.sensors {
        let acceleration = cut(smooth(&sensor.acceleration_m_per_s2[c][range.clone()])?);
        let velocity = cut(smooth(&sensor.velocity_m_per_s[c][range.clone()])?);
        let mobility = load.as_ref().map(|l| {
            let floor = 1e-12 * l.total.iter().copied().fold(0.0, f64::max);
            velocity
                .iter()
                .zip(&l.total)
                .map(|(v, p)| if *p > floor { v / p } else { f64::NAN })
                .collect()
        });
        let peaks = find_peaks(
            &frequencies[..keep],
            &acceleration,
            options.max_hz,
            options.peak_count,
        );
        sensors.push(SensorSpectra {
            name: sensor.name.clone(),
            acceleration,
            velocity,
            mobility,
            peaks,
        });
    }
    let t0 = record.time_s[range.start];
    Ok(TrackSpectra {
        component: options.component,
        bandwidth_hz: options.bandwidth_hz,
        window_s: [t0, t0 + range.len() as f64 * dt],
        samples: range.len(),
        frequencies_hz: frequencies[..keep].to_vec(),
        sensors,
        load,
    })
}

impl TrackSpectra {
    /// Column names of [`TrackSpectra::csv`].
    pub fn csv_columns(&self) -> Vec<String> {
        let c = self.component.letter();
        let mut columns = vec!["frequency_hz".to_string()];
        columns.extend(
            self.sensors
                .iter()
                .map(|s| format!("{}_a{c}_amplitude_m_per_s2", s.name)),
        );
        if self.load.is_some() {
            columns.extend(
                ["Rp1_amplitude_N", "Rp2_amplitude_N", "load_amplitude_N"].map(String::from),
            );
            columns.extend(
                self.sensors
                    .iter()
                    .map(|s| format!("{}_mobility_v{c}_m_per_s_per_N", s.name)),
            );
        }
        columns
    }

    /// The spectra as CSV: frequency, each sensor's acceleration spectrum, then (with a
    /// load) Rp1, Rp2 and Rp1 + Rp2 spectra and each sensor's mobility.
    pub fn csv(&self) -> String {
        let mut text = self.csv_columns().join(",");
        text.push('\n');
        for (k, f) in self.frequencies_hz.iter().enumerate() {
            let mut row = vec![*f];
            row.extend(self.sensors.iter().map(|s| s.acceleration[k]));
            if let Some(l) = &self.load {
                row.extend([l.rp1[k], l.rp2[k], l.total[k]]);
                row.extend(
                    self.sensors
                        .iter()
                        .map(|s| s.mobility.as_ref().map_or(f64::NAN, |m| m[k])),
                );
            }
            let cells: Vec<String> = row.iter().map(|v| format!("{v:?}")).collect();
            text.push_str(&cells.join(","));
            text.push('\n');
        }
        text
    }

    /// The peaks as JSON: `{"sensors": {NAME: {"peaks_hz", "peak_amplitudes",
    /// "peak_prominences"}}, "bandwidth_hz", "window_s", "component"}`.
    pub fn peaks_json(&self) -> serde_json::Value {
        let sensors: serde_json::Map<String, serde_json::Value> = self
            .sensors
            .iter()
            .map(|s| {
                let of = |get: fn(&Peak) -> f64| s.peaks.iter().map(get).collect::<Vec<_>>();
                (
                    s.name.clone(),
                    json!({
                        "peaks_hz": of(|p| p.frequency_hz),
                        "peak_amplitudes": of(|p| p.amplitude),
                        "peak_prominences": of(|p| p.prominence),
                    }),
                )
            })
            .collect();
        json!({
            "sensors": sensors,
            "bandwidth_hz": self.bandwidth_hz,
            "window_s": self.window_s,
            "component": self.component.letter(),
        })
    }

    /// A markdown table of the peaks, most prominent first.
    pub fn peak_table(&self) -> String {
        let c = self.component.letter();
        let mut out = format!(
            "peaks of the a{c} spectra (Parzen {} Hz), window {:.4}–{:.4} s ({} samples)\n\n\
             | sensor | rank | frequency (Hz) | amplitude (m/s²) | prominence (m/s²) |\n\
             |---|---:|---:|---:|---:|\n",
            self.bandwidth_hz, self.window_s[0], self.window_s[1], self.samples
        );
        for s in &self.sensors {
            for (rank, p) in s.peaks.iter().enumerate() {
                let _ = writeln!(
                    out,
                    "| {} | {} | {:.1} | {:.4e} | {:.4e} |",
                    s.name,
                    rank + 1,
                    p.frequency_hz,
                    p.amplitude,
                    p.prominence
                );
            }
        }
        out
    }
}

/// `prefix` with `suffix` appended to its file name (`out/run` + `_spectra.csv`).
pub fn with_suffix(prefix: &Path, suffix: &str) -> PathBuf {
    let mut name = prefix.as_os_str().to_owned();
    name.push(suffix);
    PathBuf::from(name)
}

/// Writes PREFIX_spectra.csv, PREFIX.json, PREFIX_spectra.svg/.png and
/// PREFIX_histories.svg/.png; returns the paths written.
pub fn write_report(
    record: &SensorRecord,
    spectra: &TrackSpectra,
    prefix: &Path,
) -> Result<Vec<PathBuf>> {
    // `write_atomic` creates the missing directories.
    let csv = with_suffix(prefix, "_spectra.csv");
    crate::output::write_atomic(&csv, spectra.csv().as_bytes())?;
    let json = with_suffix(prefix, ".json");
    crate::output::write_json(&json, &spectra.peaks_json())?;
    let mut files = vec![csv, json];
    files.extend(draw_spectra(spectra, &with_suffix(prefix, "_spectra.svg"))?);
    files.extend(draw_histories(
        record,
        spectra,
        &with_suffix(prefix, "_histories.svg"),
    )?);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_ranked_by_prominence() {
        // Two bumps (heights 3 and 2) on a slope, with a small ripple on the big one.
        let f: Vec<f64> = (0..200).map(|k| k as f64).collect();
        let a: Vec<f64> = f
            .iter()
            .map(|&x| {
                0.01 * x
                    + 3.0 * (-(x - 50.0).powi(2) / 20.0).exp()
                    + 2.0 * (-(x - 140.0).powi(2) / 20.0).exp()
                    + if x == 60.0 { 0.05 } else { 0.0 }
            })
            .collect();
        let peaks = find_peaks(&f, &a, 180.0, 5);
        assert_eq!(peaks[0].frequency_hz, 50.0);
        assert_eq!(peaks[1].frequency_hz, 140.0);
        assert!(
            (peaks[0].prominence - (a[50] - a[51..140].iter().copied().fold(9.0, f64::min))).abs()
                < 1e-12
        );
        assert!(peaks.len() == 3 && peaks[2].frequency_hz == 60.0 && peaks[2].prominence < 0.1);
        // max_hz cuts the search range: only the first bump (and its ripple) is left.
        let low = find_peaks(&f, &a, 100.0, 5);
        assert_eq!(
            low.iter().map(|p| p.frequency_hz).collect::<Vec<_>>(),
            [50.0, 60.0]
        );
    }

    #[test]
    fn window_is_half_open_on_the_grid() {
        let record = SensorRecord {
            path: PathBuf::from("s.csv"),
            time_s: (0..100).map(|i| i as f64 * 0.01).collect(),
            dt_s: 0.01,
            sensors: vec![],
        };
        assert_eq!(
            window_indices(&record, Some(0.2), Some(0.5)).unwrap(),
            20..50
        );
        assert_eq!(window_indices(&record, None, None).unwrap(), 0..100);
        assert!(window_indices(&record, Some(0.5), Some(0.5))
            .unwrap_err()
            .to_string()
            .contains("--from 0.5 s must be below --to 0.5 s"));
        assert!(window_indices(&record, Some(0.5), Some(0.51))
            .unwrap_err()
            .to_string()
            .contains("holds 1 sample"));
    }
}
