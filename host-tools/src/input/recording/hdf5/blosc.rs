//! HDF5's Blosc filter (id 32001, as DSEC and hdf5plugin write it), decoding only, with the
//! chunk checked before c-blosc sees it.
//!
//! The filter that the `hdf5` crate registers hands each chunk to `blosc_decompress`, which
//! has no length argument: it trusts the compressed size in the chunk's own 16-byte header.
//! A corrupt header that claims more bytes than the chunk holds makes c-blosc (and the zstd
//! or LZ4 decoder under it) read past the buffer, which the fuzzer found. This filter takes
//! the filter's place (HDF5 replaces a class registered again under the same id) and lets
//! c-blosc decode only a chunk whose header fits it: the compressed size within the bytes
//! HDF5 read, the decoded size that of the dataset's chunk (HDF5 1.10 copies a whole chunk
//! from whatever a filter returns) and within [`MAX_CHUNK_BYTES`]. Within those bounds c-blosc
//! checks every block offset and size against the header's compressed size, so it stays
//! inside the buffer.
//!
//! evcal writes no Blosc data, so the encoder is absent: HDF5 refuses to write with it.

use hdf5_sys::h5::{H5allocate_memory, H5free_memory};
use hdf5_sys::h5p::H5Pget_filter_by_id2;
use hdf5_sys::h5z::{H5Z_class2_t, H5Zregister, H5Z_CLASS_T_VERS, H5Z_FLAG_REVERSE};
use std::ffi::{c_uint, c_void};
use std::sync::OnceLock;

use super::limits::MAX_CHUNK_BYTES;

/// The id HDF5 files name the Blosc filter by (registered with The HDF Group).
const BLOSC_ID: i32 = 32001;

/// A Blosc chunk's header: version, version of the codec, flags, type size, then three
/// little-endian 32-bit sizes (decoded, block, compressed).
const HEADER_BYTES: usize = 16;

const NAME: &[u8] = b"blosc (evcal, bounds-checked)\0";

/// Registers the filter once, after the `hdf5` crate has registered its own (which it does
/// when the library is first used), so that this one replaces it. Every HDF5 reader calls
/// this before opening a file; the result is that of the one registration.
pub(crate) fn install() -> Result<(), String> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        let class = H5Z_class2_t {
            version: H5Z_CLASS_T_VERS as _,
            id: BLOSC_ID,
            encoder_present: 0,
            decoder_present: 1,
            name: NAME.as_ptr().cast(),
            can_apply: None,
            set_local: None,
            filter: Some(filter),
        };
        // `sync` initialises the library (registering the crate's filters) and holds its lock.
        // SAFETY: the class is copied by HDF5; its name is a static string.
        let status = hdf5::sync::sync(|| unsafe { H5Zregister((&class as *const H5Z_class2_t).cast()) });
        if status < 0 {
            Err("HDF5 refused evcal's Blosc filter".into())
        } else {
            Ok(())
        }
    })
    .clone()
}

/// What a chunk's header says, if the chunk can be decoded safely: the decoded size, which
/// must be `chunk_bytes`, the dataset's chunk size as the writer recorded it. HDF 1.10 takes
/// a filter's output to be a whole chunk and copies from it as much, so a shorter one would
/// be read past its end.
fn decoded_size(chunk: &[u8], chunk_bytes: usize) -> Option<usize> {
    let header = chunk.get(..HEADER_BYTES)?;
    let word = |i: usize| u32::from_le_bytes([header[i], header[i + 1], header[i + 2], header[i + 3]]) as usize;
    let (decoded, compressed) = (word(4), word(12));
    let fits = compressed >= HEADER_BYTES && compressed <= chunk.len();
    (fits && decoded > 0 && decoded == chunk_bytes && decoded <= MAX_CHUNK_BYTES as usize).then_some(decoded)
}

/// A Blosc chunk decoded here (for the chunks evcal reads raw): its header's compressed size
/// within `data`, its decoded size at most `limit`; c-blosc then stays within both.
pub(crate) fn decode(data: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    let header = data.get(..HEADER_BYTES).ok_or("Blosc data shorter than their header")?;
    let word = |i: usize| u32::from_le_bytes([header[i], header[i + 1], header[i + 2], header[i + 3]]) as usize;
    let (decoded, compressed) = (word(4), word(12));
    if compressed < HEADER_BYTES || compressed > data.len() {
        return Err(format!("a Blosc header claiming {compressed} bytes of {}", data.len()));
    }
    if decoded > limit {
        return Err(format!("Blosc data decoding to {decoded} bytes, more than {limit}"));
    }
    let mut out = vec![0u8; decoded];
    if decoded == 0 {
        return Ok(out);
    }
    // SAFETY: c-blosc reads within the header's compressed size (checked within `data`) and
    // writes at most `decoded` bytes to `out`; one thread, no global state.
    let got = unsafe { blosc_src::blosc_decompress_ctx(data.as_ptr().cast(), out.as_mut_ptr().cast(), decoded, 1) };
    if got < 0 || got as usize != decoded {
        return Err("Blosc data corrupt".into());
    }
    out.truncate(got as usize);
    Ok(out)
}

