//! Data windows applied before a Fourier transform to limit spectral leakage.

/// A data (taper) window applied to a record before its Fourier transform.
///
/// The window trades resolution for leakage: `Rectangular` keeps the narrowest main lobe
/// but leaks strongly (side lobes fall as 1/f), `Hann` doubles the main lobe and makes the
/// side lobes fall as 1/f³, which is what a peak search on a short record needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Window {
    /// No taper: every sample has weight 1.
    Rectangular,
    /// Periodic (DFT-even) Hann window `w[n] = sin²(π n / N)`; its coherent gain is 1/2.
    Hann,
}

impl Window {
    /// The `n` window weights, so callers can see exactly what the spectrum used.
    ///
    /// The Hann window is the periodic form (denominator `n`, not `n − 1`): a sinusoid
    /// on a DFT bin then leaks only into the two neighbouring bins.
    pub fn coefficients(self, n: usize) -> Vec<f64> {
        match self {
            Window::Rectangular => vec![1.0; n],
            Window::Hann => (0..n)
                .map(|i| {
                    let s = (std::f64::consts::PI * i as f64 / n as f64).sin();
                    s * s
                })
                .collect(),
        }
    }
}
