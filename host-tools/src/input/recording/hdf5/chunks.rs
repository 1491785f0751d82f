//! HDF5 datasets read as evcal reads them: a chunked dataset chunk by chunk, each read raw
//! and decoded here, held to its chunk's size; other layouts through the library.
//!
//! HDF5 1.10 (the system's `libhdf5` on Debian 12, which evcal used before it built HDF5 2.x
//! from source) takes whatever a chunk's stored bytes or its filters give to be a whole chunk
//! and copies a whole chunk from it. A corrupt file can
//! make either shorter: an unfiltered chunk stored in fewer bytes than it holds, a gzip chunk
//! that inflates short, a Blosc chunk whose header says less. The `read_h5` fuzz target found
//! both ends of this under AddressSanitizer, and valgrind shows them on `evcal info`: reads
//! past the buffer, which give garbage or an error. Here a chunk's stored bytes come from
//! `H5Dread_chunk` (HDF5 only reads them from the file, within it), and the filters evcal
//! builds in (gzip, shuffle, Fletcher-32, LZF, Blosc) are undone here, each stage held to the
//! size it must give. A pipeline with another filter (a plugin the user installed) is left to
//! the library, as before.
//!
//! Compact datasets (data inside the object header) are read by the library after their
//! stored size is checked against their shape; contiguous ones lie in one range of the file,
//! which the library reads within the end the superblock declares (`file` holds that
//! within the file).

use super::blosc;
use super::filters::filter_hint;
use super::index::ChunkIndex;
use super::limits::MAX_CHUNK_BYTES;
use hdf5::H5Type;
use hdf5_sys::h5::hsize_t;
use hdf5_sys::h5d::{H5D_layout_t, H5Dget_storage_size, H5Dread_chunk};
use hdf5_sys::h5p::{H5Pget_filter2, H5Pget_layout, H5Pget_nfilters, H5P_DEFAULT};
use hdf5_sys::h5t::{
    H5T_class_t, H5T_order_t, H5T_sign_t, H5Tclose, H5Tget_class, H5Tget_order, H5Tget_sign, H5Tget_size, H5Tget_super,
};
use std::ffi::c_uint;
use std::ops::Range;

/// HDF5's ids of the filters undone here.
const DEFLATE: i32 = 1;
const SHUFFLE: i32 = 2;
const FLETCHER32: i32 = 3;
const LZF: i32 = 32000;
const BLOSC: i32 = 32001;

/// Decoded chunks kept per dataset: a read of rows spans the column chunks of one row block.
const CACHED_CHUNKS: usize = 4;

/// A number as a dataset stores it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scalar {
    size: usize,
    float: bool,
    signed: bool,
    big_endian: bool,
}

/// A value evcal reads from a dataset, converted as HDF5 would (integers saturate).
pub(crate) trait Value: H5Type + Copy {
    /// From an integer of the file.
    fn from_int(v: i128) -> Self;
    /// From a float of the file.
    fn from_float(v: f64) -> Self;
}

impl Value for i64 {
    fn from_int(v: i128) -> Self {
        v.clamp(i64::MIN as i128, i64::MAX as i128) as i64
    }
    fn from_float(v: f64) -> Self {
        v as i64
    }
}

impl Value for u64 {
    fn from_int(v: i128) -> Self {
        v.clamp(0, u64::MAX as i128) as u64
    }
    fn from_float(v: f64) -> Self {
        v as u64
    }
}

impl Value for f64 {
    fn from_int(v: i128) -> Self {
        v as f64
    }
    fn from_float(v: f64) -> Self {
        v
    }
}

/// One filter of a dataset's pipeline, in the order it was applied when writing.
#[derive(Clone, Debug, PartialEq)]
enum Stage {
    Deflate,
    Shuffle { element: usize },
    Fletcher32,
    Lzf,
    Blosc,
}

impl Stage {
    fn name(&self) -> &'static str {
        match self {
            Stage::Deflate => "gzip",
            Stage::Shuffle { .. } => "shuffle",
            Stage::Fletcher32 => "Fletcher-32",
            Stage::Lzf => "LZF",
            Stage::Blosc => "Blosc",
        }
    }
}

