//! Fuzzes the EVT 2.0 decoder of evcal_core::evt (evt_common.rs says what is checked).
#![no_main]

#[allow(unused_imports)]
use evcal_core::evt::{Encoding, Evt21Order};
use libfuzzer_sys::fuzz_target;

#[path = "evt_common.rs"]
mod evt_common;

fuzz_target!(|data: &[u8]| {
    let encoding = Encoding::Evt2;
    evt_common::check(encoding, data);
});
