//! Fuzzes the Prophesee RAW reader: bytes starting with `%` as they are, others after a
//! header naming the encoding their first byte picks (so the decoder behind it is reached).
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "reader_common.rs"]
mod reader_common;

fuzz_target!(|data: &[u8]| {
    if data.first() == Some(&b'%') {
        return reader_common::read("f.raw", data, true);
    }
    let Some((&pick, body)) = data.split_first() else { return };
    let header: &[u8] = match pick % 4 {
        0 => b"% evt 2.0\n% format EVT2;height=480;width=640\n% end\n",
        1 => b"% evt 2.1\n% end\n",
        2 => b"% format EVT21;height=320;width=320\n% end\n",
        _ => b"% evt 3.0\n% geometry 1280x720\n% end\n",
    };
    reader_common::read("f.raw", &[header, body].concat(), true);
});
