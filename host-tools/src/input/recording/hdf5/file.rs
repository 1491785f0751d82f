//! Where every HDF5 recording is opened: evcal's Blosc filter in place, and what the
//! superblock declares checked against the file before the library reads any metadata.
//!
//! HDF5 sizes its metadata reads from fields of the file and allocates each buffer before
//! reading into it. A read past the end the superblock declares fails, but one within it is
//! zero-filled beyond the bytes the file really has, and the driver information block is read
//! whole at the size it states (up to 4 GB). Two files the `read_h5` fuzz target found made
//! HDF5 allocate and fill 2.3 GB while opening them: 69 bytes whose superblock put the data
//! and the end far beyond the file, and (made after them) 176 bytes with a true end but
//! driver information of 2 GB. With the base address, the declared end and the driver block
//! all within the file, every metadata read is bounded by the file's own size.
//!
//! One structure HDF5 reads without such a bound: a group's local heap (the names of its
//! links, in files with the original group format, as h5py writes them) keeps a list of its
//! free blocks, each naming the next, and HDF5 (2.2) follows it until it ends, allocating a
//! node per block, without noticing that it loops. A 40 kB file the fuzz target found, whose
//! free list names itself, made `evcal info` take all 24 GB of the machine in two minutes.
//! [`check_local_heaps`] walks every local heap's free list first.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// The HDF5 signature that starts a superblock.
const SIGNATURE: &[u8; 8] = b"\x89HDF\r\n\x1a\n";

/// Where a superblock may start: byte 0, then 512, 1024, 2048, ... (after a user block).
const FIRST_USER_BLOCK: u64 = 512;

/// Opens `path` as HDF5 after [`check_declared_end`]; the message says why not.
pub(crate) fn open(path: &Path) -> Result<hdf5::File, String> {
    super::blosc::install()?;
    check_declared_end(path)?;
    hdf5::File::open(path).map_err(|e| format!("not a readable HDF5 file: {e}"))
}

/// Refuses a file whose superblock puts its data, its end or its driver information beyond
/// the bytes it has (truncated, or a corrupt superblock); a superblock this cannot parse is
/// left to the library to judge.
fn check_declared_end(path: &Path) -> Result<(), String> {
    let mut f = std::fs::File::open(path).map_err(|e| format!("cannot open it: {e}"))?;
    let len = f.metadata().map_err(|e| format!("cannot read its size: {e}"))?.len();
    let mut read_at = |at: u64, buf: &mut [u8]| -> Result<usize, String> {
        f.seek(SeekFrom::Start(at)).and_then(|_| read_up_to(&mut f, buf)).map_err(|e| format!("cannot read it: {e}"))
    };
    let mut at = 0u64;
    while at < len {
        let mut head = [0u8; 96];
        let n = read_at(at, &mut head)?;
        if !head[..n].starts_with(SIGNATURE) {
            at = if at == 0 { FIRST_USER_BLOCK } else { at * 2 };
            continue;
        }
        let Some(sb) = Superblock::parse(&head[..n]) else { return Ok(()) };
        let corrupt = |what: String| {
            Err(format!("truncated or corrupt: its superblock (at byte {at}) {what}, but the file has {len} bytes"))
        };
        if sb.base > len {
            return corrupt(format!("puts its data from byte {}", sb.base));
        }
        if sb.end > len {
            return corrupt(format!("puts the end of the file at byte {}", sb.end));
        }
        let sizes = (sb.size_of_offsets, sb.size_of_lengths);
        if let Some(driver) = sb.driver {
            // The driver information block: version, 3 reserved bytes, its size (32 bits),
            // the driver's 8-byte name, then that many bytes, which HDF5 reads as the size says.
            let start = sb.base.saturating_add(driver);
            let mut header = [0u8; 8];
            let size = match read_at(start, &mut header)? {
                8 => u64::from(u32::from_le_bytes([header[4], header[5], header[6], header[7]])),
                _ => return corrupt(format!("puts driver information at byte {start}")),
            };
            let block_end = start.saturating_add(16 + size);
            if block_end > len {
                return corrupt(format!("declares {size} bytes of driver information from byte {start}"));
            }
        }
        return check_local_heaps(&mut f, len, sb.base, sizes);
    }
    Ok(())
}

