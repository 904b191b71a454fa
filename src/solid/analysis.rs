//! The headline figures of the seed 004 §3 verification scenes, computed from the probe
//! series of a run:
//! - `static_deflection`: the final displacement magnitude at the probe
//!   (`tip_deflection_m`) and how much it still moved over the last 10 % of the run;
//! - `frequency`: the dominant frequency of the probe after `after` (`first_frequency_hz`),
//!   by FFT with sub-bin refinement ([`crate::signal::dominant_frequency`]);
//! - `creep`: the strain ε = −u_z / height under a load switched off at t0, against
//!   eq. 14 (relaxation time µ_D / E) and against the laterally constrained closed form
//!   (relaxation time (κ_D + 4/3 µ_D)/(λ + 2µ), see below), with the relaxation time
//!   fitted to the run;
//! - `decay`: the exponential decay rate of the strain oscillation's peaks per shear
//!   viscosity, against the seed's 0.015 and the analytic rate of the layer's first
//!   mode.
//!
//! Why the constrained form: a layer whose top and bottom are held laterally deforms in
//! (nearly) uniaxial strain, where the stress rate that resists ε̇_zz is
//! (λ_D + 2µ_D) ε̇_zz = (κ_D + 4/3 µ_D) ε̇_zz — with zero bulk viscosity κ_D, 4/3 µ_D,
//! not the µ_D that eq. 14 assumes. The creep is then ε = σ/M (1 − e^{−t/τ}),
//! τ = (κ_D + 4/3 µ_D)/M with M = λ + 2µ (= E for ν = 0): a third slower than eq. 14,
//! the lag seed 004 reports. The first mode of that layer (fixed bottom, loaded top,
//! wavenumber k = π/(2H)) decays at rate (κ_D + 4/3 µ_D) k² / (2ρ).

use std::path::Path;

use serde_json::{json, Value};

use super::qdem_run::CaseRun;
use super::scene::SolidScene;
use super::setup::group_area;
use crate::mesh::TetMesh;
use crate::output::CsvSeries;
use crate::qdem::QdemMaterial;
use crate::signal::{dominant_frequency, fit_exponential_decay, peaks, DecayFit};
use crate::{Error, Result};

/// The displacement history of one probe.
#[derive(Debug, Clone)]
pub struct ProbeSeries {
    /// The probe's name.
    pub name: String,
    /// Sample times (s).
    pub times: Vec<f64>,
    /// Mean displacement of the probe's nodes (m).
    pub displacements: Vec<[f64; 3]>,
}

/// The decay rate per unit shear viscosity that seed 004 §3.2 reports (1/(Pa·s²)).
pub const SEED_DECAY_RATE_PER_VISCOSITY: f64 = 0.015;

