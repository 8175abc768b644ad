"""Analysis on top of the core: envelopes, spectra, harmonic balance (plots in one module)."""
