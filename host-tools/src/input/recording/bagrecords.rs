//! The records of a ROS bag: their header fields, and the data of a chunk, decompressed as it
//! is read: records, and the events of a
//! message, come out of the decoder in order. rosbag writes chunks of 768 KiB (its
//! `chunk_threshold`), and a message larger than that gets a chunk of its own, so a chunk is as
//! large as one `EventArray` may be; held whole, a chunk's declared size, or a bomb of a few MB
//! that expands to gigabytes, would set evcal's memory. Streamed, a chunk costs the decoder's
//! buffers whatever its size, and nothing is allocated from a size the file declares.

use super::codec::{self, Codec};
use evcal_core::event::SensorSize;
use std::io::{BufRead, BufReader, Read};

/// One connection (a topic with its message type) of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagTopic {
    /// The topic.
    pub topic: String,
    /// Its message type, e.g. `dvs_msgs/EventArray`.
    pub msg_type: String,
}

/// Largest record header, and largest record data held in memory (connection records: a
/// topic and its message definition, a few kB; chunk infos: 8 bytes a connection): well above
/// what rosbag writes, low enough that a corrupt length costs little.
pub(super) const MAX_HELD: u32 = 1 << 20;

/// Bytes of one `dvs_msgs/Event`.
pub(super) const EVENT_BYTES: u64 = 13;

/// Bytes buffered between the decoder and the record parser.
const BUFFER: usize = 1 << 16;

/// A record header's fields.
#[derive(Debug)]
pub(super) struct Fields<'a>(Vec<(&'a [u8], &'a [u8])>);

impl<'a> Fields<'a> {
    pub(super) fn parse(mut h: &'a [u8]) -> Result<Self, String> {
        let mut out = Vec::new();
        while !h.is_empty() {
            let len = h.get(..4).ok_or("a header field's length is cut short")?;
            let len = u32::from_le_bytes([len[0], len[1], len[2], len[3]]) as usize;
            let f = h.get(4..4usize.saturating_add(len)).ok_or("a header field runs past its header")?;
            let eq = f.iter().position(|&b| b == b'=').ok_or("a header field has no '='")?;
            out.push((&f[..eq], &f[eq + 1..]));
            h = &h[4 + len..];
        }
        Ok(Self(out))
    }

    pub(super) fn get(&self, name: &str) -> Option<&'a [u8]> {
        self.0.iter().find(|(n, _)| *n == name.as_bytes()).map(|(_, v)| *v)
    }

    pub(super) fn op(&self) -> Result<u8, String> {
        match self.get("op") {
            Some([op]) => Ok(*op),
            Some(_) => Err("the 'op' field is not one byte".into()),
            None => Err("the record header has no 'op' field".into()),
        }
    }

    pub(super) fn u32(&self, name: &str) -> Result<u32, String> {
        match self.get(name) {
            Some(v) if v.len() == 4 => Ok(u32::from_le_bytes([v[0], v[1], v[2], v[3]])),
            _ => Err(format!("the record header has no 4-byte '{name}' field")),
        }
    }

    pub(super) fn u64(&self, name: &str) -> Result<u64, String> {
        match self.get(name) {
            Some(v) if v.len() == 8 => Ok(u64::from_le_bytes(v.try_into().unwrap_or([0; 8]))),
            _ => Err(format!("the record header has no 8-byte '{name}' field")),
        }
    }

    pub(super) fn string(&self, name: &str) -> Result<String, String> {
        self.get(name)
            .map(|v| String::from_utf8_lossy(v).into_owned())
            .ok_or_else(|| format!("the record header has no '{name}' field"))
    }
}

/// The connection record's topic and type (the type is in its data: the connection header).
pub(super) fn connection(fields: &Fields<'_>, data: &[u8]) -> Result<(u32, BagTopic), String> {
    let id = fields.u32("conn")?;
    let conn_header = Fields::parse(data).map_err(|e| format!("connection {id}: {e}"))?;
    let topic = fields.string("topic").or_else(|_| conn_header.string("topic"))?;
    let msg_type = conn_header.string("type").map_err(|e| format!("connection {id}: {e}"))?;
    Ok((id, BagTopic { topic, msg_type }))
}

/// The decompressed data of a chunk (or of one record outside chunks), read in order.
pub(super) struct ChunkStream {
    r: BufReader<Box<dyn Read>>,
    /// The uncompressed size the chunk's header declares.
    size: u64,
    /// Uncompressed bytes read so far.
    pos: u64,
}

/// A record's header inside a chunk: where it starts (uncompressed offset), its fields, and
/// the length of its data, which follows in the stream.
pub(super) struct RecordHead {
    pub(super) at: u64,
    pub(super) header: Vec<u8>,
    pub(super) dlen: u64,
}

