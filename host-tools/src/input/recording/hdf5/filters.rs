//! HDF5's compression filters as evcal meets them: a dataset's parameters checked before any
//! chunk is decoded, and what to say when a filter is missing or a chunk does not decode.

use super::limits::MAX_CHUNK_BYTES;

/// Checks a dataset's compression parameters before any chunk is decompressed: hdf5-metno's
/// Blosc filter dereferences a null name on an unknown compressor code (a crash, found by
/// the random-damage test), so parameters that do not parse are refused here.
///
/// Chunks are limited to [`MAX_CHUNK_BYTES`]: HDF5 allocates a whole chunk to read any of it,
/// so a corrupt chunk size would cost that much memory.
pub(crate) fn check_filters(d: &hdf5::Dataset) -> Result<(), String> {
    d.dcpl()
        .and_then(|p| p.get_filters())
        .map(|_| ())
        .map_err(|e| format!("its compression parameters are corrupt ({e})"))?;
    super::blosc::check_parameters(d)?;
    if let Some(chunk) = d.chunk() {
        let item = d.dtype().map(|t| t.size()).unwrap_or(1) as u128;
        let bytes = chunk.iter().map(|&n| n as u128).product::<u128>() * item;
        if bytes > MAX_CHUNK_BYTES as u128 {
            return Err(format!(
                "chunks of {bytes} bytes: corrupt? (evcal reads chunks of up to {MAX_CHUNK_BYTES} bytes)"
            ));
        }
    }
    Ok(())
}

/// When a dataset cannot be read, which of its compression filters evcal lacks (HDF5's own
/// message then only names its plugin directory), or, when it has them all and one failed,
/// that a compressed chunk is corrupt (HDF5 says only that a filter failed).
pub(crate) fn filter_hint(d: &hdf5::Dataset, error: &str) -> String {
    let missing: Vec<String> = d
        .filters()
        .iter()
        .filter_map(|f| match f {
            hdf5::filters::Filter::User(id, _) => Some(format!("{id}{}", filter_name(*id))),
            _ => None,
        })
        .collect();
    if missing.is_empty() {
        return if error.contains("filter returned failure") {
            " (a compressed chunk did not decode: the file is corrupt or truncated there)".into()
        } else {
            String::new()
        };
    }
    format!(
        " (its data are compressed with HDF5 filter {}, which evcal does not build in; it builds in gzip, LZF and \
         Blosc. Point HDF5_PLUGIN_PATH at a directory holding the filter's plugin, e.g. that of Python's \
         hdf5plugin: python3 -c 'import hdf5plugin; print(hdf5plugin.PLUGIN_PATH)')",
        missing.join(", ")
    )
}

/// Names of registered HDF5 filters met in event files.
fn filter_name(id: i32) -> &'static str {
    match id {
        307 => " (bzip2)",
        32004 => " (LZ4)",
        32008 => " (bitshuffle)",
        32015 => " (Zstandard)",
        32026 => " (Blosc2)",
        0x8ecf => " (Prophesee ECF)",
        _ => "",
    }
}
