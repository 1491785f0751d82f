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
