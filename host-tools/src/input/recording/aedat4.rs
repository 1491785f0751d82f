//! AEDAT4: the recording format of iniVation's DV software and `dv-processing`.
//!
//! A file is the line `#!AER-DAT4.0\r\n`, a `u32` length and that many bytes of IOHeader
//! FlatBuffer (identifier `IOHE`: the compression of every packet, the position of the data
//! table, and the info node: an XML document describing each stream), then packets up to the
//! data table (or to the end of the file when a recording was interrupted before the table was
//! written). A packet is an 8-byte header (`i32` stream id, `i32` size) and `size` bytes,
//! compressed as the header says (none, LZ4 frames, Zstandard); decompressed, it is a
//! size-prefixed FlatBuffer whose identifier names its type. Event packets (`EVTS`) hold a
//! vector of 16-byte events: `i64` timestamp in µs, `i16` x, `i16` y, `bool` polarity, padding.
//! Frames, IMU samples and triggers are skipped without being decompressed.
//!
//! The data table (`FTAB`, compressed like the packets) lists every packet with its element
//! count: the reader uses it to know the event count up front and, at the end, to check that
//! it read every event the file holds.

pub use super::aedat4info::StreamInfo;
use super::{
    aedat4info::{choose_stream, parse_info},
    codec::{self, Codec},
    flatbuf::{Buf, Table},
    types::{EventSource, Position, ReadError},
};
use evcal_core::event::{Event, SensorSize};
use std::{
    fs::File,
    io::{BufReader, Read, Seek, SeekFrom},
    path::{Path, PathBuf},
};

/// The first bytes of every AEDAT4 file.
pub const MAGIC: &[u8; 14] = b"#!AER-DAT4.0\r\n";

/// Largest packet accepted, compressed or decompressed: 4 M events, far above what DV and
/// dv-processing write (a packet per camera transfer, or per part of an `EventStore` as it
/// was built: milliseconds of events, kB to a few MB); a packet has no declared size, so this
/// bounds what a corrupt or hostile one (19 kB of Zstandard can expand to 512 MB) makes evcal
/// hold.
const MAX_PACKET: u64 = 64 << 20;

/// Largest data table accepted, compressed or decompressed: some 40 bytes a packet, so about
/// 1.5 M packets, hours of recording.
const MAX_TABLE: u64 = 64 << 20;

/// Bytes an `EVTS` packet may hold besides its events (its tables and padding: 28 in DV's).
const MAX_PACKET_SLACK: usize = 128;

/// Largest IOHeader accepted (its info node lists the streams: a few kB).
const MAX_HEADER: u64 = 16 << 20;

/// Bytes of one event in an `EVTS` packet.
const EVENT_BYTES: usize = 16;

/// How packets are compressed (the IOHeader's `compression`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    /// Stored as they are.
    None,
    /// LZ4 frames (DV's `LZ4` and `LZ4_HIGH`).
    Lz4,
    /// Zstandard frames (DV's `ZSTD` and `ZSTD_HIGH`).
    Zstd,
}

/// Streaming reader of the events of one AEDAT4 event stream.
pub struct Aedat4Reader {
    path: PathBuf,
    file: BufReader<File>,
    file_len: u64,
    /// File offset of the next packet header.
    pos: u64,
    /// Where packets end: the data table, or the end of the file.
    end: u64,
    compression: Compression,
    stream: StreamInfo,
    streams: Vec<StreamInfo>,
    /// Events the data table lists for the stream, when it could be read.
    listed: Option<u64>,
    notes: Vec<String>,
    raw: Vec<u8>,
    packet: Vec<u8>,
    /// The current packet: file offset, first event's position in `packet`, events, next.
    packet_at: u64,
    ev_start: usize,
    ev_count: usize,
    ev_next: usize,
    read: u64,
    done: bool,
}

