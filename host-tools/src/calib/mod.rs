//! Camera calibration solver.