/// The signature of a local heap's header: "HEAP", version 0, three reserved zero bytes.
const LOCAL_HEAP: &[u8; 8] = b"HEAP\0\0\0\0";
/// HDF5's "no next free block" in a local heap's free list.
const FREE_NULL: u64 = 1;
/// Bytes of the file searched at a time for local heaps.
const SCAN_CHUNK: usize = 1 << 20;

/// Refuses a file holding a local heap whose free list loops (see the module's note).
///
/// Local heaps are found by their signature anywhere after `base` (a signature HDF5 never
/// reads, in data, is checked too: it would take the bytes of a heap header, a data block
/// within the file and a free list that loops to refuse a file by mistake). Each list is
/// followed as HDF5 follows it, stopping where HDF5 would stop with an error of its own; a
/// loop is found by Brent's method, in steps bounded by the blocks the list really has.
fn check_local_heaps(f: &mut std::fs::File, len: u64, base: u64, (o, l): (usize, usize)) -> Result<(), String> {
    let header = LOCAL_HEAP.len() + 2 * l + o;
    let mut read_at = |at: u64, buf: &mut [u8]| -> Result<usize, String> {
        f.seek(SeekFrom::Start(at)).and_then(|_| read_up_to(f, buf)).map_err(|e| format!("cannot read it: {e}"))
    };
    let mut found = Vec::new();
    let mut chunk = vec![0u8; SCAN_CHUNK + LOCAL_HEAP.len()];
    let mut at = base;
    while at < len {
        let n = read_at(at, &mut chunk)?;
        if n == 0 {
            break;
        }
        found.extend(memchr::memmem::find_iter(&chunk[..n], LOCAL_HEAP).map(|i| at + i as u64));
        // The chunks overlap by a signature's length less one, so none is cut in two.
        at += (n.saturating_sub(LOCAL_HEAP.len() - 1)).max(1) as u64;
    }
    found.dedup();
    let mut head = vec![0u8; header];
    let mut field = [0u8; 8];
    for heap in found {
        if read_at(heap, &mut head)? < header {
            continue;
        }
        let le = |b: &[u8]| b.iter().rev().fold(0u64, |v, &x| (v << 8) | u64::from(x));
        let size = le(&head[8..8 + l]);
        let first = le(&head[8 + l..8 + 2 * l]);
        let Some(block) = base.checked_add(le(&head[8 + 2 * l..header])) else { continue };
        if block.saturating_add(size) > len {
            continue; // HDF5 fails to read the data block.
        }
        // HDF5's step: the block at `fb` must hold its two fields; it names the next block
        // (0 is an error) and its own size (beyond the data block, an error).
        let mut next = |fb: u64| -> Result<Option<u64>, String> {
            if fb == FREE_NULL || fb.checked_add(2 * l as u64).is_none_or(|e| e > size) {
                return Ok(None);
            }
            if read_at(block + fb, &mut field[..l])? < l {
                return Ok(None);
            }
            let to = le(&field[..l]);
            if read_at(block + fb + l as u64, &mut field[..l])? < l {
                return Ok(None);
            }
            let own = le(&field[..l]);
            Ok((to != 0 && fb.checked_add(own).is_some_and(|e| e <= size)).then_some(to))
        };
        // Brent: a tortoise that jumps to the hare at every power of two.
        let (mut tortoise, mut hare, mut power, mut steps) = (first, first, 1u64, 0u64);
        while let Some(n) = next(hare)? {
            hare = n;
            steps += 1;
            if hare == tortoise {
                return Err(format!(
                    "corrupt: the local heap at byte {heap} lists free blocks that lead back to themselves, a list HDF5 would follow forever"
                ));
            }
            if steps == power {
                (tortoise, power, steps) = (hare, power * 2, 0);
            }
        }
    }
    Ok(())
}