impl Aedat4Reader {
    /// Opens `path`, reads its header and info node, and picks the event stream: the one
    /// named or numbered `stream` if given, else the only event stream (or the one named
    /// `events` when there are several).
    pub fn open(path: &Path, stream: Option<&str>) -> Result<Self, ReadError> {
        let at = |o: u64, m: String| ReadError::new(path, Position::Byte(o), m);
        let f = File::open(path).map_err(|e| ReadError::io(path, e))?;
        let file_len = f.metadata().map_err(|e| ReadError::io(path, e))?.len();
        let mut file = BufReader::with_capacity(1 << 16, f);

        let mut magic = [0u8; 18];
        let got = super::bytes::read_up_to(&mut file, &mut magic).map_err(|e| ReadError::io(path, e))?;
        if got < MAGIC.len() || magic[..MAGIC.len()] != MAGIC[..] {
            let start = String::from_utf8_lossy(&magic[..got.min(14)]).trim_end().to_string();
            let what = if got == 0 {
                "the file is empty".to_string()
            } else if start.starts_with("#!AER-DAT") {
                format!("it is {start:?}: AEDAT 2 and 3 are not supported (DV converts them to AEDAT4)")
            } else {
                format!("it starts {start:?}")
            };
            return Err(at(0, format!("not an AEDAT4 file: expected the header '#!AER-DAT4.0', but {what}")));
        }
        if got < magic.len() {
            return Err(at(got as u64, "truncated: the file ends inside the header length".into()));
        }
        let header_len = u64::from(u32::from_le_bytes([magic[14], magic[15], magic[16], magic[17]]));
        let header_start = 18u64;
        if header_len > MAX_HEADER {
            return Err(at(14, format!("corrupt header: an IOHeader of {header_len} bytes (DV writes a few kB)")));
        }
        if header_start + header_len > file_len {
            return Err(at(
                header_start,
                format!(
                    "truncated: the IOHeader is {header_len} bytes but the file has {} after it",
                    file_len - header_start
                ),
            ));
        }
        let mut header = vec![0u8; header_len as usize];
        file.read_exact(&mut header).map_err(|e| at(header_start, e.to_string()))?;
        let bad_header = |what: &str| at(header_start, format!("corrupt IOHeader: {what}"));
        let hb = Buf(&header);
        if hb.identifier() != Some(*b"IOHE") {
            return Err(bad_header("no 'IOHE' identifier"));
        }
        let root = hb.root().ok_or_else(|| bad_header("bad root table"))?;
        let compression = match root.i32(0, 0).ok_or_else(|| bad_header("bad compression field"))? {
            0 => Compression::None,
            1 | 2 => Compression::Lz4,
            3 | 4 => Compression::Zstd,
            c => return Err(bad_header(&format!("unknown compression {c} (known: 0 none, 1-2 LZ4, 3-4 Zstandard)"))),
        };
        let table_pos = root.i64(1, -1).ok_or_else(|| bad_header("bad data table position"))?;
        let info = root.bytes(2).flatten().ok_or_else(|| bad_header("no info node (the XML list of streams)"))?;
        let info = std::str::from_utf8(info).map_err(|_| bad_header("the info node is not UTF-8"))?;
        let (streams, bad_sizes) = parse_info(info).map_err(|m| bad_header(&m))?;
        let chosen = choose_stream(&streams, stream).map_err(|m| ReadError::new(path, Position::File, m))?;
        if let Some((_, m)) = bad_sizes.iter().find(|(id, _)| *id == chosen.id) {
            return Err(bad_header(&format!("event stream {chosen} {m}")));
        }

        let data_start = header_start + header_len;
        let mut notes = Vec::new();
        let (end, listed) = if table_pos < 0 {
            notes.push(format!(
                "{}: no data table (the recording was not closed cleanly?): reading packets to the end of the file",
                path.display()
            ));
            (file_len, None)
        } else {
            let table_pos = table_pos as u64;
            if table_pos > file_len {
                return Err(at(
                    file_len,
                    format!("truncated: the header puts the data table at byte {table_pos}, but the file has {file_len} bytes"),
                ));
            }
            if table_pos < data_start {
                return Err(bad_header(&format!("the data table position {table_pos} lies inside the header")));
            }
            let listed = match read_table(&mut file, table_pos, file_len, compression, chosen.id) {
                Ok(n) => Some(n),
                Err(m) => {
                    notes.push(format!(
                        "{}: the data table at byte {table_pos} is unreadable ({m}); the event count is not checked",
                        path.display()
                    ));
                    None
                }
            };
            file.seek(SeekFrom::Start(data_start)).map_err(|e| at(data_start, e.to_string()))?;
            (table_pos, listed)
        };
        Ok(Self {
            path: path.to_path_buf(),
            file,
            file_len,
            pos: data_start,
            end,
            compression,
            stream: chosen,
            streams,
            listed,
            notes,
            raw: Vec::new(),
            packet: Vec::new(),
            packet_at: 0,
            ev_start: 0,
            ev_count: 0,
            ev_next: 0,
            read: 0,
            done: false,
        })
    }