#[derive(Debug)]
struct Chunked {
    /// Rows and columns a chunk spans (columns 1 for a 1-D dataset).
    rows: usize,
    cols: usize,
    pipeline: Vec<Stage>,
    chunk_bytes: usize,
    scalar: Scalar,
    cache: Vec<((usize, usize), Vec<u8>)>,
    /// Where the chunks are stored, listed at the first read.
    index: Option<ChunkIndex>,
}

/// A dataset of one or two dimensions (events by fields), read by rows.
pub(crate) struct Column {
    ds: hdf5::Dataset,
    /// Values a row holds (1, or the second dimension).
    width: usize,
    /// An enumeration (h5py's booleans): the library reads it as `bool`, not as a number.
    is_enum: bool,
    chunked: Option<Chunked>,
}

impl Column {
    /// Prepares `ds` (1-D, or 2-D read by whole rows) for reading; the message says why not.
    pub(crate) fn open(ds: hdf5::Dataset) -> Result<Self, String> {
        let shape = ds.shape();
        let width = match shape.len() {
            1 => 1,
            2 => shape[1],
            n => return Err(format!("{n} dimensions; evcal reads one or two")),
        };
        let dcpl = ds.dcpl().map_err(|e| format!("its creation properties cannot be read ({e})"))?;
        // SAFETY: plain queries of open identifiers, under the library's lock.
        let layout = hdf5::sync::sync(|| unsafe { H5Pget_layout(dcpl.id()) });
        let (scalar, is_enum) = scalar(&ds)?;
        let chunked = match layout {
            H5D_layout_t::H5D_CHUNKED => {
                let pipeline = pipeline(&dcpl)?;
                match pipeline {
                    None => None,
                    Some(pipeline) => {
                        let chunk = ds.chunk().ok_or("chunked without chunk dimensions: corrupt")?;
                        let (rows, cols) = (chunk[0], chunk.get(1).copied().unwrap_or(1));
                        let bytes = (rows as u128) * (cols as u128) * (scalar.size as u128);
                        if rows == 0 || cols == 0 || bytes > MAX_CHUNK_BYTES as u128 {
                            return Err(format!("chunks of {rows} x {cols} values: corrupt"));
                        }
                        Some(Chunked {
                            rows,
                            cols,
                            pipeline,
                            chunk_bytes: bytes as usize,
                            scalar,
                            cache: Vec::new(),
                            index: None,
                        })
                    }
                }
            }
            H5D_layout_t::H5D_COMPACT => {
                // SAFETY: as above.
                let stored = hdf5::sync::sync(|| unsafe { H5Dget_storage_size(ds.id()) }) as u128;
                let wanted = ds.size() as u128 * scalar.size as u128;
                if stored != wanted {
                    return Err(format!("its data are stored in {stored} bytes but its shape needs {wanted}: corrupt"));
                }
                None
            }
            _ => None,
        };
        Ok(Self { ds, width, is_enum, chunked })
    }

    /// Rows `rows`, row by row (`width` values each).
    pub(crate) fn read<T: Value>(&mut self, rows: Range<usize>) -> Result<Vec<T>, String> {
        let width = self.width;
        let Some(c) = self.chunked.as_mut() else {
            let r = if self.is_enum && width == 1 {
                self.ds.read_slice_1d::<bool, _>(rows).map(|a| a.iter().map(|&b| T::from_int(i128::from(b))).collect())
            } else if width == 1 {
                self.ds.read_slice_1d::<T, _>(rows).map(|a| a.to_vec())
            } else {
                self.ds.read_slice_2d::<T, _>((rows, ..)).map(|a| a.iter().copied().collect())
            };
            return r.map_err(|e| format!("{e}{}", filter_hint(&self.ds, &e.to_string())));
        };
        let (per_chunk_rows, per_chunk_cols, sc) = (c.rows, c.cols, c.scalar);
        let mut out = vec![T::from_int(0); rows.len() * width];
        let mut row = rows.start;
        while row < rows.end {
            let block = row / per_chunk_rows;
            let block_end = ((block + 1) * per_chunk_rows).min(rows.end);
            for col_block in 0..width.div_ceil(per_chunk_cols) {
                let chunk = c.chunk(&self.ds, (block, col_block))?;
                let cols = col_block * per_chunk_cols..((col_block + 1) * per_chunk_cols).min(width);
                for r in row..block_end {
                    for col in cols.clone() {
                        let i = ((r - block * per_chunk_rows) * per_chunk_cols + col - cols.start) * sc.size;
                        out[(r - rows.start) * width + col] = value::<T>(&chunk[i..i + sc.size], sc);
                    }
                }
            }
            row = block_end;
        }
        Ok(out)
    }
}

