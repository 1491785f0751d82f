//! Fuzzes the text reader (`t x y p` lines): reader_common.rs says what is checked.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "reader_common.rs"]
mod reader_common;

fuzz_target!(|data: &[u8]| reader_common::read("f.txt", data, true));
