//! Simulated event camera watching an asymmetric circle grid, with ground truth.
