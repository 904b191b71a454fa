//! Signal processing for solver time series: spectra, dominant frequencies, decay fits.
//!
//! - [`amplitude_spectrum`] / [`amplitude_spectrum_padded`]: one-sided linear amplitude
//!   spectrum by FFT (rustfft), scaled so a sinusoid of amplitude A peaks at ≈ A;
//! - [`dominant_frequency`]: the main frequency of a short record to ≪ 0.1 % (a
//!   cantilever's first frequency from a few periods of tip displacement);
//! - [`parzen_smooth`]: Parzen spectral-window smoothing with a stated bandwidth
//!   convention (train-impact acceleration spectra, seed 004);
//! - [`peaks`], [`fit_exponential_decay`], [`decay_rate_of_oscillation`]: the decay
//!   rate of a damped oscillation from its envelope.
//!
//! Bad input (empty or mismatched series, non-finite values, a step that is not
//! positive) gives a one-line [`crate::Error::Message`] naming the function and argument.

mod decay;
mod frequency;
mod parzen;
mod spectrum;
mod validate;
mod window;

pub use decay::{decay_rate_of_oscillation, fit_exponential_decay, peaks, DecayFit, PEAK_FLOOR};
pub use frequency::dominant_frequency;
pub use parzen::{parzen_lag_width, parzen_smooth};
pub use spectrum::{amplitude_spectrum, amplitude_spectrum_padded, Spectrum};
pub use window::Window;
