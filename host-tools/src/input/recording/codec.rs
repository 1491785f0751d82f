//! Decompression of the blocks binary recordings store: LZ4 frames (AEDAT4 packets, ROS bag
//! chunks), Zstandard (AEDAT4), bzip2 (ROS bag chunks). [`decompress`] decodes one whole block
//! into a caller's buffer, which grows with what the decoder actually gives (never with a size
//! the file declares) and never past a limit, and reports a block cut short as an error;
//! [`reader`] decodes a block as it is read, for blocks too large to hold.

use std::io::Read;

/// How a block is compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Codec {
    /// Stored as it is.
    None,
    /// One or more LZ4 frames.
    Lz4,
    /// Zstandard frames.
    Zstd,
    /// bzip2 streams.
    Bz2,
}

/// Decompresses `raw` into `out` (cleared first), at most `limit` bytes.
pub(crate) fn decompress(codec: Codec, raw: &[u8], limit: u64, out: &mut Vec<u8>) -> Result<(), String> {
    out.clear();
    let r = match codec {
        Codec::None => {
            if raw.len() as u64 > limit {
                return Err(format!("more than {limit} bytes"));
            }
            out.extend_from_slice(raw);
            return Ok(());
        }
        Codec::Lz4 => {
            if !lz4_frame_complete(raw) {
                return Err("LZ4 frame cut short (no end mark)".into());
            }
            lz4_flex::frame::FrameDecoder::new(raw).take(limit + 1).read_to_end(out)
        }
        Codec::Zstd => match zstd::stream::read::Decoder::with_buffer(raw) {
            Ok(d) => d.take(limit + 1).read_to_end(out),
            Err(e) => return Err(format!("cannot start Zstandard: {e}")),
        },
        Codec::Bz2 => bzip2::read::MultiBzDecoder::new(raw).take(limit + 1).read_to_end(out),
    };
    match r {
        Ok(n) if n as u64 > limit => Err(format!("decompresses to more than {limit} bytes")),
        Ok(_) => Ok(()),
        Err(e) => Err(format!("cannot decompress ({codec:?}): {e}")),
    }
}

/// A reader of the decompressed bytes of `raw`, decoding as it is read: memory is the
/// decoder's buffers, whatever the block's size.
pub(crate) fn reader(codec: Codec, raw: impl Read + 'static) -> Result<Box<dyn Read>, String> {
    Ok(match codec {
        Codec::None => Box::new(raw),
        Codec::Lz4 => Box::new(lz4_flex::frame::FrameDecoder::new(raw)),
        Codec::Zstd => {
            Box::new(zstd::stream::read::Decoder::new(raw).map_err(|e| format!("cannot start Zstandard: {e}"))?)
        }
        Codec::Bz2 => Box::new(bzip2::read::MultiBzDecoder::new(raw)),
    })
}

/// Decompresses the first `n` bytes of `raw` (fewer if it holds fewer) into `out`.
pub(crate) fn decompress_prefix(codec: Codec, raw: &[u8], n: u64, out: &mut Vec<u8>) -> Result<(), String> {
    out.clear();
    let r = match codec {
        Codec::None => {
            out.extend_from_slice(&raw[..raw.len().min(n as usize)]);
            return Ok(());
        }
        Codec::Lz4 => lz4_flex::frame::FrameDecoder::new(raw).take(n).read_to_end(out),
        Codec::Zstd => match zstd::stream::read::Decoder::with_buffer(raw) {
            Ok(d) => d.take(n).read_to_end(out),
            Err(e) => return Err(format!("cannot start Zstandard: {e}")),
        },
        Codec::Bz2 => bzip2::read::MultiBzDecoder::new(raw).take(n).read_to_end(out),
    };
    r.map(|_| ()).map_err(|e| format!("cannot decompress ({codec:?}): {e}"))
}

