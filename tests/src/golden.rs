//! Golden hashes: the detector's output on fixed simulations, pinned to constants, so that
//! "bit for bit the same" (between commits, and between the host and the firmware) is
//! checked rather than stated.
//!
//! Each constant is the 64-bit FNV-1a hash of one output, byte for byte. The host's run of
//! the core and the firmware under QEMU are both checked against it: where their outputs
//! have the same format, they must hash the same.
//!
//! When a change to the detector's output is intended, the failing test prints the new
//! hash: put it here, and say in the commit why the output changed.
//!
//! This file stands alone (no dependencies, no `crate::` paths): host-tools' CLI test
//! includes it by path, as the CLI's package cannot depend on this one.

/// FNV-1a, 64 bits: the offset basis and prime of the FNV specification.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3))
}

/// The seeded simulation of [`DETECT_JSONL`]: `evcal simulate --seed 7 --seconds 0.47` with
/// the defaults (DAVIS346, 4x11 grid, cone, good light), as `tests/tests/end_to_end/firmware_qemu.rs`'s
/// UART replay simulates it.
pub const DETECT_SEED: u64 = 7;
/// Simulated seconds of [`DETECT_JSONL`]'s recording.
pub const DETECT_SECONDS: f64 = 0.47;
/// Milliseconds between window ticks of [`DETECT_JSONL`]: windows back to back.
pub const DETECT_STEP_MS: u64 = 0;

/// `evcal detect REC --step-ms 0 --events-per-window 4000` (the device's window; the host's
/// default is 8000) on [`DETECT_SEED`]'s recording: its JSON lines, with their newlines (101
/// windows). The same bytes as the firmware's detection frames give,
/// written as `evcal replay` writes them. Each line ends with the sensor's size since issue
/// 44 (`"sensor":[346,260]`; without it the lines hash to the former 0xf306_0bde_7816_0794).
pub const DETECT_JSONL: u64 = 0x13d2_8768_cf36_8299;

/// The seeded simulation of [`BENCH_LINES`]: DAVIS346, 4x11 grid, cone, good light, seed 5,
/// 0.6 s, windows of 4000 events every 5 ms (`tests/tests/end_to_end/firmware_qemu.rs`'s bulk replay).
pub const BENCH_SEED: u64 = 5;
/// Simulated seconds of [`BENCH_LINES`]'s recording.
pub const BENCH_SECONDS: f64 = 0.6;
/// Microseconds between window ticks of [`BENCH_LINES`].
pub const BENCH_STEP_US: u64 = 5_000;

/// The firmware's benchmark-mode window lines (`firmware/src/bench.rs`: counts, and each
/// centre's floats as their bit patterns) with the stage times zeroed, newline-terminated,
/// for [`BENCH_SEED`]'s recording; the host's run of the core written in the same format.
/// Full-precision floats, where [`DETECT_JSONL`] has the wire's fixed point.
pub const BENCH_LINES: u64 = 0xbbbe_98d6_3899_15ee;

/// Asserts that `bytes` (`what`: whose output) hash to `want`, the constant `name` of this
/// file; on a mismatch the message gives the new hash and says how to pin it.
#[track_caller]
pub fn assert_pinned(name: &str, what: &str, bytes: &[u8], want: u64) {
    let got = fnv1a64(bytes);
    assert!(
        got == want,
        "{what}: FNV-1a 64 of the output is {got:#018x}, pinned {want:#018x} ({len} bytes).\n\
         The detector's output changed. If that is intended, set `{name}` in tests/src/golden.rs \
         to {got:#018x} and say why in the commit; if not, this change broke bit-for-bit \
         reproducibility.",
        len = bytes.len()
    );
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn fnv1a64_of_the_specifications_test_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }
}
