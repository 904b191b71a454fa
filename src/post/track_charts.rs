//! The charts of `ballast-post spectra`: smoothed spectra, load spectra and mobilities
//! against frequency, and the displacement (seed 004 Figure 8) and acceleration (Figures
//! 9a, 11a) histories of the sensors.

use plotters::coord::Shift;
use plotters::prelude::{DrawingArea, DrawingBackend};

use std::path::{Path, PathBuf};

use super::chart::{line_panel, write_svg_png, Figure, LinePanel, Stacked};
use super::track_sensors::{Sensor, SensorRecord};
use super::track_spectra::TrackSpectra;
use crate::Result;

/// Draws the spectra chart to `base.svg` and `base.png`: acceleration spectra, and with
/// a load the load spectra and the mobilities, log amplitude against frequency.
pub(crate) fn draw_spectra(spectra: &TrackSpectra, base: &Path) -> Result<Vec<PathBuf>> {
    let height = if spectra.load.is_some() { 1300 } else { 600 };
    write_svg_png(&SpectraChart(spectra), base, (1100, height))
}

/// Draws the histories chart to `base.svg` and `base.png`: lateral and vertical
/// displacement of every sensor, then each sensor group's acceleration.
pub(crate) fn draw_histories(
    record: &SensorRecord,
    spectra: &TrackSpectra,
    base: &Path,
) -> Result<Vec<PathBuf>> {
    let chart = HistoriesChart { record, spectra };
    let height = 330 * chart.panels().len() as u32;
    write_svg_png(&chart, base, (1100, height))
}

/// log10 of each amplitude (floored at 10⁻⁹ of the largest) against frequency.
fn log_line(f: &[f64], a: &[f64]) -> Vec<(f64, f64)> {
    let floor = 1e-9
        * a.iter()
            .copied()
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
    f.iter()
        .zip(a)
        .filter(|(_, v)| v.is_finite())
        .map(|(f, v)| (*f, v.max(floor).max(f64::MIN_POSITIVE).log10()))
        .collect()
}

struct SpectraChart<'a>(&'a TrackSpectra);

impl Figure for SpectraChart<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let s = self.0;
        let f = &s.frequencies_hz;
        let c = s.component.letter();
        let title = |what: &str| {
            format!(
                "{what}, Parzen {} Hz, {:.3}–{:.3} s",
                s.bandwidth_hz, s.window_s[0], s.window_s[1]
            )
        };
        let mut panels = vec![LinePanel {
            title: title(&format!("acceleration a{c} spectra")),
            x_desc: "frequency (Hz)",
            y_desc: "amplitude (m/s²)",
            log10_y: true,
            series: s
                .sensors
                .iter()
                .map(|x| (x.name.clone(), log_line(f, &x.acceleration)))
                .collect(),
            shade_x: None,
        }];
        if let Some(l) = &s.load {
            panels.push(LinePanel {
                title: title("rail-seat load spectra"),
                x_desc: "frequency (Hz)",
                y_desc: "amplitude (N)",
                log10_y: true,
                series: vec![
                    ("Rp1".into(), log_line(f, &l.rp1)),
                    ("Rp2".into(), log_line(f, &l.rp2)),
                    ("Rp1 + Rp2".into(), log_line(f, &l.total)),
                ],
                shade_x: None,
            });
            panels.push(LinePanel {
                title: title(&format!("mobility |V{c}| / |Rp1 + Rp2|")),
                x_desc: "frequency (Hz)",
                y_desc: "mobility ((m/s)/N)",
                log10_y: true,
                series: s
                    .sensors
                    .iter()
                    .filter_map(|x| Some((x.name.clone(), log_line(f, x.mobility.as_ref()?))))
                    .collect(),
                shade_x: None,
            });
        }
        let areas = root.split_evenly((panels.len(), 1));
        for (area, panel) in areas.iter().zip(&panels) {
            line_panel(area, panel)?;
        }
        Ok(())
    }
}

struct HistoriesChart<'a> {
    record: &'a SensorRecord,
    spectra: &'a TrackSpectra,
}

/// At most ~2 × `buckets` points of a long history: the minimum and the maximum of each
/// bucket, in time order, so spikes stay visible in the chart.
pub(crate) fn decimate(t: &[f64], v: &[f64], scale: f64, buckets: usize) -> Vec<(f64, f64)> {
    let size = t.len().div_ceil(buckets).max(1);
    let mut out = Vec::with_capacity(2 * buckets + 2);
    for start in (0..t.len()).step_by(size) {
        let end = (start + size).min(t.len());
        let (lo, hi) = (start..end).fold((start, start), |(lo, hi), i| {
            (
                if v[i] < v[lo] { i } else { lo },
                if v[i] > v[hi] { i } else { hi },
            )
        });
        for i in if lo <= hi { [lo, hi] } else { [hi, lo] } {
            out.push((t[i], scale * v[i]));
        }
    }
    out
}

impl HistoriesChart<'_> {
    /// Lateral and vertical displacement of every sensor (seed 004 Figure 8), then the
    /// acceleration of each group of sensors that share a name prefix (S…, B…).
    fn panels(&self) -> Vec<LinePanel<'static>> {
        let t = &self.record.time_s;
        let sensors = &self.record.sensors;
        let line = |s: &Sensor, v: &[f64], scale| (s.name.clone(), decimate(t, v, scale, 1500));
        let mut panels = vec![
            LinePanel {
                title: "lateral displacement uy".into(),
                x_desc: "time (s)",
                y_desc: "uy (mm)",
                log10_y: false,
                series: sensors
                    .iter()
                    .map(|s| line(s, &s.displacement_m[1], 1e3))
                    .collect(),
                shade_x: None,
            },
            LinePanel {
                title: "vertical displacement uz (settlement negative)".into(),
                x_desc: "time (s)",
                y_desc: "uz (mm)",
                log10_y: false,
                series: sensors
                    .iter()
                    .map(|s| line(s, &s.displacement_m[2], 1e3))
                    .collect(),
                shade_x: None,
            },
        ];
        let c = self.spectra.component;
        let mut groups: Vec<String> = Vec::new();
        for s in sensors {
            let group: String = s.name.chars().take_while(|ch| ch.is_alphabetic()).collect();
            if !groups.contains(&group) {
                groups.push(group);
            }
        }
        for group in groups {
            let members = sensors.iter().filter(|s| {
                s.name
                    .chars()
                    .take_while(|ch| ch.is_alphabetic())
                    .collect::<String>()
                    == group
            });
            panels.push(LinePanel {
                title: format!(
                    "acceleration a{} of {group}… (spectral window shaded)",
                    c.letter()
                ),
                x_desc: "time (s)",
                y_desc: "acceleration (m/s²)",
                log10_y: false,
                series: members
                    .map(|s| line(s, &s.acceleration_m_per_s2[c.index()], 1.0))
                    .collect(),
                shade_x: Some((self.spectra.window_s[0], self.spectra.window_s[1])),
            });
        }
        panels
    }
}

impl Figure for HistoriesChart<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        Stacked(self.panels()).draw(root)
    }
}