/// What an `EventArray` message's fields before its events say.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct EventArrayHead {
    /// The events that follow.
    pub(super) count: u64,
    /// The `width` and `height` fields, as stated.
    pub(super) width: u32,
    pub(super) height: u32,
}

impl EventArrayHead {
    /// The sensor size the message states: `None` for 0 (drivers that do not know it), an
    /// error naming the value for one outside what evcal handles.
    pub(super) fn sensor(&self) -> Result<Option<SensorSize>, String> {
        super::types::stated_sensor(i128::from(self.width), i128::from(self.height))
    }
}

impl ChunkStream {
    /// The data `compressed`, decoded by `codec`, which must come to `size` bytes.
    pub(super) fn new(codec: Codec, compressed: impl Read + 'static, size: u64) -> Result<Self, String> {
        Ok(Self { r: BufReader::with_capacity(BUFFER, codec::reader(codec, compressed)?), size, pos: 0 })
    }

    /// Uncompressed bytes read so far: where the next record starts.
    pub(super) fn position(&self) -> u64 {
        self.pos
    }

    /// Bytes of the chunk not read yet.
    fn left(&self) -> u64 {
        self.size - self.pos
    }

    /// Fills `buf`, which the caller checked lies inside the chunk.
    fn fill(&mut self, buf: &mut [u8]) -> Result<(), String> {
        let mut got = 0;
        while got < buf.len() {
            match self.r.read(&mut buf[got..]) {
                Ok(0) => {
                    return Err(format!(
                        "the chunk header says {} bytes uncompressed, its data gives {}",
                        self.size,
                        self.pos + got as u64
                    ))
                }
                Ok(n) => got += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(format!("cannot decompress: {e}")),
            }
        }
        self.pos += got as u64;
        Ok(())
    }

    fn u32(&mut self) -> Result<u32, String> {
        let mut b = [0u8; 4];
        self.fill(&mut b)?;
        Ok(u32::from_le_bytes(b))
    }

    /// Passes over `n` bytes (which the caller checked lie inside the chunk).
    pub(super) fn skip(&mut self, mut n: u64) -> Result<(), String> {
        while n > 0 {
            let avail = match self.r.fill_buf() {
                Ok([]) => {
                    return Err(format!(
                        "the chunk header says {} bytes uncompressed, its data gives {}",
                        self.size, self.pos
                    ))
                }
                Ok(b) => b.len().min(usize::try_from(n).unwrap_or(usize::MAX)),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(format!("cannot decompress: {e}")),
            };
            self.r.consume(avail);
            self.pos += avail as u64;
            n -= avail as u64;
        }
        Ok(())
    }

    /// The next record's header; `None` at the end of the chunk, once the decoder has been
    /// seen to end there too.
    pub(super) fn next_record(&mut self) -> Result<Option<RecordHead>, String> {
        let at = self.pos;
        if self.left() == 0 {
            return match self.r.fill_buf() {
                Ok([]) => Ok(None),
                Ok(_) => Err(format!("the chunk's data gives more than the {} bytes its header says", self.size)),
                Err(e) => Err(format!("cannot decompress: {e}")),
            };
        }
        if self.left() < 4 {
            return Err("the record is cut short".into());
        }
        let hlen = self.u32()?;
        if hlen > MAX_HELD {
            return Err(format!("corrupt record: a header of {hlen} bytes (evcal reads at most {MAX_HELD})"));
        }
        if u64::from(hlen) + 4 > self.left() {
            return Err("the record header runs past the chunk".into());
        }
        let mut header = vec![0u8; hlen as usize];
        self.fill(&mut header)?;
        let dlen = u64::from(self.u32()?);
        if dlen > self.left() {
            return Err("the record data runs past the chunk".into());
        }
        Ok(Some(RecordHead { at, header, dlen }))
    }

    /// The data of a record to hold (a connection's), `dlen` bytes.
    pub(super) fn held_data(&mut self, dlen: u64) -> Result<Vec<u8>, String> {
        if dlen > u64::from(MAX_HELD) {
            return Err(format!("a connection record of {dlen} bytes (evcal reads at most {MAX_HELD})"));
        }
        let mut d = vec![0u8; dlen as usize];
        self.fill(&mut d)?;
        Ok(d)
    }

    /// Reads the fields of an `EventArray` message of `dlen` bytes up to its events, and checks
    /// that its events fill the rest of it. `std_msgs/Header` (`u32` seq, `u32` secs, `u32`
    /// nsecs, string frame_id), `u32` height, `u32` width, `u32` event count.
    pub(super) fn event_array(&mut self, dlen: u64) -> Result<EventArrayHead, String> {
        let cut = |o: u64| format!("EventArray cut short at byte {o} of {dlen}");
        if dlen < 16 {
            return Err(cut(dlen.min(12)));
        }
        self.skip(12)?;
        let frame_id_len = u64::from(self.u32()?);
        let o = 16 + frame_id_len;
        if o + 12 > dlen {
            return Err(cut(o.min(dlen)));
        }
        self.skip(frame_id_len)?;
        let height = self.u32()?;
        let width = self.u32()?;
        let count = u64::from(self.u32()?);
        let need = o + 12 + count * EVENT_BYTES;
        if need != dlen {
            return Err(format!("an EventArray of {count} events takes {need} bytes, the message has {dlen}"));
        }
        Ok(EventArrayHead { count, width, height })
    }

