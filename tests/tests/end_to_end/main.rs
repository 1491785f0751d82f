//! End to end: simulated and real recordings through the core, the host and the firmware,
//! against ground truth. One test binary, since each links the host library and HDF5.
//!
//! The slow tier (`bash scripts/test-slow.sh`, docs/testing.md) runs the tests ignored here
//! under a `slow` module; CI runs a smoke case of each. `firmware_qemu` is ignored by a plain
//! `cargo test` (it needs QEMU): `scripts/test.sh` runs it.

mod calibration;
mod detection;
mod firmware_qemu;
mod golden;
mod link;
mod opencv;
mod physics;
mod prophesee_files;
mod prophesee_real;