/// Figures for the scene's `[analysis]` (none without one).
pub fn analyse(
    scene_path: &Path,
    scene: &SolidScene,
    mesh: &TetMesh,
    runs: &[CaseRun],
) -> Result<Vec<(String, Value)>> {
    let Some(spec) = &scene.analysis else {
        return Ok(Vec::new());
    };
    let series = |run: &CaseRun| -> ProbeSeries {
        let s = run
            .probes
            .iter()
            .find(|p| p.name == spec.probe)
            .expect("validated probe name");
        let after = spec.after.map_or(f64::NEG_INFINITY, |t| t.si());
        let keep: Vec<usize> = (0..s.times.len())
            .filter(|&i| s.times[i] >= after)
            .collect();
        ProbeSeries {
            name: s.name.clone(),
            times: keep.iter().map(|&i| s.times[i]).collect(),
            displacements: keep.iter().map(|&i| s.displacements[i]).collect(),
        }
    };
    let mut figures = Vec::new();
    let reference = |value: f64, figures: &mut Vec<(String, Value)>| {
        if let Some(r) = spec.reference {
            figures.push(("reference".into(), json!(r)));
            figures.push(("relative_error_vs_reference".into(), json!((value - r) / r)));
            if let Some(src) = &spec.reference_source {
                figures.push(("reference_source".into(), json!(src)));
            }
        }
    };
    match spec.kind.as_str() {
        "static_deflection" => {
            let s = series(&runs[0]);
            let n = s.times.len();
            let norm = |u: &[f64; 3]| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
            let last = norm(&s.displacements[n - 1]);
            let earlier = norm(&s.displacements[(n * 9) / 10]);
            figures.push(("tip_deflection_m".into(), json!(last)));
            figures.push((
                "tip_deflection_z_m".into(),
                json!(s.displacements[n - 1][2]),
            ));
            figures.push((
                "steady_change_last_10_percent".into(),
                json!(((last - earlier) / last).abs()),
            ));
            reference(last, &mut figures);
        }
        "frequency" => {
            let s = series(&runs[0]);
            let (times, values) = uniform_dominant_component(&s);
            if times.len() < 16 {
                return Err(Error::invalid(
                    scene_path,
                    format!(
                        "key analysis.after: only {} samples after it; run longer",
                        times.len()
                    ),
                ));
            }
            let f = dominant_frequency(&values, times[1] - times[0])?;
            figures.push(("first_frequency_hz".into(), json!(f)));
            figures.push((
                "record_length_s".into(),
                json!(times[times.len() - 1] - times[0]),
            ));
            reference(f, &mut figures);
        }
        "creep" => {
            let height = spec.height.expect("validated").si();
            let (stress, t0) = layer_load(scene_path, scene, mesh)?;
            let mut cases = Vec::new();
            for run in runs {
                let s = series(run);
                let strain: Vec<f64> = s.displacements.iter().map(|u| -u[2] / height).collect();
                cases.push(creep_case(run, &s.times, &strain, stress, t0)?);
            }
            figures.push(("stress_pa".into(), json!(stress)));
            figures.push(("creep".into(), Value::Array(cases)));
        }
        "decay" => {
            let height = spec.height.expect("validated").si();
            layer_load(scene_path, scene, mesh)?;
            let mut cases = Vec::new();
            let mut ratios = Vec::new();
            let mut analytic = f64::NAN;
            for run in runs {
                let s = series(run);
                let strain: Vec<f64> = s.displacements.iter().map(|u| -u[2] / height).collect();
                let m = &run.material;
                let fit = swing_decay(&s.times, &strain)?;
                let mu = m.shear_viscosity;
                let k = std::f64::consts::PI / (2.0 * height);
                let rate_analytic = longitudinal_viscosity(m) * k * k / (2.0 * m.density);
                analytic = rate_analytic / mu;
                ratios.push(fit.rate / mu);
                cases.push(json!({
                    "name": run.name,
                    "shear_viscosity_pa_s": mu,
                    "decay_rate_per_s": fit.rate,
                    "decay_rate_per_viscosity": fit.rate / mu,
                    "analytic_decay_rate_per_s": rate_analytic,
                    "fit_r_squared": fit.r_squared,
                }));
            }
            let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
            let spread = ratios.iter().fold(0.0f64, |a, r| a.max((r - mean).abs())) / mean;
            figures.push(("decay_rate_per_viscosity".into(), Value::Array(cases)));
            figures.push(("decay_rate_per_viscosity_mean".into(), json!(mean)));
            figures.push((
                "decay_rate_per_viscosity_max_deviation".into(),
                json!(spread),
            ));
            figures.push(("decay_rate_per_viscosity_analytic".into(), json!(analytic)));
            figures.push((
                "decay_rate_per_viscosity_seed".into(),
                json!(SEED_DECAY_RATE_PER_VISCOSITY),
            ));
        }
        other => unreachable!("validated analysis kind {other}"),
    }
    Ok(figures)
}

/// Decay of an oscillation about an unknown equilibrium: half the swing between each
/// extreme and the next (a maximum and the following minimum, or the reverse), at the
/// mid time, fitted by A e^{−rate t}. Swings below 1e-3 of the largest are round-off
/// and left out. The equilibrium cancels, so neither the static value nor its
/// discretisation error enters the rate.
pub fn swing_decay(times: &[f64], values: &[f64]) -> Result<DecayFit> {
    let negated: Vec<f64> = values.iter().map(|v| -v).collect();
    let mut extremes: Vec<usize> = peaks(values);
    extremes.extend(peaks(&negated));
    extremes.sort_unstable();
    let (mut t, mut a) = (Vec::new(), Vec::new());
    for w in extremes.windows(2) {
        t.push(0.5 * (times[w[0]] + times[w[1]]));
        a.push(0.5 * (values[w[0]] - values[w[1]]).abs());
    }
    let largest = a.iter().copied().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..a.len()).filter(|&i| a[i] > 1e-3 * largest).collect();
    if keep.len() < 3 {
        return Err(Error::Message(format!(
            "decay analysis: only {} swings above 1e-3 of the largest; run longer",
            keep.len()
        )));
    }
    let t: Vec<f64> = keep.iter().map(|&i| t[i]).collect();
    let a: Vec<f64> = keep.iter().map(|&i| a[i]).collect();
    fit_exponential_decay(&t, &a)
}