fn read_up_to(f: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match f.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

/// The addresses of a superblock that HDF5 sizes its first reads by.
#[derive(Debug, PartialEq)]
struct Superblock {
    /// Where the file's addresses count from (after a user block).
    base: u64,
    /// The end of the file it declares, relative to `base`.
    end: u64,
    /// Where its driver information block is, relative to `base` (versions 0 and 1).
    driver: Option<u64>,
    /// Bytes of an address in the file.
    size_of_offsets: usize,
    /// Bytes of a length in the file.
    size_of_lengths: usize,
}

impl Superblock {
    /// Reads `sb` (from its signature on), if its version and sizes are ones HDF5 writes.
    fn parse(sb: &[u8]) -> Option<Self> {
        let version = *sb.get(8)?;
        // Versions 0 and 1 list four addresses after their fixed fields (24 and 28 bytes):
        // base, free space, end of file, driver information; 2 and 3 list base, extension,
        // end of file and root group after 12.
        let (size_of_offsets, size_of_lengths, first) = match version {
            0 => (*sb.get(13)?, *sb.get(14)?, 24),
            1 => (*sb.get(13)?, *sb.get(14)?, 28),
            2 | 3 => (*sb.get(9)?, *sb.get(10)?, 12),
            _ => return None,
        };
        let (o, l) = (usize::from(size_of_offsets), usize::from(size_of_lengths));
        // HDF5 writes 2, 4, 8 (16 and 32 allowed by the format); evcal's checks read up to 8.
        if ![2, 4, 8, 16, 32].contains(&o) || ![2, 4, 8].contains(&l) {
            return None;
        }
        let address = |i: usize| -> Option<Option<u64>> {
            let field = sb.get(first + i * o..first + (i + 1) * o)?;
            // Little-endian; "undefined" is all ones.
            Some(if field.iter().all(|&b| b == 0xff) {
                None
            } else if field[8.min(o)..].iter().any(|&b| b != 0) {
                Some(u64::MAX)
            } else {
                Some(field[..8.min(o)].iter().rev().fold(0u64, |v, &b| (v << 8) | u64::from(b)))
            })
        };
        Some(Superblock {
            base: address(0)?.unwrap_or(u64::MAX),
            end: address(2)?.unwrap_or(u64::MAX),
            driver: if version < 2 { address(3)? } else { None },
            size_of_offsets: o,
            size_of_lengths: l,
        })
    }
}

#[cfg(test)]
mod test {
    use super::*;

    fn superblock_v0(end: u64, driver: Option<u64>) -> Vec<u8> {
        let mut sb = SIGNATURE.to_vec();
        sb.extend_from_slice(&[0, 0, 0, 0, 0, 8, 8, 0, 4, 0, 16, 0, 0, 0, 0, 0]);
        for a in [0u64, u64::MAX, end, driver.unwrap_or(u64::MAX)] {
            sb.extend_from_slice(&a.to_le_bytes());
        }
        sb
    }

    #[test]
    fn the_addresses_are_read_from_each_superblock_version() {
        let sb = Superblock::parse(&superblock_v0(1234, None)).unwrap();
        assert_eq!(sb, Superblock { base: 0, end: 1234, driver: None, size_of_offsets: 8, size_of_lengths: 8 });
        let mut v2 = SIGNATURE.to_vec();
        v2.extend_from_slice(&[2, 4, 4, 0]);
        for a in [0u32, u32::MAX, 777, 48] {
            v2.extend_from_slice(&a.to_le_bytes());
        }
        assert_eq!(
            Superblock::parse(&v2),
            Some(Superblock { base: 0, end: 777, driver: None, size_of_offsets: 4, size_of_lengths: 4 })
        );
        let mut bad = superblock_v0(1, None);
        bad[13] = 3;
        assert_eq!(Superblock::parse(&bad), None, "an offset size HDF5 never writes: left to HDF5");
        assert_eq!(Superblock::parse(&superblock_v0(1, None)[..30]), None, "cut short: left to HDF5");
    }

    #[test]
    fn a_superblock_declaring_more_than_the_file_holds_is_refused_before_hdf5_reads() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("short.h5");
        std::fs::write(&p, superblock_v0(1 << 40, None)).unwrap();
        let e = check_declared_end(&p).unwrap_err();
        assert!(e.contains("at byte 1099511627776") && e.contains("has 56 bytes"), "{e}");
        std::fs::write(&p, superblock_v0(56, None)).unwrap();
        assert_eq!(check_declared_end(&p), Ok(()));
        // After a user block of 512 bytes.
        let mut with_block = vec![0u8; 512];
        with_block.extend(superblock_v0(1 << 30, None));
        std::fs::write(&p, with_block).unwrap();
        assert!(check_declared_end(&p).unwrap_err().contains("superblock (at byte 512)"));
    }

    /// A file of a v0 superblock and one local heap whose free list starts at `first`, its
    /// 64-byte data block holding `blocks` (offset, next, size).
    fn file_with_heap(first: u64, blocks: &[(usize, u64, u64)]) -> Vec<u8> {
        let mut b = superblock_v0(0, None);
        let heap = b.len() as u64;
        b.extend_from_slice(LOCAL_HEAP);
        for v in [64, first, heap + 32] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let block = b.len();
        b.resize(block + 64, 0);
        for &(at, next, size) in blocks {
            b[block + at..block + at + 8].copy_from_slice(&next.to_le_bytes());
            b[block + at + 8..block + at + 16].copy_from_slice(&size.to_le_bytes());
        }
        let end = b.len() as u64;
        b[40..48].copy_from_slice(&end.to_le_bytes());
        b
    }

    #[test]
    fn a_local_heap_whose_free_list_loops_is_refused() {
        // HDF5 2.2 follows such a list forever, a node per step: 24 GB in two minutes.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("heap.h5");
        for (first, blocks, ok) in [
            (FREE_NULL, vec![], true),
            (8, vec![(8, FREE_NULL, 16)], true),
            (8, vec![(8, 40, 16), (40, FREE_NULL, 16)], true),
            (8, vec![(8, 8, 16)], false),
            (8, vec![(8, 24, 16), (24, 40, 16), (40, 24, 16)], false),
            // Lists HDF5 stops at by itself: a block past the data, a next of 0, a block
            // longer than the data.
            (8, vec![(8, 60, 16)], true),
            (8, vec![(8, 0, 16)], true),
            (8, vec![(8, 8, 100)], true),
        ] {
            std::fs::write(&p, file_with_heap(first, &blocks)).unwrap();
            let r = check_declared_end(&p);
            assert_eq!(r.is_ok(), ok, "{first} {blocks:?}: {r:?}");
            if let Err(e) = r {
                assert!(e.contains("local heap at byte 56") && e.contains("forever"), "{e}");
            }
        }
    }

    #[test]
    fn driver_information_larger_than_the_file_is_refused() {
        // HDF5 allocated and zero-filled the 2 GB such a 136-byte file declared.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("driver.h5");
        for (size, ok) in [(0x8000_0000u32, false), (64, true), (65, false)] {
            let mut b = superblock_v0(136, Some(56));
            b.extend_from_slice(&[0, 0, 0, 0]);
            b.extend_from_slice(&size.to_le_bytes());
            b.extend_from_slice(b"NCSAfami");
            b.resize(136, 0);
            std::fs::write(&p, b).unwrap();
            let r = check_declared_end(&p);
            assert_eq!(r.is_ok(), ok, "{size}: {r:?}");
        }
    }
}