    /// The sensor size the event stream states.
    pub fn sensor(&self) -> Option<SensorSize> {
        self.stream.size
    }

    /// The event stream being read.
    pub fn stream(&self) -> &StreamInfo {
        &self.stream
    }

    /// Every stream the file lists.
    pub fn streams(&self) -> &[StreamInfo] {
        &self.streams
    }

    /// The event count the data table lists, when the file has a readable one.
    pub fn len(&self) -> Option<u64> {
        self.listed
    }

    /// Whether the data table lists no events.
    pub fn is_empty(&self) -> bool {
        self.listed == Some(0)
    }

    /// The packet compression.
    pub fn compression(&self) -> Compression {
        self.compression
    }

    /// What the reader noticed that the user should know (no data table, ...).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    fn err(&self, at: u64, m: impl Into<String>) -> ReadError {
        ReadError::new(&self.path, Position::Byte(at), m)
    }

    /// Reads packets until one of the chosen stream with events is loaded; `Ok(false)` at the
    /// end of the packets.
    fn next_packet(&mut self) -> Result<bool, ReadError> {
        loop {
            if self.pos >= self.end {
                return Ok(false);
            }
            let at = self.pos;
            if self.end - at < 8 {
                return Err(self.err(at, format!("truncated: {} bytes left, a packet header takes 8", self.end - at)));
            }
            let mut h = [0u8; 8];
            self.file.read_exact(&mut h).map_err(|e| self.err(at, format!("cannot read packet header: {e}")))?;
            let id = i32::from_le_bytes([h[0], h[1], h[2], h[3]]);
            let size = i32::from_le_bytes([h[4], h[5], h[6], h[7]]);
            if size < 0 {
                return Err(self.err(at, format!("corrupt packet header: negative size {size}")));
            }
            let size = size as u64;
            if size > MAX_PACKET {
                return Err(self.err(
                    at,
                    format!(
                        "corrupt packet header: a packet of {size} bytes (evcal reads packets of up to {MAX_PACKET})"
                    ),
                ));
            }
            if size > self.end - at - 8 {
                let what =
                    if self.end == self.file_len { "the file" } else { "the packet area (up to the data table)" };
                return Err(self.err(
                    at,
                    format!(
                        "truncated: a packet of stream {id} declares {size} bytes, {what} has {} left",
                        self.end - at - 8
                    ),
                ));
            }
            self.pos = at + 8 + size;
            if id != self.stream.id {
                self.skip_packet(at, id, size)?;
                continue;
            }
            self.raw.resize(size as usize, 0);
            self.file.read_exact(&mut self.raw).map_err(|e| self.err(at, format!("cannot read packet: {e}")))?;
            decompress(self.compression, &self.raw, MAX_PACKET, &mut self.packet)
                .map_err(|m| self.err(at, format!("packet of stream {id}: {m}")))?;
            let (start, count) =
                events_of(&self.packet).map_err(|m| self.err(at, format!("event packet of stream {id}: {m}")))?;
            self.packet_at = at;
            self.ev_start = start;
            self.ev_count = count;
            self.ev_next = 0;
            if count > 0 {
                return Ok(true);
            }
        }
    }

    /// Passes over a packet of another stream. Its stream must be one the header lists.
    /// Without a readable data table (which would show events lost at the end), a packet
    /// whose stream id was corrupted would hide its events: then each skipped packet's
    /// first bytes are decompressed and its type checked against its stream's.
    fn skip_packet(&mut self, at: u64, id: i32, size: u64) -> Result<(), ReadError> {
        let Some(stream) = self.streams.iter().find(|s| s.id == id) else {
            return Err(self.err(at, format!("a packet of stream {id}, which the header does not list: corrupt")));
        };
        if self.listed.is_some() || stream.type_id.len() != 4 {
            return self.file.seek_relative(size as i64).map_err(|e| self.err(at, e.to_string()));
        }
        let want = stream.type_id.clone();
        self.raw.resize(size as usize, 0);
        self.file.read_exact(&mut self.raw).map_err(|e| self.err(at, format!("cannot read packet: {e}")))?;
        let codec = codec_of(self.compression);
        codec::decompress_prefix(codec, &self.raw, 12, &mut self.packet)
            .map_err(|m| self.err(at, format!("packet of stream {id}: {m}")))?;
        match self.packet.get(8..12) {
            Some(got) if got == want.as_bytes() => Ok(()),
            got => Err(self.err(
                at,
                format!(
                    "a packet of stream {id} ({want}) holds {:?}: its stream id is corrupt",
                    got.map(String::from_utf8_lossy).unwrap_or_default()
                ),
            )),
        }
    }

    fn finish(&mut self) -> Option<ReadError> {
        match self.listed {
            Some(n) if n != self.read => Some(self.err(
                self.end,
                format!(
                    "the data table lists {n} events for stream {}, but the packets hold {}",
                    self.stream, self.read
                ),
            )),
            _ => None,
        }
    }
}

