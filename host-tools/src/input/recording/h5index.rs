//! Where a chunked dataset's chunks are stored, listed once.
//!
//! HDF5's `H5Dget_chunk_info_by_coord` walks the whole chunk index to find one chunk, so
//! asking it for every chunk in turn costs the square of their number: 1.7 M events in
//! 128-row chunks took 18.9 s against 0.6 s in 4096-row chunks (issue 46), and h5py's
//! default appending (1024-row chunks) of 50 M events minutes. `H5Dchunk_iter` lists them all
//! in one walk; the reader then looks each chunk up here.

use hdf5_sys::h5::{haddr_t, hsize_t, HADDR_UNDEF};
use hdf5_sys::h5d::H5Dchunk_iter;
use hdf5_sys::h5p::H5P_DEFAULT;
use std::collections::HashMap;
use std::ffi::{c_int, c_uint, c_void};

/// The stored chunks of a dataset of one or two dimensions: their sizes in the file, by the
/// offset of their first element (row, column; column 0 for one dimension). The filters a
/// chunk's writer skipped come with its bytes (`H5Dread_chunk`).
#[derive(Debug, Default)]
pub(crate) struct ChunkIndex {
    chunks: HashMap<(u64, u64), u64>,
}

/// What the listing's callback fills.
struct Listing {
    ndim: usize,
    most: usize,
    chunks: HashMap<(u64, u64), u64>,
    too_many: bool,
}

/// HDF5's "go on" and "stop" for an iteration callback.
const ITER_CONT: c_int = 0;
const ITER_STOP: c_int = 1;

/// Called by `H5Dchunk_iter` once per stored chunk.
///
/// # Safety
/// `offset` holds at least the dataset's rank of values and `data` is the `Listing` given to
/// `H5Dchunk_iter`, as HDF5 calls it.
unsafe extern "C" fn list_one(
    offset: *const hsize_t,
    _filter_mask: c_uint,
    addr: haddr_t,
    size: hsize_t,
    data: *mut c_void,
) -> c_int {
    // SAFETY: as the function's contract says.
    let listing = unsafe { &mut *data.cast::<Listing>() };
    if listing.chunks.len() >= listing.most {
        listing.too_many = true;
        return ITER_STOP;
    }
    if offset.is_null() || addr == HADDR_UNDEF {
        return ITER_CONT;
    }
    // SAFETY: as above.
    let o = unsafe { std::slice::from_raw_parts(offset, listing.ndim) };
    let key = (o[0], if listing.ndim > 1 { o[1] } else { 0 });
    // A corrupt index may list an offset twice: the first is the one a lookup finds too, and
    // the stored size is checked against what `H5Dread_chunk` gives anyway.
    listing.chunks.entry(key).or_insert(size);
    ITER_CONT
}

impl ChunkIndex {
    /// Lists the chunks of `ds` (one or two dimensions) in one walk of its index. `most` is
    /// how many chunks its shape holds: an index that lists more is corrupt, and listing
    /// stops there, so memory stays within the shape's count.
    pub(crate) fn list(ds: &hdf5::Dataset, most: usize) -> Result<Self, String> {
        let ndim = ds.ndim();
        if !(1..=2).contains(&ndim) {
            return Err(format!("{ndim} dimensions; evcal reads one or two"));
        }
        let mut listing = Listing { ndim, most, chunks: HashMap::new(), too_many: false };
        // SAFETY: the callback reads `ndim` offsets (HDF5 passes the rank and one more) and
        // `listing`, which outlives the call; it does not call HDF5.
        let status = hdf5::sync::sync(|| unsafe {
            H5Dchunk_iter(ds.id(), H5P_DEFAULT, Some(list_one), std::ptr::from_mut(&mut listing).cast())
        });
        if listing.too_many {
            return Err(format!("its chunk index lists more chunks than its shape holds ({most}): corrupt"));
        }
        if status < 0 {
            return Err("its chunk index cannot be read: the file is truncated or corrupt".to_string());
        }
        Ok(Self { chunks: listing.chunks })
    }

    /// The stored size of the chunk whose first element is at (`row`, `col`), if it is stored.
    pub(crate) fn size(&self, row: u64, col: u64) -> Option<u64> {
        self.chunks.get(&(row, col)).copied()
    }
}

#[cfg(test)]
mod test {
    use super::super::h5chunks::Column;

    /// 40 000 chunks of 4 rows, plain and gzip: every row read, in the order written, and the
    /// listing made once (the lookup per chunk walked them all: 40 000² / 2 steps, some 40 s).
    #[test]
    fn many_small_chunks_read_fully_and_a_chunk_never_written_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("small_chunks.h5");
        let n = 160_000usize;
        let ts: Vec<i64> = (0..n).map(|i| 1_000_000 + 3 * i as i64).collect();
        let rows = ndarray::Array2::from_shape_fn((n / 4, 2), |(i, j)| (2 * i + j) as u16);
        {
            let f = hdf5::File::create(&path).unwrap();
            f.new_dataset_builder().chunk(4).with_data(&ts).create("plain").unwrap();
            f.new_dataset_builder().chunk(4).deflate(1).with_data(&ts).create("gzip").unwrap();
            f.new_dataset_builder().chunk((2, 1)).with_data(&rows).create("rows").unwrap();
            // Rows 0..50 of 100 written: chunks from row 50 on are not stored.
            let part = f.new_dataset::<i64>().chunk(10).shape(100).create("part").unwrap();
            part.write_slice(&ts[..50], 0..50).unwrap();
        }
        let f = hdf5::File::open(&path).unwrap();
        for name in ["plain", "gzip"] {
            let mut c = Column::open(f.dataset(name).unwrap()).unwrap();
            let started = std::time::Instant::now();
            assert_eq!(c.read::<i64>(0..n).unwrap(), ts, "{name}");
            // Correctness is the test; this bound, far above the listing's milliseconds, only
            // catches a return to a walk per chunk.
            assert!(started.elapsed().as_secs_f64() < 5.0, "{name}: {:?}", started.elapsed());
        }
        let mut c = Column::open(f.dataset("rows").unwrap()).unwrap();
        assert_eq!(
            c.read::<i64>(3..n / 4).unwrap(),
            rows.slice(ndarray::s![3.., ..]).iter().map(|&v| i64::from(v)).collect::<Vec<_>>()
        );
        let mut c = Column::open(f.dataset("part").unwrap()).unwrap();
        assert_eq!(c.read::<i64>(0..50).unwrap(), ts[..50]);
        let err = c.read::<i64>(45..60).unwrap_err();
        assert!(err.contains("the chunk from row 50 is not stored"), "{err}");
    }
}
