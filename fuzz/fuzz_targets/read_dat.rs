//! Fuzzes the Prophesee DAT reader: bytes starting with `%` as they are, others after a CD
//! header (so that the record checks are reached).
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "reader_common.rs"]
mod reader_common;

fuzz_target!(|data: &[u8]| {
    if data.first() == Some(&b'%') {
        return reader_common::read("f.dat", data, true);
    }
    let header: &[u8] = b"% Height 480\n% Version 2\n% Width 640\n\x0c\x08";
    reader_common::read("f.dat", &[header, data].concat(), true);
});
