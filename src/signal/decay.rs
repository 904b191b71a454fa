//! Peaks of a series and exponential decay fits of a damped oscillation's envelope.

use super::validate::{bad, check_increasing, check_same_len, check_series};
use crate::Result;

/// Peaks smaller than this fraction of the largest are ignored by
/// [`decay_rate_of_oscillation`]: near the noise or rounding floor their heights no longer
/// follow the envelope.
pub const PEAK_FLOOR: f64 = 1e-3;

/// An exponential `amplitude · e^{−rate · t}` fitted to positive data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecayFit {
    /// Amplitude `A` at `t = 0` (unit of the data).
    pub amplitude: f64,
    /// Decay rate (1/s, or 1/unit of the times); positive for decay. For a damped
    /// oscillator it is `ζ ω_n`.
    pub rate: f64,
    /// Coefficient of determination of the straight-line fit of `ln(amplitude)` on `t`
    /// (1 for an exact exponential).
    pub r_squared: f64,
}

/// Indices of the strict local maxima of `samples`: higher than the neighbour on each
/// side. A flat-topped maximum (equal neighbours at the top, higher than the samples on
/// both sides of the plateau) is reported once, at its middle (the left one of two
/// middles). The first and last samples are never peaks; NaN is never a peak and no
/// plateau extends across it. Used to find the envelope points of an oscillation.
pub fn peaks(samples: &[f64]) -> Vec<usize> {
    let mut out = Vec::new();
    let n = samples.len();
    let mut i = 1;
    while i + 1 < n {
        if samples[i] > samples[i - 1] {
            // Walk over a possible plateau starting at i.
            let mut end = i;
            while end + 1 < n && samples[end + 1] == samples[i] {
                end += 1;
            }
            if end + 1 < n && samples[end + 1] < samples[i] {
                out.push(i + (end - i) / 2);
            }
            i = end + 1;
        } else {
            i += 1;
        }
    }
    out
}

/// Least-squares fit of `ln(amplitude) = ln(A) − rate · t` over the points with a positive
/// amplitude (the others are skipped, as the logarithm needs them positive).
///
/// Used for the decay rate of an oscillation from its envelope peaks (see
/// [`decay_rate_of_oscillation`]). Errors if the lengths differ, a value is not finite,
/// or fewer than 2 points with distinct times have positive amplitude.
pub fn fit_exponential_decay(times: &[f64], amplitudes: &[f64]) -> Result<DecayFit> {
    const FUNC: &str = "fit_exponential_decay";
    check_series(FUNC, "times", times, 1)?;
    check_series(FUNC, "amplitudes", amplitudes, 1)?;
    check_same_len(FUNC, "times", times, "amplitudes", amplitudes)?;
    let points: Vec<(f64, f64)> = times
        .iter()
        .zip(amplitudes)
        .filter(|(_, &a)| a > 0.0)
        .map(|(&t, &a)| (t, a.ln()))
        .collect();
    if points.len() < 2 {
        return Err(bad(
            FUNC,
            format!(
                "{} positive amplitudes, at least 2 are needed",
                points.len()
            ),
        ));
    }
    let m = points.len() as f64;
    let t_mean = points.iter().map(|p| p.0).sum::<f64>() / m;
    let y_mean = points.iter().map(|p| p.1).sum::<f64>() / m;
    let stt: f64 = points.iter().map(|p| (p.0 - t_mean).powi(2)).sum();
    let sty: f64 = points.iter().map(|p| (p.0 - t_mean) * (p.1 - y_mean)).sum();
    let syy: f64 = points.iter().map(|p| (p.1 - y_mean).powi(2)).sum();
    if stt <= 0.0 {
        return Err(bad(FUNC, "all positive amplitudes are at the same time"));
    }
    let slope = sty / stt;
    let intercept = y_mean - slope * t_mean;
    let ss_res: f64 = points
        .iter()
        .map(|p| (p.1 - intercept - slope * p.0).powi(2))
        .sum();
    let r_squared = if syy > 0.0 { 1.0 - ss_res / syy } else { 1.0 };
    Ok(DecayFit {
        amplitude: intercept.exp(),
        rate: -slope,
        r_squared,
    })
}