/// P-wave modulus M = λ + 2µ (Pa): the stiffness of a laterally constrained layer.
pub fn p_modulus(m: &QdemMaterial) -> f64 {
    m.lame_lambda() + 2.0 * m.lame_mu()
}

/// The viscosity a laterally constrained layer feels, λ_D + 2µ_D = κ_D + 4/3 µ_D (Pa·s).
pub fn longitudinal_viscosity(m: &QdemMaterial) -> f64 {
    m.viscous_lambda() + 2.0 * m.viscous_mu()
}

/// Kelvin–Voigt creep and recovery under a stress σ applied at 0 and removed at t0:
/// ε = ε∞ (1 − e^{−t/τ}) before t0, ε∞ e^{−t/τ} (e^{t0/τ} − 1) after (eq. 14 with the
/// sign of its recovery branch written so that ε stays positive).
pub fn kelvin_voigt_creep(t: f64, strain_inf: f64, tau: f64, t0: Option<f64>) -> f64 {
    match t0 {
        Some(t0) if t >= t0 => strain_inf * (-(t - t0) / tau).exp() * (1.0 - (-t0 / tau).exp()),
        _ => strain_inf * (1.0 - (-t / tau).exp()),
    }
}

/// Stress of the scene's first load over its group's area, and its switch-off time.
fn layer_load(scene_path: &Path, scene: &SolidScene, mesh: &TetMesh) -> Result<(f64, Option<f64>)> {
    let load = scene.load.first().ok_or_else(|| {
        Error::invalid(
            scene_path,
            "key load: creep and decay analyses need a [[load]]",
        )
    })?;
    let area = group_area(mesh, &load.group);
    if area <= 0.0 {
        return Err(Error::invalid(
            scene_path,
            format!("key load[0].group: \"{}\" has no surface area", load.group),
        ));
    }
    let force = load
        .force
        .iter()
        .map(|f| f.si() * f.si())
        .sum::<f64>()
        .sqrt();
    let t0 = match &load.time {
        Some(t) if t.kind == "switch_off" => Some(t.t0.expect("validated").si()),
        _ => None,
    };
    Ok((force / area, t0))
}

fn creep_case(
    run: &CaseRun,
    times: &[f64],
    strain: &[f64],
    stress: f64,
    t0: Option<f64>,
) -> Result<Value> {
    let m = &run.material;
    let (e, mu) = (m.young_modulus, m.shear_viscosity);
    let strain_inf = stress / p_modulus(m);
    // The shape g(t) = creep(t; ε∞ = 1, τ); its best amplitude is Σ ε g / Σ g². The
    // amplitude is fitted because the plateau of a node under equal nodal forces on an
    // unstructured face differs from σ/M by the mesh's load distribution (it is σ/M
    // for consistent loads); the time constant is what eq. 14 is about.
    let shape = |tau: f64| -> Vec<f64> {
        times
            .iter()
            .map(|&t| kelvin_voigt_creep(t, 1.0, tau, t0))
            .collect()
    };
    let amplitude = |g: &[f64]| -> f64 {
        let num: f64 = g.iter().zip(strain).map(|(g, s)| g * s).sum();
        let den: f64 = g.iter().map(|g| g * g).sum();
        num / den
    };
    let rms = |tau: f64| -> f64 {
        let g = shape(tau);
        let a = amplitude(&g);
        let sum: f64 = g.iter().zip(strain).map(|(g, s)| (s - a * g).powi(2)).sum();
        (sum / times.len() as f64).sqrt() / a.abs()
    };
    let tau_eq14 = mu / e;
    let tau_corrected = longitudinal_viscosity(m) / p_modulus(m);
    let tau_fit = golden_minimum(
        |log_tau| rms(log_tau.exp()),
        (tau_eq14 / 30.0).ln(),
        (tau_eq14 * 30.0).ln(),
    )
    .exp();
    let fitted_amplitude = amplitude(&shape(tau_fit));
    let scaled = |tau: f64, a: f64| -> Vec<f64> { shape(tau).iter().map(|g| a * g).collect() };
    write_creep_csv(
        &run.dir.join("creep.csv"),
        times,
        strain,
        &scaled(tau_eq14, fitted_amplitude),
        &scaled(tau_corrected, fitted_amplitude),
    )?;
    Ok(json!({
        "name": run.name,
        "shear_viscosity_pa_s": mu,
        "eq14_relaxation_time_s": tau_eq14,
        "corrected_relaxation_time_s": tau_corrected,
        "fitted_relaxation_time_s": tau_fit,
        "fitted_over_corrected": tau_fit / tau_corrected,
        "fitted_over_eq14": tau_fit / tau_eq14,
        "eq14_rms_error": rms(tau_eq14),
        "corrected_rms_error": rms(tau_corrected),
        "fitted_rms_error": rms(tau_fit),
        "closed_form_strain": strain_inf,
        "fitted_plateau_strain": fitted_amplitude,
    }))
}

