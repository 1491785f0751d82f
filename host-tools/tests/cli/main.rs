//! The `evcal` command and the host library's readers, end to end: one test binary, since
//! each links HDF5 and the command (a binary per file cost CI a link each).
//!
//! The slow tier (`bash scripts/test-slow.sh`, docs/testing.md) runs the tests ignored here
//! under a `slow` module; CI runs a smoke case of each.

mod closed_stdout;
mod faery_aedat4;
mod filled_discs_fallback;
mod formats;
mod golden_detect;
mod hostile_input;
mod info_cli;
mod read_options;
mod report_frames;
mod target;
mod verdict;
