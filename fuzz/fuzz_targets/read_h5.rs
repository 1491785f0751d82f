//! Fuzzes the HDF5 readers, every layout (E-Calib's events_data, events/{x,y,t,p}, root
//! columns), through the HDF5 C library; seeded with h5py's files by scripts/fuzz.sh.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "reader_common.rs"]
mod reader_common;

// Through a stream only: that copies to a temporary file and reads it, the file's path.
fuzz_target!(|data: &[u8]| reader_common::read("f.h5", data, false));
