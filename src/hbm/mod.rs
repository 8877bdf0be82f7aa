//! Harmonic balance.
