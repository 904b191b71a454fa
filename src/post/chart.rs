//! Chart helpers shared by the post-processing reports (speed/accuracy chart, track
//! spectra and histories): the font plotters needs, one palette, writing one figure to
//! both SVG and PNG and a panel of labelled lines.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::{Error, Result};

const FONT_FILE: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// Line colours, in order of the series: black first, then the tab10 colours.
pub(crate) const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 0, 0),
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
];

/// Registers DejaVu Sans as plotters' "sans-serif" (once per process): plotters' `ab_glyph`
/// text needs a font given to it, and both SVG and PNG use the same one.
pub(crate) fn register_font() -> Result<()> {
    static DONE: std::sync::OnceLock<std::result::Result<(), String>> = std::sync::OnceLock::new();
    DONE.get_or_init(|| {
        let bytes = std::fs::read(FONT_FILE).map_err(|e| {
            format!("{FONT_FILE}: {e} (install Debian's fonts-dejavu-core: `make setup` does)")
        })?;
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| format!("{FONT_FILE}: not a TrueType font"))
    })
    .clone()
    .map_err(Error::Message)
}

/// A figure that can draw itself on any plotters backend (so one drawing code serves
/// the SVG and the PNG).
pub(crate) trait Figure {
    /// Draws the whole figure on `root` (filled white by the caller).
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String>;
}

/// Draws `figure` to `base.svg` and `base.png` (`base` with its extension replaced) at
/// `size` pixels; returns the two paths.
pub(crate) fn write_svg_png(
    figure: &impl Figure,
    base: &Path,
    size: (u32, u32),
) -> Result<Vec<PathBuf>> {
    register_font()?;
    let svg = base.with_extension("svg");
    let png = base.with_extension("png");
    render(
        figure,
        SVGBackend::new(&svg, size).into_drawing_area(),
        &svg,
    )?;
    render(
        figure,
        BitMapBackend::new(&png, size).into_drawing_area(),
        &png,
    )?;
    Ok(vec![svg, png])
}

fn render<DB: DrawingBackend>(
    figure: &impl Figure,
    root: DrawingArea<DB, Shift>,
    path: &Path,
) -> Result<()> {
    let to_line = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::invalid(path, e.to_string());
    root.fill(&WHITE).map_err(to_line)?;
    figure.draw(&root).map_err(|e| Error::invalid(path, e))?;
    root.present().map_err(to_line)
}

/// Panels stacked top to bottom, each drawn by [`line_panel`] in an equal share of the
/// height.
pub(crate) struct Stacked<'a>(pub Vec<LinePanel<'a>>);

impl Figure for Stacked<'_> {
    fn draw<DB: DrawingBackend>(
        &self,
        root: &DrawingArea<DB, Shift>,
    ) -> std::result::Result<(), String> {
        let areas = root.split_evenly((self.0.len(), 1));
        for (area, panel) in areas.iter().zip(&self.0) {
            line_panel(area, panel)?;
        }
        Ok(())
    }
}

/// One panel of [`line_panel`]: labelled lines on linear axes. A panel whose y values
/// are log10 of the data says so with `log10_y`, and its tick labels show 10^y.
pub(crate) struct LinePanel<'a> {
    /// Caption above the panel.
    pub title: String,
    /// X-axis label.
    pub x_desc: &'a str,
    /// Y-axis label.
    pub y_desc: &'a str,
    /// The y values are log10 of the quantity: label ticks as 10^y.
    pub log10_y: bool,
    /// (label, points) of each line, drawn in [`PALETTE`] order.
    pub series: Vec<(String, Vec<(f64, f64)>)>,
    /// An x interval shaded in light grey (e.g. the spectral window), if any.
    pub shade_x: Option<(f64, f64)>,
}

/// Draws `panel` on `area`: axes fitted to the data (5 % margin), one line per series,
/// a legend. Non-finite points are skipped; an empty panel draws only its caption.
pub(crate) fn line_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &LinePanel,
) -> std::result::Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let points = || {
        panel
            .series
            .iter()
            .flat_map(|s| s.1.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite())
    };
    let range = |values: Vec<f64>| {
        let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !lo.is_finite() {
            return (0.0, 1.0);
        }
        let pad = if hi > lo {
            0.05 * (hi - lo)
        } else {
            0.5 * lo.abs().max(1e-12)
        };
        (lo - pad, hi + pad)
    };
    let (x0, x1) = range(points().map(|p| p.0).collect());
    let (y0, y1) = range(points().map(|p| p.1).collect());
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    let log10_y = panel.log10_y;
    let span = y1 - y0;
    let y_format = move |v: &f64| {
        if log10_y {
            format!("{:.0e}", 10f64.powf(*v))
        } else {
            plain_tick(*v, span)
        }
    };
    chart
        .configure_mesh()
        .x_desc(panel.x_desc)
        .y_desc(panel.y_desc)
        .y_label_formatter(&y_format)
        .draw()
        .map_err(err)?;
    if let Some((a, b)) = panel.shade_x {
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(a, y0), (b, y1)],
                RGBColor(220, 220, 220).mix(0.5).filled(),
            )))
            .map_err(err)?;
    }
    for (i, (label, line)) in panel.series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let finite = line
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite());
        chart
            .draw_series(LineSeries::new(finite, colour.stroke_width(1)))
            .map_err(err)?
            .label(label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
    }
    if !panel.series.is_empty() {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

/// A linear-axis tick label: the decimals that a tenth of the span needs when the
/// values are of ordinary size, else 3 significant digits in e-notation; a value within
/// 10⁻⁹ of the span from zero (rounding of the tick grid) is written 0.
fn plain_tick(v: f64, span: f64) -> String {
    if v.abs() <= 1e-9 * span {
        return "0".into();
    }
    let size = v.abs().max(span);
    if (1e-3..1e5).contains(&size) {
        let decimals = (-(0.1 * span).log10().floor()).clamp(0.0, 6.0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.2e}")
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn tick_labels() {
        use super::plain_tick;
        assert_eq!(plain_tick(3.469e-18, 0.03), "0");
        assert_eq!(plain_tick(-0.025, 0.03), "-0.025");
        assert_eq!(plain_tick(1500.0, 6000.0), "1500");
        assert_eq!(plain_tick(-0.5, 0.9), "-0.50");
        assert_eq!(plain_tick(2.5e-9, 1e-8), "2.50e-9");
    }
}
