//! Fuzzes the ROS bag reader (seeded with rosbags' files by scripts/fuzz.sh).
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "reader_common.rs"]
mod reader_common;

// Through a stream only: that copies to a temporary file and reads it, the file's path.
fuzz_target!(|data: &[u8]| reader_common::read("f.bag", data, false));