impl Chunked {
    /// The decoded chunk at (row block, column block), from the cache or the file.
    fn chunk(&mut self, ds: &hdf5::Dataset, key: (usize, usize)) -> Result<&[u8], String> {
        if let Some(i) = self.cache.iter().position(|(k, _)| *k == key) {
            return Ok(&self.cache[i].1);
        }
        if self.index.is_none() {
            // The chunks the shape holds: more listed is a corrupt index.
            let shape = ds.shape();
            let blocks = |extent: usize, per: usize| extent.div_ceil(per.max(1));
            let most = blocks(shape.first().copied().unwrap_or(0), self.rows)
                .saturating_mul(blocks(shape.get(1).copied().unwrap_or(1), self.cols));
            self.index = Some(ChunkIndex::list(ds, most)?);
        }
        let bytes = self.load(ds, key)?;
        if self.cache.len() == CACHED_CHUNKS {
            self.cache.remove(0);
        }
        self.cache.push((key, bytes));
        Ok(&self.cache.last().expect("just pushed").1)
    }

    fn load(&self, ds: &hdf5::Dataset, (block, col_block): (usize, usize)) -> Result<Vec<u8>, String> {
        let first_row = block * self.rows;
        let offset: Vec<hsize_t> = if ds.ndim() == 1 {
            vec![first_row as hsize_t]
        } else {
            vec![first_row as hsize_t, (col_block * self.cols) as hsize_t]
        };
        let stored = self.index.as_ref().and_then(|i| i.size(offset[0], offset.get(1).copied().unwrap_or(0)));
        let size = match stored {
            Some(size) if size > 0 => size,
            _ => {
                return Err(format!("the chunk from row {first_row} is not stored: the file is incomplete or corrupt"))
            }
        };
        let limit = self.chunk_bytes as u64 + self.chunk_bytes as u64 / 16 + 4096;
        if size > limit {
            return Err(format!(
                "the chunk from row {first_row} is stored in {size} bytes, more than a chunk of {} bytes takes: corrupt",
                self.chunk_bytes
            ));
        }
        let mut stored = vec![0u8; size as usize];
        let (mut filters, mut len): (u32, usize) = (0, stored.len());
        // SAFETY: HDF5 writes at most `len` bytes (the chunk's stored size, given above) into
        // `stored`, and says in `len` how many it wrote.
        let status = hdf5::sync::sync(|| unsafe {
            H5Dread_chunk(ds.id(), H5P_DEFAULT, offset.as_ptr(), &mut filters, stored.as_mut_ptr().cast(), &mut len)
        });
        if status < 0 || len != stored.len() {
            return Err(format!("the chunk from row {first_row} cannot be read: the file is truncated or corrupt"));
        }
        undo(&self.pipeline, filters, stored, self.chunk_bytes)
            .map_err(|m| format!("the chunk from row {first_row} does not decode ({m}): the file is corrupt"))
    }
}

