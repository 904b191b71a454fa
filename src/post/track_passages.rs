//! The sleeper's settlement passage by passage: how much each bogie (or each group of
//! axles close together) sinks the sleeper, from a track run's `track.csv`.
//!
//! Seed 004 §4.1 reads its Figure 8 car by car ("suddenly settled during the passage of
//! the first car", then a "stable period"); a table per passage says whether a run
//! reaches that stable period, and where its settlement is made.
//!
//! A passage is a stretch of the record where the rail-seat load (Rp1 + Rp2, averaged
//! over [`SMOOTHING_S`] to take out the roughness) stays above [`THRESHOLD`] of its
//! largest value: the axles of one bogie keep the load up between them (the rail
//! spreads each axle over ±1.5 m), and it falls to nothing between bogies. The record
//! is cut midway between passages, so the passages' settlements add up to the whole
//! (from t = 0, the load's start, to the end).

use std::path::Path;

use super::track_sensors::read_table;
use crate::Result;

/// Width of the moving average over the load (s): one period of the roughness's slowest
/// component (50 Hz, which it then takes out), shorter than an axle's passage (≈ 0.1 s
/// at 115 km/h).
pub const SMOOTHING_S: f64 = 0.02;

/// Fraction of the largest smoothed load above which the sleeper is under a passage.
pub const THRESHOLD: f64 = 0.1;

/// One passage of axles over the sleeper.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Passage {
    /// When the smoothed load rose above the threshold (s).
    pub load_from_s: f64,
    /// When it fell below it again (s; the record's end if it did not).
    pub load_to_s: f64,
    /// Where the record is cut before it (s).
    pub from_s: f64,
    /// Where the record is cut after it (s).
    pub to_s: f64,
    /// The sleeper's settlement between the two cuts (m; negative: down).
    pub settlement_m: f64,
    /// The largest smoothed load in it (N).
    pub peak_load_n: f64,
}

/// The passages of a record: `time` (s, increasing), the total rail-seat `load` (N) and
/// the sleeper's `settlement` (m) at each sample. Samples before t = 0 (the settle) are
/// left out. Empty when the load never rises.
pub fn passages(time: &[f64], load: &[f64], settlement: &[f64]) -> Vec<Passage> {
    // The load's start, t = 0, even if written a round-off below it.
    let start = time.iter().position(|&t| t >= -1e-9).unwrap_or(time.len());
    let (time, load, settlement) = (&time[start..], &load[start..], &settlement[start..]);
    if time.len() < 2 {
        return Vec::new();
    }
    let smooth = moving_average(time, load, SMOOTHING_S);
    let peak = smooth.iter().copied().fold(0.0, f64::max);
    if peak <= 0.0 {
        return Vec::new();
    }
    let above: Vec<bool> = smooth.iter().map(|&l| l > THRESHOLD * peak).collect();
    let mut spans: Vec<(usize, usize)> = Vec::new();
    let mut i = 0;
    while i < above.len() {
        if above[i] {
            let j = (i..above.len()).find(|&j| !above[j]).unwrap_or(above.len());
            spans.push((i, j - 1));
            i = j;
        } else {
            i += 1;
        }
    }
    let last = time.len() - 1;
    let cut = |k: usize| -> usize {
        // Midway between passage k − 1's end and passage k's start.
        if k == 0 {
            0
        } else if k == spans.len() {
            last
        } else {
            (spans[k - 1].1 + spans[k].0) / 2
        }
    };
    spans
        .iter()
        .enumerate()
        .map(|(k, &(a, b))| {
            let (from, to) = (cut(k), cut(k + 1));
            Passage {
                load_from_s: time[a],
                load_to_s: time[b],
                from_s: time[from],
                to_s: time[to],
                settlement_m: settlement[to] - settlement[from],
                peak_load_n: smooth[a..=b].iter().copied().fold(f64::MIN, f64::max),
            }
        })
        .collect()
}

