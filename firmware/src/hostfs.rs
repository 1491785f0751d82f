//! Host files and the command line through semihosting: only the emulator has them.
//!
//! QEMU passes `-append` to the program as its command line (after the image's path), and
//! serves semihosting file calls from the host's file system. The firmware uses both to read
//! a bulk replay file fast (see `evcal_firmware::bulk`).

use core::convert::Infallible;
use cortex_m_semihosting::{nr, syscall, syscall1};

/// Longest command line read; longer ones are cut.
pub const CMDLINE_MAX: usize = 256;

/// The command line QEMU was given (`-append`), without the image's path; empty if none.
pub fn cmdline(buf: &mut [u8; CMDLINE_MAX]) -> &str {
    // SYS_GET_CMDLINE takes {buffer, length} and writes the length used back.
    let mut block = [buf.as_mut_ptr() as usize, CMDLINE_MAX - 1];
    // SAFETY: the block describes `buf`, which outlives the call.
    let failed = unsafe { syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) } != 0;
    if failed {
        return "";
    }
    let len = block[1].min(CMDLINE_MAX - 1);
    let line = core::str::from_utf8(&buf[..len]).unwrap_or("").trim_end_matches('\0');
    // QEMU prefixes the kernel's path.
    match line.split_once(' ') {
        Some((_, rest)) => rest.trim(),
        None => "",
    }
}

/// Longest file path accepted.
pub const PATH_MAX: usize = 240;

/// A host file opened for reading.
pub struct HostFile {
    handle: usize,
}

impl HostFile {
    /// Opens `path` read-only, in binary mode. `None` if the host refuses or the path is
    /// longer than [`PATH_MAX`].
    pub fn open(path: &str) -> Option<Self> {
        let mut z = [0u8; PATH_MAX + 1];
        if path.len() > PATH_MAX || path.as_bytes().contains(&0) {
            return None;
        }
        z[..path.len()].copy_from_slice(path.as_bytes());
        // SAFETY: `z` is a NUL-terminated string of `path.len()` bytes that outlives the call.
        let h = unsafe { syscall!(OPEN, z.as_ptr(), nr::open::R_BINARY, path.len()) } as isize;
        (h >= 0).then_some(Self { handle: h as usize })
    }
}

impl embedded_io::ErrorType for HostFile {
    type Error = Infallible;
}

impl embedded_io::Read for HostFile {
    /// Reads up to `buf.len()` bytes; 0 at the end of the file (a host error reads as the end).
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Infallible> {
        if buf.is_empty() {
            return Ok(0);
        }
        // SYS_READ returns the number of bytes *not* read.
        // SAFETY: `buf` is writable for `buf.len()` bytes for the duration of the call.
        let left = unsafe { syscall!(READ, self.handle, buf.as_mut_ptr(), buf.len()) };
        Ok(buf.len().saturating_sub(left))
    }
}

impl Drop for HostFile {
    fn drop(&mut self) {
        // SAFETY: closes the handle this value owns.
        unsafe { syscall!(CLOSE, self.handle) };
    }
}