/// Undoes `pipeline` (skipping the filters `mask` marks as not applied) on a chunk's stored
/// bytes; the result must be `chunk_bytes` long, and so must each stage's as far as the
/// stages written before it tell.
fn undo(pipeline: &[Stage], mask: u32, stored: Vec<u8>, chunk_bytes: usize) -> Result<Vec<u8>, String> {
    let applied = |i: usize| i >= 32 || mask & (1 << i) == 0;
    // The size each stage's output must have: what went into it when the chunk was written.
    let mut sizes = vec![Some(chunk_bytes)];
    for (i, s) in pipeline.iter().enumerate() {
        let before = sizes[i];
        sizes.push(match s {
            _ if !applied(i) => before,
            Stage::Shuffle { .. } => before,
            Stage::Fletcher32 => before.map(|n| n + 4),
            Stage::Deflate | Stage::Lzf | Stage::Blosc => None,
        });
    }
    let mut data = stored;
    if let Some(n) = sizes[pipeline.len()] {
        if data.len() != n {
            return Err(format!("{} bytes stored where the chunk takes {n}", data.len()));
        }
    }
    let bound = MAX_CHUNK_BYTES as usize + 16;
    for (i, stage) in pipeline.iter().enumerate().rev() {
        if !applied(i) {
            continue;
        }
        let want = sizes[i];
        let limit = want.unwrap_or(bound);
        data = match stage {
            Stage::Shuffle { element } => unshuffle(&data, *element),
            Stage::Fletcher32 => strip_fletcher32(&data)?,
            Stage::Deflate => inflate(&data, limit)?,
            Stage::Lzf => lzf_decompress(&data, limit)?,
            Stage::Blosc => blosc::decode(&data, limit)?,
        };
        if let Some(n) = want {
            if data.len() != n {
                return Err(format!("{} gave {} bytes where {n} were written", stage.name(), data.len()));
            }
        }
    }
    Ok(data)
}

/// The dataset's pipeline as evcal can undo it; `None` when it holds a filter evcal does not
/// build in (then the library reads it, through the plugin the user points it to).
fn pipeline(dcpl: &hdf5::plist::DatasetCreate) -> Result<Option<Vec<Stage>>, String> {
    hdf5::sync::sync(|| {
        // SAFETY: queries of an open property list; `cd` holds the `n` values asked for.
        let count = unsafe { H5Pget_nfilters(dcpl.id()) };
        if count < 0 {
            return Err("its filters cannot be read: corrupt".to_string());
        }
        let mut stages = Vec::new();
        for i in 0..count as c_uint {
            let (mut flags, mut n, mut cd): (c_uint, usize, [c_uint; 8]) = (0, 8, [0; 8]);
            let id = unsafe {
                H5Pget_filter2(
                    dcpl.id(),
                    i,
                    &mut flags,
                    &mut n,
                    cd.as_mut_ptr(),
                    0,
                    std::ptr::null_mut(),
                    std::ptr::null_mut(),
                )
            };
            stages.push(match id {
                DEFLATE => Stage::Deflate,
                SHUFFLE => Stage::Shuffle { element: if n >= 1 { cd[0] as usize } else { 1 } },
                FLETCHER32 => Stage::Fletcher32,
                LZF => Stage::Lzf,
                BLOSC => Stage::Blosc,
                _ if id < 0 => return Err("its filters cannot be read: corrupt".to_string()),
                _ => return Ok(None),
            });
        }
        Ok(Some(stages))
    })
}

/// How the dataset's numbers are stored (integers, enums of them such as h5py's booleans,
/// floats); anything else is refused.
fn scalar(ds: &hdf5::Dataset) -> Result<(Scalar, bool), String> {
    let dtype = ds.dtype().map_err(|e| format!("its type cannot be read ({e})"))?;
    hdf5::sync::sync(|| {
        // SAFETY: queries of an open type; the super type opened here is closed here.
        unsafe {
            let mut id = dtype.id();
            let mut opened = None;
            if H5Tget_class(id) == H5T_class_t::H5T_ENUM {
                id = H5Tget_super(id);
                if id < 0 {
                    return Err("an enumeration without a base type: corrupt".to_string());
                }
                opened = Some(id);
            }
            let class = H5Tget_class(id);
            let s = Scalar {
                size: H5Tget_size(id),
                float: class == H5T_class_t::H5T_FLOAT,
                signed: H5Tget_sign(id) == H5T_sign_t::H5T_SGN_2,
                big_endian: H5Tget_order(id) == H5T_order_t::H5T_ORDER_BE,
            };
            if let Some(o) = opened {
                H5Tclose(o);
            }
            let ok = match class {
                H5T_class_t::H5T_INTEGER => matches!(s.size, 1 | 2 | 4 | 8),
                H5T_class_t::H5T_FLOAT => matches!(s.size, 4 | 8),
                _ => false,
            };
            if ok {
                Ok((s, opened.is_some()))
            } else {
                Err(format!("values of a type evcal does not read ({class:?}, {} bytes)", s.size))
            }
        }
    })
}

