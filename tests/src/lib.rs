//! Shared helpers of the end-to-end tests (in `tests/`).

pub mod args;
pub mod faery;
pub mod firmware;
pub mod golden;
pub mod link;
pub mod recorded;
pub mod sweep;