/// Decay of a damped oscillation of `values` about `equilibrium`, sampled at `times`.
///
/// The peaks of `|values − equilibrium|` (two per period) are located with [`peaks`],
/// each refined by the parabola through the three samples around it (vertex time and
/// height; the times need not be uniform), peaks below [`PEAK_FLOOR`] of the largest are
/// dropped, and [`fit_exponential_decay`] is fitted to the rest. For
/// `e^{−ζω t} cos(ω_d t)` the rate is `ζω`, the logarithmic decrement is `rate · 2π/ω_d`.
/// Errors if the series are empty or mismatched, a value is not finite, the times are not
/// strictly increasing, or fewer than 3 peaks remain.
pub fn decay_rate_of_oscillation(
    times: &[f64],
    values: &[f64],
    equilibrium: f64,
) -> Result<DecayFit> {
    const FUNC: &str = "decay_rate_of_oscillation";
    check_series(FUNC, "times", times, 1)?;
    check_series(FUNC, "values", values, 1)?;
    check_same_len(FUNC, "times", times, "values", values)?;
    check_increasing(FUNC, "times", times)?;
    if !equilibrium.is_finite() {
        return Err(bad(
            FUNC,
            format!("equilibrium = {equilibrium} is not finite"),
        ));
    }
    let envelope: Vec<f64> = values.iter().map(|v| (v - equilibrium).abs()).collect();
    let refined: Vec<(f64, f64)> = peaks(&envelope)
        .into_iter()
        .map(|i| parabolic_vertex(&times[i - 1..=i + 1], &envelope[i - 1..=i + 1]))
        .collect();
    let largest = refined.iter().fold(0.0_f64, |m, p| m.max(p.1));
    let (peak_times, peak_heights): (Vec<f64>, Vec<f64>) = refined
        .into_iter()
        .filter(|p| p.1 >= PEAK_FLOOR * largest && p.1 > 0.0)
        .unzip();
    if peak_times.len() < 3 {
        return Err(bad(
            FUNC,
            format!(
                "{} peaks of |values - equilibrium| above {PEAK_FLOOR} of the largest, \
                 at least 3 are needed",
                peak_times.len()
            ),
        ));
    }
    fit_exponential_decay(&peak_times, &peak_heights)
}