impl EventSource for Aedat4Reader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        if self.done {
            return None;
        }
        if self.ev_next >= self.ev_count {
            match self.next_packet() {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    return self.finish().map(Err);
                }
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
            }
        }
        let i = self.ev_next;
        self.ev_next += 1;
        let o = self.ev_start + i * EVENT_BYTES;
        // `events_of` checked that the whole vector lies inside the packet.
        let b = &self.packet[o..o + EVENT_BYTES];
        let t = i64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
        let x = i16::from_le_bytes([b[8], b[9]]);
        let y = i16::from_le_bytes([b[10], b[11]]);
        let p = b[12];
        if t < 0 || x < 0 || y < 0 || p > 1 {
            self.done = true;
            return Some(Err(self.err(
                self.packet_at,
                format!("event {i} of the packet: bad event (t {t} µs, x {x}, y {y}, polarity byte {p})"),
            )));
        }
        self.read += 1;
        Some(Ok(Event { t_us: t as u64, x: x as u16, y: y as u16, polarity: p == 1 }))
    }

    fn progress_bytes(&self) -> u64 {
        self.pos
    }

    fn notes(&self) -> Vec<String> {
        self.notes.clone()
    }
}

/// Decompresses one packet (or the data table) into `out`, at most `limit` bytes.
fn decompress(c: Compression, raw: &[u8], limit: u64, out: &mut Vec<u8>) -> Result<(), String> {
    codec::decompress(codec_of(c), raw, limit, out)
}

fn codec_of(c: Compression) -> Codec {
    match c {
        Compression::None => Codec::None,
        Compression::Lz4 => Codec::Lz4,
        Compression::Zstd => Codec::Zstd,
    }
}

