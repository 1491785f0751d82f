//! The limits the HDF5 pieces share, in a leaf that imports nothing of theirs: every piece
//! may take them from here without depending on the reader that uses the pieces.

/// The largest HDF5 chunk read, decoded; writers use kilobytes to a few megabytes. A corrupt
/// chunk size would otherwise cost that much memory, as HDF5 and the decoders here allocate a
/// whole chunk to read any of it.
pub(super) const MAX_CHUNK_BYTES: u64 = 64 << 20;

/// Rows read per HDF5 request (per field): large enough to amortise the library's per-call
/// cost, small enough to keep memory constant for multi-gigabyte files.
pub(super) const READ_ROWS: usize = 1 << 16;