/// One stored number, as `T`.
fn value<T: Value>(b: &[u8], s: Scalar) -> T {
    let mut le = [0u8; 8];
    le[..s.size].copy_from_slice(b);
    if s.big_endian {
        le[..s.size].reverse();
    }
    let bits = u64::from_le_bytes(le);
    if s.float {
        return T::from_float(if s.size == 4 { f64::from(f32::from_bits(bits as u32)) } else { f64::from_bits(bits) });
    }
    let v = if s.signed {
        let shift = 64 - 8 * s.size as u32;
        i128::from(((bits << shift) as i64) >> shift)
    } else {
        i128::from(bits)
    };
    T::from_int(v)
}

/// HDF5's shuffle undone: the stored bytes hold every element's first byte, then every
/// second byte, ...; a remainder shorter than an element stays at the end.
fn unshuffle(data: &[u8], element: usize) -> Vec<u8> {
    if element <= 1 || data.len() < element {
        return data.to_vec();
    }
    let n = data.len() / element;
    let mut out = vec![0u8; data.len()];
    for b in 0..element {
        for j in 0..n {
            out[j * element + b] = data[b * n + j];
        }
    }
    out[n * element..].copy_from_slice(&data[n * element..]);
    out
}

/// Checks and removes the 4-byte Fletcher-32 checksum HDF5 appends.
fn strip_fletcher32(data: &[u8]) -> Result<Vec<u8>, String> {
    let Some(n) = data.len().checked_sub(4) else {
        return Err("shorter than its checksum".into());
    };
    let stored = u32::from_le_bytes([data[n], data[n + 1], data[n + 2], data[n + 3]]);
    let sum = fletcher32(&data[..n]);
    // Files of HDF5 before 1.6.3 hold the checksum's bytes in the other order.
    let swapped = sum.swap_bytes();
    if stored != sum && stored != swapped {
        return Err(format!("Fletcher-32 checksum {stored:#010x}, the data give {sum:#010x}"));
    }
    Ok(data[..n].to_vec())
}

/// HDF5's Fletcher-32 of `data`, in big-endian 16-bit words (an odd last byte as the high byte).
fn fletcher32(data: &[u8]) -> u32 {
    let (mut a, mut b) = (0u32, 0u32);
    for block in data.chunks(720) {
        for w in block.chunks(2) {
            a += u32::from(w[0]) << 8 | u32::from(*w.get(1).unwrap_or(&0));
            b += a;
        }
        a = (a & 0xffff) + (a >> 16);
        b = (b & 0xffff) + (b >> 16);
    }
    a = (a & 0xffff) + (a >> 16);
    b = (b & 0xffff) + (b >> 16);
    (b << 16) | a
}

/// A zlib stream inflated to at most `limit` bytes (more is an error, as is a cut stream).
fn inflate(data: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    // One inflater per thread, reset per chunk: a new one allocates and clears tens of
    // kilobytes, which for chunks of a few hundred bytes (h5py's appends) cost more than
    // inflating them.
    thread_local! {
        static INFLATER: std::cell::RefCell<flate2::Decompress> = std::cell::RefCell::new(flate2::Decompress::new(true));
    }
    let mut out = Vec::with_capacity(limit + 1);
    let status = INFLATER.with_borrow_mut(|d| {
        d.reset(true);
        d.decompress_vec(data, &mut out, flate2::FlushDecompress::Finish)
    });
    match status {
        Ok(flate2::Status::StreamEnd) if out.len() <= limit => Ok(out),
        Ok(_) if out.len() > limit => Err(format!("gzip data inflate to more than {limit} bytes")),
        Ok(_) => Err("gzip data cut short".into()),
        Err(e) => Err(format!("gzip data corrupt: {e}")),
    }
}