    /// The next event's bytes (the caller counts them against the message's).
    pub(super) fn event(&mut self) -> Result<[u8; EVENT_BYTES as usize], String> {
        let mut b = [0u8; EVENT_BYTES as usize];
        self.fill(&mut b)?;
        Ok(b)
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn header_fields() {
        let mut h = Vec::new();
        for f in [&b"op=\x05"[..], b"compression=lz4", b"size=\x10\x00\x00\x00"] {
            h.extend((f.len() as u32).to_le_bytes());
            h.extend(f);
        }
        let f = Fields::parse(&h).unwrap();
        assert_eq!(f.op(), Ok(5));
        assert_eq!(f.string("compression").unwrap(), "lz4");
        assert_eq!(f.u32("size"), Ok(16));
        assert!(f.u64("size").is_err());
        assert!(Fields::parse(&h[..h.len() - 1]).is_err());
        assert!(Fields::parse(&[3, 0, 0, 0, b'a', b'b', b'c']).unwrap_err().contains("'='"));
    }

    /// An LZ4 frame of `n` zero bytes, compressed (about 1/250 of `n`).
    fn lz4_zeros(n: usize) -> Vec<u8> {
        let mut lz = lz4_flex::frame::FrameEncoder::new(Vec::new());
        let block = vec![0u8; 1 << 16];
        for _ in 0..n / block.len() {
            std::io::Write::write_all(&mut lz, &block).unwrap();
        }
        lz.finish().unwrap()
    }

    /// A chunk declaring far more than its records hold, and a bomb expanding to 64 MiB of
    /// zeros: errors, each at the first record, with no buffer larger than the stream's own.
    #[test]
    fn a_bomb_is_refused_at_its_first_record_without_holding_it() {
        let bomb = lz4_zeros(64 << 20);
        assert!(bomb.len() < 1 << 20);
        let mut s = ChunkStream::new(Codec::Lz4, Cursor::new(bomb), 1 << 30).unwrap();
        // zeros: a record with an empty header and empty data, then the next...
        let r = s.next_record().unwrap().unwrap();
        assert_eq!((r.at, r.header.len(), r.dlen), (0, 0, 0));
        // ...and a zero-length message of the topic is refused before any allocation.
        assert!(s.event_array(0).unwrap_err().contains("cut short"));
        assert!(s.r.capacity() <= BUFFER);

        // A declared event count beyond the message: refused from the fields alone.
        let mut m = Vec::new();
        m.extend([0u8; 12]);
        m.extend(0u32.to_le_bytes());
        m.extend(260u32.to_le_bytes());
        m.extend(346u32.to_le_bytes());
        m.extend(u32::MAX.to_le_bytes());
        let n = m.len() as u64;
        let mut s = ChunkStream::new(Codec::None, Cursor::new(m), n).unwrap();
        assert!(s.event_array(n).unwrap_err().contains("4294967295 events takes"));

        // A held record longer than the cap: refused before it is allocated.
        let mut s = ChunkStream::new(Codec::None, Cursor::new(Vec::new()), 1 << 30).unwrap();
        let e = s.held_data(u64::from(MAX_HELD) + 1).unwrap_err();
        assert!(e.contains("evcal reads at most"), "{e}");
    }

    #[test]
    fn sizes_that_disagree_with_the_data_are_named() {
        let data = vec![1u8, 0, 0, 0, b'x', 0, 0, 0, 0];
        // the chunk header says more than the data gives
        let mut s = ChunkStream::new(Codec::None, Cursor::new(data.clone()), 20).unwrap();
        s.next_record().unwrap().unwrap();
        let e = s.next_record().err().unwrap();
        assert!(e.contains("says 20 bytes uncompressed, its data gives 9"), "{e}");
        // the chunk header says less
        let mut s = ChunkStream::new(Codec::None, Cursor::new([data.clone(), vec![7]].concat()), 9).unwrap();
        s.next_record().unwrap().unwrap();
        assert!(s.next_record().err().unwrap().contains("more than the 9 bytes"));
        // the data is exactly the size
        let mut s = ChunkStream::new(Codec::None, Cursor::new(data), 9).unwrap();
        assert_eq!(s.next_record().unwrap().unwrap().header, b"x");
        assert!(s.next_record().unwrap().is_none());
    }
}
