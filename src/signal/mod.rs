//! Signal processing for solver time series: spectra, dominant frequencies, decay fits.