/// The centred moving average of `values` over `width` seconds of `time` (the window
/// shrinks at the ends).
fn moving_average(time: &[f64], values: &[f64], width: f64) -> Vec<f64> {
    let dt = (time[time.len() - 1] - time[0]) / (time.len() - 1) as f64;
    let half = (0.5 * width / dt).round() as usize;
    let mut prefix = vec![0.0; values.len() + 1];
    for (k, v) in values.iter().enumerate() {
        prefix[k + 1] = prefix[k] + v;
    }
    (0..values.len())
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(values.len()));
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect()
}

/// Reads `time_s`, `rp1_n + rp2_n` and `sleeper_settlement_m` from a run's `track.csv`
/// (as `ballast-qdem` writes it) and returns its passages.
pub fn read_passages(path: &Path) -> Result<Vec<Passage>> {
    let table = read_table(path)?;
    let load: Vec<f64> = table
        .column("rp1_n")?
        .iter()
        .zip(table.column("rp2_n")?)
        .map(|(a, b)| a + b)
        .collect();
    Ok(passages(
        &table.column("time_s")?,
        &load,
        &table.column("sleeper_settlement_m")?,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two bogies of two axles (bumps of 60 kN, 0.1 s wide) at 0.1 / 0.16 s and
    /// 0.5 / 0.56 s, 50 Hz roughness of ±5 kN on top; the sleeper sinks 2 mm under
    /// the first bogie and 0.5 mm under the second, in steps at each axle.
    fn record() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let dt = 1e-4;
        let time: Vec<f64> = (-200..8000).map(|k| k as f64 * dt).collect();
        let bump = |t: f64, at: f64| {
            let x = (t - at) / 0.05;
            if x.abs() < 1.0 {
                60e3 * (1.0 - x * x)
            } else {
                0.0
            }
        };
        let axles = [0.1, 0.16, 0.5, 0.56];
        let load: Vec<f64> = time
            .iter()
            .map(|&t| {
                let sum: f64 = axles.iter().map(|&a| bump(t, a)).sum();
                if sum > 0.0 {
                    sum + 5e3 * (2.0 * std::f64::consts::PI * 50.0 * t).sin()
                } else {
                    0.0
                }
            })
            .collect();
        let steps = [
            (0.1, -1.2e-3),
            (0.16, -0.8e-3),
            (0.5, -0.3e-3),
            (0.56, -0.2e-3),
        ];
        let settlement = time
            .iter()
            .map(|&t| steps.iter().filter(|s| t >= s.0).map(|s| s.1).sum())
            .collect();
        (time, load, settlement)
    }

    #[test]
    fn each_bogie_is_one_passage_and_the_passages_add_up() {
        let (time, load, settlement) = record();
        let p = passages(&time, &load, &settlement);
        assert_eq!(p.len(), 2, "{p:?}");
        assert!((p[0].settlement_m + 2.0e-3).abs() < 1e-12, "{:?}", p[0]);
        assert!((p[1].settlement_m + 0.5e-3).abs() < 1e-12, "{:?}", p[1]);
        // The load rises above 10 % of its peak a little after the first bump starts
        // (0.05 s) and falls below it before the last one ends (0.21 s).
        assert!(
            p[0].load_from_s > 0.05 && p[0].load_from_s < 0.07,
            "{:?}",
            p[0]
        );
        assert!(p[0].load_to_s > 0.19 && p[0].load_to_s < 0.21, "{:?}", p[0]);
        // The cut between them is midway through the quiet stretch; the first starts
        // at t = 0 (the settle before it is left out), the last ends with the record.
        assert_eq!(p[0].from_s, 0.0);
        assert!((p[0].to_s - 0.5 * (p[0].load_to_s + p[1].load_from_s)).abs() < 2e-4);
        assert_eq!(p[0].to_s, p[1].from_s);
        assert!((p[1].to_s - 0.7999).abs() < 1e-9);
        let total: f64 = p.iter().map(|p| p.settlement_m).sum();
        assert!((total - settlement[settlement.len() - 1]).abs() < 1e-15);
    }

    #[test]
    fn a_record_without_load_has_no_passage() {
        let time = [0.0, 0.1, 0.2];
        assert!(passages(&time, &[0.0; 3], &[0.0, -1e-3, -2e-3]).is_empty());
        assert!(passages(&[-0.1, -0.05], &[1.0, 1.0], &[0.0, 0.0]).is_empty());
    }
}
