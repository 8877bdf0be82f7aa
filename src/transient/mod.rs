//! Explicit time marching to the periodic steady state: the independent cross-check of
//! harmonic balance.