/// Whether `raw` is whole LZ4 frames, each ending with its end mark (and content checksum,
/// if its flags announce one). The decoder takes input that stops between two blocks as a
/// complete frame, so a block cut after its last data byte would pass unnoticed; walking the
/// block sizes (no decoding) tells.
fn lz4_frame_complete(raw: &[u8]) -> bool {
    let mut at = 0usize;
    while at < raw.len() {
        let Some(&flags) = raw.get(at + 4) else { return false };
        // magic, FLG, BD, optional content size and dictionary id, header checksum
        at += 7 + if flags & 0x08 != 0 { 8 } else { 0 } + if flags & 0x01 != 0 { 4 } else { 0 };
        let block_checksum = if flags & 0x10 != 0 { 4 } else { 0 };
        loop {
            let Some(b) = raw.get(at..at + 4) else { return false };
            let size = u32::from_le_bytes([b[0], b[1], b[2], b[3]]) & 0x7fff_ffff;
            at += 4;
            if size == 0 {
                break;
            }
            at = at.saturating_add(size as usize + block_checksum);
        }
        if flags & 0x04 != 0 {
            at += 4;
        }
        if at > raw.len() {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn round_trips_and_cuts() {
        let data: Vec<u8> = (0..50_000u32).flat_map(|i| (i / 7).to_le_bytes()).collect();
        let mut lz = lz4_flex::frame::FrameEncoder::new(Vec::new());
        std::io::Write::write_all(&mut lz, &data).unwrap();
        let lz = lz.finish().unwrap();
        let mut out = Vec::new();
        decompress(Codec::Lz4, &lz, 1 << 20, &mut out).unwrap();
        assert_eq!(out, data);
        for cut in [1, 3, 4, 5, lz.len() / 2] {
            assert!(decompress(Codec::Lz4, &lz[..lz.len() - cut], 1 << 20, &mut out).is_err(), "cut {cut}");
        }
        assert!(decompress(Codec::Lz4, &lz, 1000, &mut out).unwrap_err().contains("more than 1000"));

        let mut bz = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
        std::io::Write::write_all(&mut bz, &data).unwrap();
        let bz = bz.finish().unwrap();
        decompress(Codec::Bz2, &bz, 1 << 20, &mut out).unwrap();
        assert_eq!(out, data);
        assert!(decompress(Codec::Bz2, &bz[..bz.len() - 1], 1 << 20, &mut out).is_err());

        let zs = zstd::encode_all(&data[..], 3).unwrap();
        decompress(Codec::Zstd, &zs, 1 << 20, &mut out).unwrap();
        assert_eq!(out, data);
        for cut in [1, 4, zs.len() / 2] {
            assert!(decompress(Codec::Zstd, &zs[..zs.len() - cut], 1 << 20, &mut out).is_err(), "cut {cut}");
        }
        assert!(decompress(Codec::Zstd, b"not zstd", 1 << 20, &mut out).is_err());
        assert!(decompress(Codec::None, &data, 10, &mut out).is_err());
    }

    /// A bomb (64 MiB of zeros in a few kB) against a 1 MiB limit: an error naming the limit,
    /// and the buffer never grew past about twice the limit (it grows with the decoder's
    /// output, doubling).
    #[test]
    fn bombs_stop_at_the_limit() {
        let mut z = zstd::stream::Encoder::new(Vec::new(), 3).unwrap();
        let block = vec![0u8; 1 << 20];
        for _ in 0..64 {
            std::io::Write::write_all(&mut z, &block).unwrap();
        }
        let z = z.finish().unwrap();
        let mut lz = lz4_flex::frame::FrameEncoder::new(Vec::new());
        for _ in 0..64 {
            std::io::Write::write_all(&mut lz, &block).unwrap();
        }
        let lz = lz.finish().unwrap();
        for (codec, raw) in [(Codec::Zstd, z), (Codec::Lz4, lz)] {
            let mut out = Vec::new();
            let e = decompress(codec, &raw, 1 << 20, &mut out).unwrap_err();
            assert!(e.contains("more than 1048576 bytes"), "{codec:?}: {e}");
            assert!(out.capacity() <= 2 << 20, "{codec:?}: grew to {} bytes", out.capacity());
        }
    }
}
