//! Fuzzes the EVT 2.1 (both half orders) decoder of evcal_core::evt (evt_common.rs says what is checked).
#![no_main]

#[allow(unused_imports)]
use evcal_core::evt::{Encoding, Evt21Order};
use libfuzzer_sys::fuzz_target;

#[path = "evt_common.rs"]
mod evt_common;

fuzz_target!(|data: &[u8]| {
    let encoding = if data.first().is_some_and(|b| b & 1 == 1) {
        Encoding::Evt21(Evt21Order::HighHalfFirst)
    } else {
        Encoding::Evt21(Evt21Order::LowHalfFirst)
    };
    evt_common::check(encoding, data);
});