/// Checks a decompressed `EVTS` packet; where its events start and how many there are.
fn events_of(packet: &[u8]) -> Result<(usize, usize), String> {
    let buf = Buf::size_prefixed(packet).ok_or("the size prefix claims more bytes than the packet holds")?;
    match buf.identifier() {
        Some(id) if &id == b"EVTS" => {}
        Some(id) => return Err(format!("identifier '{}', expected 'EVTS'", String::from_utf8_lossy(&id))),
        None => return Err("too short for a FlatBuffer".into()),
    }
    let root = buf.root().ok_or("bad root table")?;
    let (start, count) = root.vector(0).ok_or("bad events vector")?.unwrap_or((0, 0));
    let bytes = count.checked_mul(EVENT_BYTES).ok_or("absurd event count")?;
    if start.checked_add(bytes).is_none_or(|e| e > buf.0.len()) {
        return Err(format!("{count} events of {EVENT_BYTES} bytes do not fit in the packet"));
    }
    // Besides its events, a packet holds a few dozen bytes of tables. One much larger than its
    // events has a corrupted count: packets carry no checksum (nor do DV's LZ4 frames), and
    // the data table, which would show the loss, may be missing.
    if buf.0.len() > bytes + MAX_PACKET_SLACK {
        return Err(format!("{} bytes hold only {count} events: the event count is corrupt", buf.0.len()));
    }
    // Positions are relative to the FlatBuffer, which starts after the 4-byte size prefix.
    Ok((start + 4, count))
}

/// Reads the data table at `pos` and counts the events it lists for stream `id`.
fn read_table(file: &mut BufReader<File>, pos: u64, file_len: u64, c: Compression, id: i32) -> Result<u64, String> {
    let len = file_len - pos;
    if len > MAX_TABLE {
        return Err(format!("{len} bytes is more than evcal reads for a table ({MAX_TABLE})"));
    }
    file.seek(SeekFrom::Start(pos)).map_err(|e| e.to_string())?;
    let mut raw = vec![0u8; len as usize];
    file.read_exact(&mut raw).map_err(|e| e.to_string())?;
    let mut table = Vec::new();
    decompress(c, &raw, MAX_TABLE, &mut table)?;
    let buf = Buf::size_prefixed(&table).ok_or("bad size prefix")?;
    if buf.identifier() != Some(*b"FTAB") {
        return Err("no 'FTAB' identifier".into());
    }
    let root = buf.root().ok_or("bad root table")?;
    let Some((start, n)) = root.vector(0).ok_or("bad table vector")? else { return Ok(0) };
    let mut total = 0u64;
    for i in 0..n {
        let def: Table<'_> = root.table_in_vector(start, i).ok_or_else(|| format!("bad entry {i}"))?;
        // FileDataDefinition: ByteOffset, PacketInfo (struct: i32 stream id, i32 size), NumElements, ...
        let info = def.inline(1).ok_or_else(|| format!("bad entry {i}"))?;
        let stream = match info {
            Some(at) => def.buf().i32(at).ok_or_else(|| format!("bad entry {i}"))?,
            None => 0,
        };
        if stream == id {
            let count = def.i64(2, 0).ok_or_else(|| format!("bad entry {i}"))?;
            let count = u64::try_from(count).map_err(|_| format!("entry {i}: negative count"))?;
            total = total.checked_add(count).ok_or_else(|| format!("entry {i}: absurd count {count}"))?;
        }
    }
    Ok(total)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn event_packet_checks() {
        // Well-formed packets come from dv-processing's files (the writer tests); here only
        // the rejections of malformed ones.
        assert!(events_of(&[]).is_err());
        assert!(events_of(&[8, 0, 0, 0, 4, 0, 0, 0, b'F', b'R', b'M', b'E']).unwrap_err().contains("FRME"));
        assert!(events_of(&[200, 0, 0, 0, 4, 0, 0, 0]).unwrap_err().contains("size prefix"));
    }
}