/// Vertex `(t, y)` of the parabola through three points whose middle one is the highest;
/// falls back to the middle point if the three are collinear.
fn parabolic_vertex(t: &[f64], y: &[f64]) -> (f64, f64) {
    let (t0, t1, t2) = (t[0] - t[1], 0.0, t[2] - t[1]);
    let d0 = (y[1] - y[0]) / (t1 - t0);
    let d1 = (y[2] - y[1]) / (t2 - t1);
    let curvature = (d1 - d0) / (t2 - t0); // y = y1 + slope·s + curvature·s² about t1
    if curvature.is_nan() || curvature >= 0.0 {
        return (t[1], y[1]);
    }
    // Slope at s = 0 of the interpolating parabola.
    let slope = d0 + curvature * (t1 - t0);
    let s = (-slope / (2.0 * curvature)).clamp(t0, t2);
    (t[1] + s, y[1] + slope * s + curvature * s * s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn peaks_are_strict_maxima_with_plateaus_once() {
        assert_eq!(peaks(&[0.0, 1.0, 0.0, 2.0, 2.0, 0.0, 3.0]), vec![1, 3]);
        assert_eq!(peaks(&[0.0, 5.0, 5.0, 5.0, 1.0]), vec![2]);
        assert_eq!(peaks(&[0.0, 1.0, 1.0, 2.0, 1.0]), vec![3]); // a step is no peak
        assert_eq!(peaks(&[3.0, 1.0, 1.0, 1.0]), Vec::<usize>::new());
        assert_eq!(peaks(&[0.0, f64::NAN, 0.0, 1.0, 0.0]), vec![3]);
        assert!(peaks(&[]).is_empty() && peaks(&[1.0, 2.0]).is_empty());
    }

    #[test]
    fn exact_exponential_is_recovered() {
        // Exact data: only rounding in ln and the sums, ~1e-15; assert 1e-12.
        let t: Vec<f64> = (0..20).map(|i| 0.05 * i as f64).collect();
        let mut a: Vec<f64> = t.iter().map(|t| 2.0 * (-3.0 * t).exp()).collect();
        a[5] = 0.0; // skipped: not positive
        a[7] = -1.0;
        let fit = fit_exponential_decay(&t, &a).unwrap();
        assert!((fit.amplitude - 2.0).abs() < 1e-12 && (fit.rate - 3.0).abs() < 1e-12);
        assert!((fit.r_squared - 1.0).abs() < 1e-12);
    }

    #[test]
    fn damped_oscillation_rate() {
        // e^{−15 t} cos(2π·2500 t) about 0.2, 0.1 s at 1 MHz (400 samples a period, 500
        // envelope peaks). Required 0.5 %. The parabola through three samples misses
        // each peak's height by ~(ω dt)⁴ ≈ 6e-8 relatively, nearly the same at every
        // peak, and the phase of the peak of e^{−αt}cos is the same at all peaks, so
        // only ~1e-8 is left; assert 1e-5.
        let n = 100_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-6).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|t| 0.2 + (-15.0 * t).exp() * (2.0 * PI * 2500.0 * t).cos())
            .collect();
        let fit = decay_rate_of_oscillation(&t, &x, 0.2).unwrap();
        assert!((fit.rate / 15.0 - 1.0).abs() < 1e-5, "rate {}", fit.rate);
        assert!((fit.amplitude - 1.0).abs() < 1e-4 && fit.r_squared > 0.999_999);
    }

    #[test]
    fn peaks_in_the_noise_floor_are_ignored() {
        // Rate 200/s over 0.1 s decays to e^{−20} ≈ 2e-9, below a ±1e-7 ripple at 37 kHz
        // that then makes the tail's peaks: fitted too, they ruin the rate (checked
        // below). Those below 1e-3 of the largest are dropped; the kept ones are
        // ≥ 1e-3, so the ripple shifts their ln by ≤ 1e-4: rate within 0.1 %.
        let n = 100_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-6).collect();
        let x: Vec<f64> = t
            .iter()
            .map(|t| {
                (-200.0 * t).exp() * (2.0 * PI * 2500.0 * t).sin()
                    + 1e-7 * (2.0 * PI * 37_000.0 * t).sin()
            })
            .collect();
        let fit = decay_rate_of_oscillation(&t, &x, 0.0).unwrap();
        assert!((fit.rate / 200.0 - 1.0).abs() < 1e-3, "rate {}", fit.rate);

        let envelope: Vec<f64> = x.iter().map(|v| v.abs()).collect();
        let all = peaks(&envelope);
        let times: Vec<f64> = all.iter().map(|&i| t[i]).collect();
        let heights: Vec<f64> = all.iter().map(|&i| envelope[i]).collect();
        let unfloored = fit_exponential_decay(&times, &heights).unwrap();
        assert!((unfloored.rate / 200.0 - 1.0).abs() > 0.1, "{unfloored:?}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let msg = |r: Result<DecayFit>| r.unwrap_err().to_string();
        assert!(msg(fit_exponential_decay(&[0.0, 1.0], &[1.0]))
            .contains("times has 2 values but amplitudes has 1"));
        assert!(
            msg(fit_exponential_decay(&[0.0, 1.0], &[1.0, -1.0])).contains("1 positive amplitudes")
        );
        assert!(msg(fit_exponential_decay(&[1.0, 1.0], &[1.0, 2.0])).contains("same time"));
        assert!(msg(fit_exponential_decay(&[], &[])).contains("times is empty"));
        let t: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        let one_period: Vec<f64> = t.iter().map(|t| (2.0 * PI * t).sin()).collect();
        assert!(msg(decay_rate_of_oscillation(&t, &one_period, 0.0)).contains("2 peaks"));
        assert!(msg(decay_rate_of_oscillation(&t, &one_period, f64::NAN)).contains("equilibrium"));
        let mut back = t.clone();
        back.swap(10, 11);
        assert!(
            msg(decay_rate_of_oscillation(&back, &one_period, 0.0)).contains("strictly increasing")
        );
        let mut nan = one_period.clone();
        nan[4] = f64::NAN;
        assert!(msg(decay_rate_of_oscillation(&t, &nan, 0.0)).contains("values[4] = NaN"));
    }
}