/// An LZF block (as h5py's LZF filter stores it, no header) to at most `limit` bytes.
fn lzf_decompress(data: &[u8], limit: usize) -> Result<Vec<u8>, String> {
    let corrupt = || "LZF data corrupt".to_string();
    let mut out: Vec<u8> = Vec::with_capacity(limit.min(1 << 20));
    let mut i = 0;
    while i < data.len() {
        let ctrl = usize::from(data[i]);
        i += 1;
        if ctrl < 32 {
            let run = ctrl + 1;
            let lit = data.get(i..i + run).ok_or_else(corrupt)?;
            if out.len() + run > limit {
                return Err(format!("LZF data decode to more than {limit} bytes"));
            }
            out.extend_from_slice(lit);
            i += run;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += usize::from(*data.get(i).ok_or_else(corrupt)?);
                i += 1;
            }
            let back = ((ctrl & 0x1f) << 8) + usize::from(*data.get(i).ok_or_else(corrupt)?) + 1;
            i += 1;
            let from = out.len().checked_sub(back).ok_or_else(corrupt)?;
            if out.len() + len + 2 > limit {
                return Err(format!("LZF data decode to more than {limit} bytes"));
            }
            for k in 0..len + 2 {
                out.push(out[from + k]);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn shuffle_is_undone_with_its_remainder() {
        let elements: Vec<u8> = (0..11).collect(); // three 3-byte elements and 2 left over
        let mut shuffled = Vec::new();
        for b in 0..3 {
            for j in 0..3 {
                shuffled.push(elements[j * 3 + b]);
            }
        }
        shuffled.extend_from_slice(&elements[9..]);
        assert_eq!(unshuffle(&shuffled, 3), elements);
    }

    #[test]
    fn lzf_literals_and_back_references_decode_within_their_limit() {
        // "abcabcabc": 3 literals, then a back reference of 6 bytes, 3 back.
        let data = [2, b'a', b'b', b'c', (4 << 5), 2];
        assert_eq!(lzf_decompress(&data, 9).unwrap(), b"abcabcabc");
        assert!(lzf_decompress(&data, 8).is_err(), "beyond the limit");
        assert!(lzf_decompress(&[(4 << 5), 9], 100).is_err(), "a reference before the start");
        assert!(lzf_decompress(&[5, b'a'], 100).is_err(), "a literal run cut short");
    }

    #[test]
    fn values_convert_as_hdf5_would() {
        let s = |size, float, signed, big_endian| Scalar { size, float, signed, big_endian };
        assert_eq!(value::<i64>(&[0xff, 0xff], s(2, false, true, false)), -1);
        assert_eq!(value::<i64>(&[0xff, 0xff], s(2, false, false, false)), 65535);
        assert_eq!(value::<i64>(&[0x01, 0x02], s(2, false, false, true)), 0x0102);
        assert_eq!(value::<i64>(&u64::MAX.to_le_bytes(), s(8, false, false, false)), i64::MAX, "saturated");
        assert_eq!(value::<u64>(&u64::MAX.to_le_bytes(), s(8, false, false, false)), u64::MAX);
        assert_eq!(value::<f64>(&1.5f32.to_le_bytes(), s(4, true, true, false)), 1.5);
        assert_eq!(value::<f64>(&2.25f64.to_be_bytes(), s(8, true, true, true)), 2.25);
    }

    #[test]
    fn a_pipeline_stage_that_gives_another_size_than_was_written_is_refused() {
        let raw: Vec<u8> = (0..64u8).collect();
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        std::io::Write::write_all(&mut z, &raw).unwrap();
        let packed = z.finish().unwrap();
        assert_eq!(undo(&[Stage::Deflate], 0, packed.clone(), 64).unwrap(), raw);
        assert!(undo(&[Stage::Deflate], 0, packed.clone(), 65).is_err(), "inflates short of the chunk");
        assert!(undo(&[Stage::Deflate], 0, packed, 63).is_err(), "inflates past the chunk");
        assert!(undo(&[], 0, raw.clone(), 65).is_err(), "an unfiltered chunk stored short");
        assert_eq!(undo(&[Stage::Deflate], 1, raw.clone(), 64).unwrap(), raw, "a filter the mask skips");
    }

    /// Every filter evcal undoes, alone and together, on the types event files use: the values
    /// read here are those HDF5 itself reads from the same datasets.
    #[test]
    fn chunks_decoded_here_read_as_hdf5_reads_them() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("filters.h5");
        let n = 3000usize;
        let xs: Vec<u16> = (0..n).map(|i| (i * 7 % 346) as u16).collect();
        let ts: Vec<i64> = (0..n).map(|i| 1_600_000_000_000_000 + (i * i) as i64).collect();
        let us: Vec<u64> = (0..n).map(|i| u64::MAX - i as u64).collect();
        let ps: Vec<bool> = (0..n).map(|i| i % 3 == 0).collect();
        let fs: Vec<f32> = (0..n).map(|i| i as f32 * 0.25).collect();
        let rows = ndarray::Array2::from_shape_fn((n, 4), |(i, j)| (i * 4 + j) as f64 * 0.5);
        {
            let f = hdf5::File::create(&path).unwrap();
            f.new_dataset_builder().chunk(700).with_data(&xs).create("plain").unwrap();
            f.new_dataset_builder().chunk(700).deflate(4).with_data(&xs).create("gzip").unwrap();
            f.new_dataset_builder().chunk(700).shuffle().deflate(6).with_data(&ts).create("shuffle_gzip").unwrap();
            f.new_dataset_builder().chunk(512).fletcher32().with_data(&us).create("fletcher").unwrap();
            f.new_dataset_builder().chunk(512).shuffle().deflate(1).fletcher32().with_data(&fs).create("all").unwrap();
            f.new_dataset_builder().chunk(1024).lzf().with_data(&ts).create("lzf").unwrap();
            f.new_dataset_builder().chunk(600).deflate(3).with_data(&ps).create("bools").unwrap();
            f.new_dataset_builder().with_data(&ps).create("bools_contiguous").unwrap();
            f.new_dataset_builder().chunk((500, 2)).deflate(2).with_data(&rows).create("rows").unwrap();
        }
        let f = hdf5::File::open(&path).unwrap();
        let check_i64 = |name: &str| {
            let d = f.dataset(name).unwrap();
            let want: Vec<i64> = if d.dtype().unwrap().to_descriptor().unwrap() == hdf5::types::TypeDescriptor::Boolean
            {
                d.read_raw::<bool>().unwrap().into_iter().map(i64::from).collect()
            } else {
                d.read_raw::<i64>().unwrap()
            };
            let mut c = Column::open(d).unwrap();
            assert!(c.chunked.is_some() || name.ends_with("contiguous"), "{name}: read raw");
            // In pieces that start and end inside chunks.
            let mut got = c.read::<i64>(0..1234).unwrap();
            got.extend(c.read::<i64>(1234..n).unwrap());
            assert_eq!(got, want, "{name}");
        };
        for name in ["plain", "gzip", "shuffle_gzip", "lzf", "bools", "bools_contiguous"] {
            check_i64(name);
        }
        let mut c = Column::open(f.dataset("fletcher").unwrap()).unwrap();
        assert_eq!(c.read::<u64>(0..n).unwrap(), us);
        let mut c = Column::open(f.dataset("all").unwrap()).unwrap();
        assert_eq!(c.read::<f64>(0..n).unwrap(), fs.iter().map(|&v| f64::from(v)).collect::<Vec<_>>());
        let mut c = Column::open(f.dataset("rows").unwrap()).unwrap();
        assert_eq!(
            c.read::<f64>(10..2990).unwrap(),
            rows.slice(ndarray::s![10..2990, ..]).iter().copied().collect::<Vec<_>>()
        );
    }
}