/// Minimises a unimodal function on [a, b] by golden-section search (60 iterations:
/// the bracket shrinks by 0.618⁶⁰ ≈ 3e-13).
fn golden_minimum(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - r * (b - a), a + r * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..60 {
        if fc < fd {
            b = d;
            (d, fd) = (c, fc);
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            (c, fc) = (d, fd);
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}

/// The uniformly sampled part of a series (a forced last sample may break the spacing)
/// and its displacement component of largest variance.
fn uniform_dominant_component(s: &ProbeSeries) -> (Vec<f64>, Vec<f64>) {
    let mut n = s.times.len();
    if n >= 3 {
        let h = s.times[1] - s.times[0];
        let last = s.times[n - 1] - s.times[n - 2];
        if (last - h).abs() > 1e-6 * h {
            n -= 1;
        }
    }
    let variance = |d: usize| {
        let mean = s.displacements[..n].iter().map(|u| u[d]).sum::<f64>() / n as f64;
        s.displacements[..n]
            .iter()
            .map(|u| (u[d] - mean).powi(2))
            .sum::<f64>()
    };
    let d = (0..3)
        .max_by(|&a, &b| variance(a).total_cmp(&variance(b)))
        .unwrap_or(2);
    (
        s.times[..n].to_vec(),
        s.displacements[..n].iter().map(|u| u[d]).collect(),
    )
}

/// Writes `creep.csv` (time, strain of the run, eq. 14 and the constrained closed form,
/// both scaled to the run's fitted plateau so that the columns compare time constants)
/// for a case, for charts.
pub fn write_creep_csv(
    path: &Path,
    times: &[f64],
    strain: &[f64],
    eq14: &[f64],
    corrected: &[f64],
) -> Result<()> {
    let mut csv = CsvSeries::create(
        path,
        &["time_s", "strain", "eq14_strain", "constrained_strain"],
    )?;
    for i in 0..times.len() {
        csv.push(&[times[i], strain[i], eq14[i], corrected[i]])?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn creep_closed_form_is_continuous_and_recovers() {
        let (inf, tau, t0) = (2.0, 0.1, 0.5);
        let before = kelvin_voigt_creep(t0 - 1e-12, inf, tau, Some(t0));
        let after = kelvin_voigt_creep(t0, inf, tau, Some(t0));
        assert!((before - after).abs() < 1e-9);
        assert!(kelvin_voigt_creep(5.0, inf, tau, Some(t0)) < 1e-12);
        assert!(
            (kelvin_voigt_creep(0.1, inf, tau, None) - inf * (1.0 - (-1f64).exp())).abs() < 1e-12
        );
    }

    #[test]
    fn golden_section_finds_a_parabola_minimum() {
        let x = golden_minimum(|x| (x - 0.3).powi(2), -2.0, 5.0);
        assert!((x - 0.3).abs() < 1e-9);
    }
}