/// Refuses a dataset whose Blosc parameters do not state its chunks' size in bytes (the
/// fourth, which the filter holds every decoded chunk to; a corrupt file can state another).
/// Called on every dataset before it is read.
pub(crate) fn check_parameters(d: &hdf5::Dataset) -> Result<(), String> {
    if !d.filters().iter().any(|f| f.id() == BLOSC_ID) {
        return Ok(());
    }
    let Some(chunk) = d.chunk() else {
        return Err("Blosc-compressed but not chunked: corrupt".into());
    };
    let item = d.dtype().map_err(|e| format!("its type cannot be read ({e})"))?.size() as u128;
    let bytes = chunk.iter().map(|&n| n as u128).product::<u128>() * item;
    let dcpl = d.dcpl().map_err(|e| format!("its compression parameters are corrupt ({e})"))?;
    let (mut flags, mut n, mut values): (c_uint, usize, [c_uint; 8]) = (0, 8, [0; 8]);
    // SAFETY: `values` holds the `n` values asked for; no name is asked for.
    let status = hdf5::sync::sync(|| unsafe {
        H5Pget_filter_by_id2(
            dcpl.id(),
            BLOSC_ID,
            &mut flags,
            &mut n,
            values.as_mut_ptr(),
            0,
            std::ptr::null_mut(),
            std::ptr::null_mut(),
        )
    });
    if status < 0 {
        return Err("its Blosc parameters cannot be read: corrupt".into());
    }
    if n < 4 || u128::from(values[3]) != bytes {
        let stated = if n < 4 { "none".to_string() } else { values[3].to_string() };
        return Err(format!(
            "its Blosc parameters state chunks of {stated} bytes, but its chunks hold {bytes}: corrupt"
        ));
    }
    Ok(())
}

/// HDF5's filter callback: returns the decoded size and swaps `*buf` for the decoded chunk,
/// or returns 0 (a failed filter, which HDF5 reports as a read error) and leaves it.
extern "C" fn filter(
    flags: c_uint,
    cd_nelmts: usize,
    cd_values: *const c_uint,
    nbytes: usize,
    buf_size: *mut usize,
    buf: *mut *mut c_void,
) -> usize {
    if flags & H5Z_FLAG_REVERSE == 0 || buf.is_null() || buf_size.is_null() {
        return 0;
    }
    // hdf5-blosc's parameters: filter version, format version, type size, chunk bytes, ...
    // (the last checked against the dataset by `check_parameters`).
    if cd_values.is_null() || cd_nelmts < 4 {
        return 0;
    }
    // SAFETY: HDF5 passes `cd_nelmts` values.
    let chunk_bytes = unsafe { *cd_values.add(3) as usize };
    // SAFETY: HDF5 hands the filter `*buf`, of `*buf_size` bytes, the first `nbytes` valid.
    let src = unsafe { *buf };
    if src.is_null() {
        return 0;
    }
    let valid = nbytes.min(unsafe { *buf_size });
    let chunk = unsafe { std::slice::from_raw_parts(src as *const u8, valid) };
    let Some(size) = decoded_size(chunk, chunk_bytes) else {
        return 0;
    };
    // SAFETY: memory for HDF5 comes from HDF5's allocator, which frees the old buffer the same way.
    let out = unsafe { H5allocate_memory(size, 0) };
    if out.is_null() {
        return 0;
    }
    // SAFETY: the header's compressed size lies within `chunk` (checked above) and c-blosc
    // writes at most `size` bytes to `out`; one thread, no global state.
    let got = unsafe { blosc_src::blosc_decompress_ctx(src, out, size, 1) };
    if got <= 0 || got as usize != size {
        unsafe { H5free_memory(out) };
        return 0;
    }
    unsafe {
        H5free_memory(src);
        *buf = out;
        *buf_size = size;
    }
    size
}

#[cfg(test)]
mod test {
    use super::*;

    fn header(decoded: u32, compressed: u32) -> Vec<u8> {
        let mut h = vec![2, 1, 1, 8];
        for v in [decoded, 4096, compressed] {
            h.extend_from_slice(&v.to_le_bytes());
        }
        h
    }

    #[test]
    fn a_header_claiming_more_bytes_than_the_chunk_holds_is_refused() {
        let mut chunk = header(800, 64);
        chunk.resize(64, 0);
        assert_eq!(decoded_size(&chunk, 800), Some(800));
        assert_eq!(decoded_size(&chunk[..63], 800), None, "compressed size beyond the chunk");
        assert_eq!(decoded_size(&chunk[..10], 800), None, "no whole header");
    }

    #[test]
    fn a_decoded_size_other_than_the_datasets_chunk_is_refused() {
        let mut chunk = header(801, 64);
        chunk.resize(64, 0);
        assert_eq!(decoded_size(&chunk, 800), None, "more than a chunk");
        let mut short = header(188, 64);
        short.resize(64, 0);
        assert_eq!(decoded_size(&short, 1024), None, "less than a chunk: HDF5 would read past it");
        let mut huge = header(u32::MAX, 64);
        huge.resize(64, 0);
        assert_eq!(decoded_size(&huge, u32::MAX as usize), None, "beyond the chunk limit");
        let mut empty = header(0, 64);
        empty.resize(64, 0);
        assert_eq!(decoded_size(&empty, 0), None);
    }
}
