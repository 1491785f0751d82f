//! ROS1 bags (format 2.0) holding `dvs_msgs/EventArray` messages, as the ROS DVS driver
//! records them (E-Calib's own recordings: topic `/dvs/events`).
//!
//! A bag is the line `#ROSBAG V2.0\n` and records. A record is a `u32` header length, a
//! header of fields (`u32` length, `name=value`; the `op` field gives the record type), a
//! `u32` data length and the data. The bag header record (op 3) gives the position of the
//! index section (0 while a recording is still being written, or if it was never closed)
//! and the chunk count. Chunks (op 5) hold connection records (op 7: a topic and its message
//! type) and message data records (op 2: connection id, time, serialised message), compressed
//! as their `compression` field says (`none`, `bz2`, `lz4`). Index data records (op 4) follow
//! each chunk; the index section at the end repeats the connections and lists each chunk
//! (op 6: chunk info, with the message count per connection).
//!
//! The reader streams chunk by chunk. From the index section it learns the topics before
//! reading (to pick one, or list them in the error) and how many chunks and messages to
//! expect: reading fewer is an error, never a silent loss. An unindexed bag is read to its
//! end, the topic chosen when its connection first appears.
//!
//! `dvs_msgs/EventArray`: `std_msgs/Header` (`u32` seq, `u32` secs, `u32` nsecs, string
//! frame_id), `u32` height, `u32` width, `Event[]` (`u32` count, then 13 bytes each: `u16` x,
//! `u16` y, `u32` secs, `u32` nsecs, `u8` polarity). Times become µs rounded to nearest.

use super::{
    codec::{self, Codec},
    EventSource, Position, ReadError,
};
use evcal_core::event::{Event, SensorSize};
use std::{
    collections::HashMap,
    fs::File,
    io::{BufReader, Read, Seek, SeekFrom},
    path::{Path, PathBuf},
};

/// The first bytes of every ROS1 bag of format 2.0.
pub const MAGIC: &[u8; 13] = b"#ROSBAG V2.0\n";

/// The topic read when none is given and the bag has several event topics: the ROS DVS
/// driver's (and E-Calib's recordings').
pub const DEFAULT_TOPIC: &str = "/dvs/events";

/// The message type evcal decodes.
pub const EVENT_ARRAY: &str = "dvs_msgs/EventArray";

/// Largest record header, and largest chunk (compressed or not) accepted: well above what
/// `rosbag record` writes (768 KiB chunks; one message per chunk when larger), low enough that
/// a corrupt length cannot exhaust memory.
const MAX_HEADER: u32 = 1 << 20;
const MAX_CHUNK: u64 = 1 << 30;

/// Bytes of one `dvs_msgs/Event`.
const EVENT_BYTES: usize = 13;

const OP_MSG_DATA: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_INDEX_DATA: u8 = 0x04;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

/// One connection (a topic with its message type) of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagTopic {
    /// The topic.
    pub topic: String,
    /// Its message type, e.g. `dvs_msgs/EventArray`.
    pub msg_type: String,
}

/// Streaming reader of the events of one `dvs_msgs/EventArray` topic of a ROS1 bag.
pub struct BagReader {
    path: PathBuf,
    file: BufReader<File>,
    /// Offset of the next top-level record.
    pos: u64,
    /// Where the data records end: the index section, or the end of the file.
    data_end: u64,
    /// Chunk count and messages of the chosen topic that the index lists, for indexed bags.
    expected: Option<(u64, u64)>,
    /// The topic wanted (`--topic`), and the one being read once chosen.
    wanted: Option<String>,
    chosen: Option<String>,
    /// Connections seen: id to topic and type.
    conns: HashMap<u32, BagTopic>,
    chunk: Vec<u8>,
    raw: Vec<u8>,
    /// The chunk being read: its file offset, and the offset of its next record.
    chunk_at: u64,
    chunk_next: usize,
    in_chunk: bool,
    /// The message being read: where its record starts in the chunk (or in the file, for a
    /// message outside chunks), its events' start in `chunk`, their count, the next one.
    msg_at: (u64, Option<usize>),
    ev_start: usize,
    ev_count: usize,
    ev_next: usize,
    sensor: Option<SensorSize>,
    notes: Vec<String>,
    chunks_read: u64,
    messages_read: u64,
    done: bool,
}

/// A record header's fields.
#[derive(Debug)]
struct Fields<'a>(Vec<(&'a [u8], &'a [u8])>);

impl<'a> Fields<'a> {
    fn parse(mut h: &'a [u8]) -> Result<Self, String> {
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

    fn get(&self, name: &str) -> Option<&'a [u8]> {
        self.0.iter().find(|(n, _)| *n == name.as_bytes()).map(|(_, v)| *v)
    }

    fn op(&self) -> Result<u8, String> {
        match self.get("op") {
            Some([op]) => Ok(*op),
            Some(_) => Err("the 'op' field is not one byte".into()),
            None => Err("the record header has no 'op' field".into()),
        }
    }

    fn u32(&self, name: &str) -> Result<u32, String> {
        match self.get(name) {
            Some(v) if v.len() == 4 => Ok(u32::from_le_bytes([v[0], v[1], v[2], v[3]])),
            _ => Err(format!("the record header has no 4-byte '{name}' field")),
        }
    }

    fn u64(&self, name: &str) -> Result<u64, String> {
        match self.get(name) {
            Some(v) if v.len() == 8 => Ok(u64::from_le_bytes(v.try_into().unwrap_or([0; 8]))),
            _ => Err(format!("the record header has no 8-byte '{name}' field")),
        }
    }

    fn string(&self, name: &str) -> Result<String, String> {
        self.get(name)
            .map(|v| String::from_utf8_lossy(v).into_owned())
            .ok_or_else(|| format!("the record header has no '{name}' field"))
    }
}

/// A record inside a chunk's data at `at`: where its header and data lie, and where the next
/// record starts.
fn chunk_record(b: &[u8], at: usize) -> Result<(std::ops::Range<usize>, std::ops::Range<usize>, usize), String> {
    let u32_at = |o: usize| -> Result<usize, String> {
        let v = b.get(o..o.checked_add(4).ok_or("offset overflow")?).ok_or("the record is cut short")?;
        Ok(u32::from_le_bytes([v[0], v[1], v[2], v[3]]) as usize)
    };
    let hlen = u32_at(at)?;
    let h = at + 4..(at + 4).saturating_add(hlen);
    if h.end > b.len() {
        return Err("the record header runs past the chunk".into());
    }
    let dlen = u32_at(h.end)?;
    let d = h.end + 4..(h.end + 4).saturating_add(dlen);
    if d.end > b.len() {
        return Err("the record data runs past the chunk".into());
    }
    let next = d.end;
    Ok((h, d, next))
}

/// The connection record's topic and type (the type is in its data: the connection header).
fn connection(fields: &Fields<'_>, data: &[u8]) -> Result<(u32, BagTopic), String> {
    let id = fields.u32("conn")?;
    let conn_header = Fields::parse(data).map_err(|e| format!("connection {id}: {e}"))?;
    let topic = fields.string("topic").or_else(|_| conn_header.string("topic"))?;
    let msg_type = conn_header.string("type").map_err(|e| format!("connection {id}: {e}"))?;
    Ok((id, BagTopic { topic, msg_type }))
}

/// Where an EventArray message's events start in `msg`, their count, and the sensor size.
fn event_array(msg: &[u8]) -> Result<(usize, usize, Option<SensorSize>), String> {
    let u32_at = |o: usize| -> Result<u32, String> {
        msg.get(o..o + 4)
            .map(|v| u32::from_le_bytes([v[0], v[1], v[2], v[3]]))
            .ok_or_else(|| format!("EventArray cut short at byte {o} of {}", msg.len()))
    };
    // std_msgs/Header: seq, stamp (secs, nsecs), frame_id
    let frame_id_len = u32_at(12)? as usize;
    let o = 16usize.checked_add(frame_id_len).ok_or("absurd frame_id length")?;
    let height = u32_at(o)?;
    let width = u32_at(o + 4)?;
    let count = u32_at(o + 8)? as usize;
    let start = o + 12;
    let need = start as u64 + count as u64 * EVENT_BYTES as u64;
    if need != msg.len() as u64 {
        return Err(format!("an EventArray of {count} events takes {need} bytes, the message has {}", msg.len()));
    }
    let size = match (u16::try_from(width), u16::try_from(height)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Some(SensorSize::new(w, h)),
        _ => None,
    };
    Ok((start, count, size))
}

impl BagReader {
    /// Opens `path` and chooses the topic: `topic` if given, else the only
    /// `dvs_msgs/EventArray` topic, else `/dvs/events`. For an indexed bag a missing topic is
    /// an error here, listing the bag's topics; the first message is read to learn the sensor
    /// size.
    pub fn open(path: &Path, topic: Option<&str>) -> Result<Self, ReadError> {
        let at = |o: u64, m: String| ReadError::new(path, Position::Byte(o), m);
        let f = File::open(path).map_err(|e| ReadError::io(path, e))?;
        let file_len = f.metadata().map_err(|e| ReadError::io(path, e))?.len();
        let mut file = BufReader::with_capacity(1 << 16, f);
        let mut magic = Vec::with_capacity(13);
        (&mut file).take(13).read_to_end(&mut magic).map_err(|e| ReadError::io(path, e))?;
        if magic[..] != MAGIC[..] {
            let what = if magic.is_empty() {
                "the file is empty".to_string()
            } else if magic.starts_with(b"#ROSBAG V") {
                format!("it is {:?}; evcal reads format 2.0 (ROS1 since 2010)", String::from_utf8_lossy(&magic).trim())
            } else {
                format!("it starts {:?}", String::from_utf8_lossy(&magic))
            };
            return Err(at(0, format!("not a ROS bag (format 2.0): expected '#ROSBAG V2.0', but {what}")));
        }
        let mut r = Self {
            path: path.to_path_buf(),
            file,
            pos: 13,
            data_end: file_len,
            expected: None,
            wanted: topic.map(str::to_string),
            chosen: None,
            conns: HashMap::new(),
            chunk: Vec::new(),
            raw: Vec::new(),
            chunk_at: 0,
            chunk_next: 0,
            in_chunk: false,
            msg_at: (0, None),
            ev_start: 0,
            ev_count: 0,
            ev_next: 0,
            sensor: None,
            notes: Vec::new(),
            chunks_read: 0,
            messages_read: 0,
            done: false,
        };
        let (fields, _) =
            r.read_record(file_len, false)?.ok_or_else(|| at(13, "truncated: no bag header record".into()))?;
        let f = Fields::parse(&fields).map_err(|m| at(13, format!("bag header: {m}")))?;
        if f.op().map_err(|m| at(13, m))? != OP_BAG_HEADER {
            return Err(at(13, "the first record is not the bag header (op 3)".into()));
        }
        let index_pos = f.u64("index_pos").map_err(|m| at(13, m))?;
        let chunk_count = f.u32("chunk_count").map_err(|m| at(13, m))?;
        if index_pos == 0 {
            r.notes.push(format!(
                "{}: the bag has no index (recording not closed cleanly?): reading it to the end; `rosbag reindex` makes one",
                path.display()
            ));
        } else if index_pos > file_len {
            return Err(at(
                file_len,
                format!(
                    "truncated: the bag header puts the index at byte {index_pos}, but the file has {file_len} bytes"
                ),
            ));
        } else if index_pos < r.pos {
            return Err(at(13, format!("corrupt bag header: index position {index_pos} lies inside the header")));
        } else {
            let data_start = r.pos;
            let chunk_messages = r.read_index(index_pos, file_len)?;
            let topics = r.topics();
            let chosen =
                choose_topic(&topics, r.wanted.as_deref()).map_err(|m| ReadError::new(path, Position::File, m))?;
            let ids: Vec<u32> = r.conns.iter().filter(|(_, c)| c.topic == chosen).map(|(id, _)| *id).collect();
            let messages = chunk_messages.iter().filter(|(id, _)| ids.contains(id)).map(|(_, n)| n).sum();
            r.chosen = Some(chosen);
            r.expected = Some((u64::from(chunk_count), messages));
            r.data_end = index_pos;
            r.pos = data_start;
            r.file.seek(SeekFrom::Start(data_start)).map_err(|e| at(data_start, e.to_string()))?;
        }
        // Read up to the first message of the topic: it gives the sensor size (and, unindexed,
        // decides the topic).
        match r.next_message() {
            Ok(true) => {}
            Ok(false) => {
                r.done = true;
                if r.chosen.is_none() {
                    // Unindexed, and no message of the topic: fine if the topic exists (no
                    // events), an error listing the topics otherwise.
                    let topics = r.topics();
                    r.chosen = Some(
                        choose_topic(&topics, r.wanted.as_deref())
                            .map_err(|m| ReadError::new(path, Position::File, m))?,
                    );
                }
            }
            Err(e) => return Err(e),
        }
        Ok(r)
    }

    /// The sensor size of the first message (its `width`, `height`).
    pub fn sensor(&self) -> Option<SensorSize> {
        self.sensor
    }

    /// The topic being read.
    pub fn topic(&self) -> Option<&str> {
        self.chosen.as_deref()
    }

    /// The bag's topics (those seen so far, for an unindexed bag), sorted.
    pub fn topics(&self) -> Vec<BagTopic> {
        let mut t: Vec<BagTopic> = self.conns.values().cloned().collect();
        t.sort_by(|a, b| a.topic.cmp(&b.topic));
        t.dedup();
        t
    }

    /// What the reader noticed that the user should know (no index, ...).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    fn err(&self, at: u64, m: impl Into<String>) -> ReadError {
        ReadError::new(&self.path, Position::Byte(at), m)
    }

    fn err_in_chunk(&self, rec: usize, m: impl std::fmt::Display) -> ReadError {
        self.err(self.chunk_at, format!("in the chunk's uncompressed data at offset {rec}: {m}"))
    }

    /// Reads the top-level record at `self.pos` (which must end by `end`): its header, and its
    /// data into `self.raw` if `keep_data`, else skipped. `None` at `end`.
    fn read_record(&mut self, end: u64, keep_data: bool) -> Result<Option<(Vec<u8>, u64)>, ReadError> {
        let at = self.pos;
        if at >= end {
            return Ok(None);
        }
        let left = end - at;
        let trunc = |what: &str| format!("truncated: the file ends inside a record's {what}");
        let mut n = [0u8; 4];
        if left < 4 {
            return Err(self.err(at, trunc("header length")));
        }
        self.file.read_exact(&mut n).map_err(|e| self.err(at, e.to_string()))?;
        let hlen = u32::from_le_bytes(n);
        if hlen > MAX_HEADER {
            return Err(self.err(at, format!("corrupt record: a header of {hlen} bytes")));
        }
        if left < 8 + u64::from(hlen) {
            return Err(self.err(at, trunc("header")));
        }
        let mut header = vec![0u8; hlen as usize];
        self.file.read_exact(&mut header).map_err(|e| self.err(at, e.to_string()))?;
        self.file.read_exact(&mut n).map_err(|e| self.err(at, e.to_string()))?;
        let dlen = u64::from(u32::from_le_bytes(n));
        if left < 8 + u64::from(hlen) + dlen {
            return Err(
                self.err(at, format!("truncated: a record's data of {dlen} bytes runs past the end of the file"))
            );
        }
        if keep_data {
            if dlen > MAX_CHUNK {
                return Err(self.err(at, format!("a record of {dlen} bytes is more than evcal reads at once")));
            }
            self.raw.resize(dlen as usize, 0);
            let mut raw = std::mem::take(&mut self.raw);
            let r = self.file.read_exact(&mut raw);
            self.raw = raw;
            r.map_err(|e| self.err(at, e.to_string()))?;
        } else {
            self.file.seek_relative(dlen as i64).map_err(|e| self.err(at, e.to_string()))?;
        }
        self.pos = at + 8 + u64::from(hlen) + dlen;
        Ok(Some((header, dlen)))
    }

    /// Reads the index section: connections, and the message count per connection over all
    /// chunk infos.
    fn read_index(&mut self, index_pos: u64, file_len: u64) -> Result<Vec<(u32, u64)>, ReadError> {
        self.pos = index_pos;
        self.file.seek(SeekFrom::Start(index_pos)).map_err(|e| self.err(index_pos, e.to_string()))?;
        let mut counts: HashMap<u32, u64> = HashMap::new();
        loop {
            let at = self.pos;
            let Some((h, _)) = self.read_record(file_len, true)? else { break };
            let f = Fields::parse(&h).map_err(|m| self.err(at, m))?;
            match f.op().map_err(|m| self.err(at, m))? {
                OP_CONNECTION => {
                    let (id, c) = connection(&f, &self.raw).map_err(|m| self.err(at, m))?;
                    self.conns.insert(id, c);
                }
                OP_CHUNK_INFO => {
                    for pair in self.raw.chunks(8) {
                        let [a, b, c, d, e, g, h, i] =
                            pair.try_into().map_err(|_| self.err(at, "chunk info: odd data length"))?;
                        *counts.entry(u32::from_le_bytes([a, b, c, d])).or_default() +=
                            u64::from(u32::from_le_bytes([e, g, h, i]));
                    }
                }
                op => return Err(self.err(at, format!("unexpected record (op {op}) in the index section"))),
            }
        }
        Ok(counts.into_iter().collect())
    }

    /// Whether connection `id` belongs to the topic being read; chooses the topic on the fly
    /// for an unindexed bag.
    fn selected(&mut self, id: u32) -> Result<bool, String> {
        let Some(c) = self.conns.get(&id) else { return Ok(false) };
        if let Some(t) = &self.chosen {
            return Ok(c.topic == *t);
        }
        let take = match &self.wanted {
            Some(w) => c.topic == *w,
            None => c.msg_type == EVENT_ARRAY,
        };
        if !take {
            return Ok(false);
        }
        if c.msg_type != EVENT_ARRAY {
            return Err(format!("topic '{}' has type {}; evcal reads {EVENT_ARRAY}", c.topic, c.msg_type));
        }
        if self.wanted.is_none() {
            self.notes.push(format!(
                "{}: reading topic '{}', the first {EVENT_ARRAY} topic found",
                self.path.display(),
                c.topic
            ));
        }
        self.chosen = Some(c.topic.clone());
        Ok(true)
    }

    /// Loads the next message of the topic; `Ok(false)` at the end of the bag.
    fn next_message(&mut self) -> Result<bool, ReadError> {
        loop {
            if self.in_chunk {
                if self.chunk_next >= self.chunk.len() {
                    self.in_chunk = false;
                    continue;
                }
                let rec = self.chunk_next;
                let (h, d, next) = chunk_record(&self.chunk, rec).map_err(|m| self.err_in_chunk(rec, m))?;
                self.chunk_next = next;
                let f = Fields::parse(&self.chunk[h]).map_err(|m| self.err_in_chunk(rec, m))?;
                match f.op().map_err(|m| self.err_in_chunk(rec, m))? {
                    OP_CONNECTION => {
                        let (id, c) = connection(&f, &self.chunk[d]).map_err(|m| self.err_in_chunk(rec, m))?;
                        self.add_connection(id, c).map_err(|m| self.err_in_chunk(rec, m))?;
                    }
                    OP_MSG_DATA => {
                        let id = f.u32("conn").map_err(|m| self.err_in_chunk(rec, m))?;
                        if self.selected(id).map_err(|m| self.err_in_chunk(rec, m))? {
                            let (start, count, size) =
                                event_array(&self.chunk[d.clone()]).map_err(|m| self.err_in_chunk(rec, m))?;
                            self.start_message((self.chunk_at, Some(rec)), d.start + start, count, size);
                            return Ok(true);
                        }
                    }
                    op => return Err(self.err_in_chunk(rec, format!("unexpected record (op {op}) inside a chunk"))),
                }
                continue;
            }
            let at = self.pos;
            let Some((h, dlen)) = self.read_record(self.data_end, true)? else { return self.finish() };
            let f = Fields::parse(&h).map_err(|m| self.err(at, m))?;
            match f.op().map_err(|m| self.err(at, m))? {
                OP_CHUNK => {
                    let compression = f.string("compression").map_err(|m| self.err(at, m))?;
                    let size = u64::from(f.u32("size").map_err(|m| self.err(at, m))?);
                    if size > MAX_CHUNK {
                        return Err(self.err(at, format!("a chunk of {size} bytes is more than evcal reads at once")));
                    }
                    decompress(&compression, &self.raw, size, &mut self.chunk)
                        .map_err(|m| self.err(at, format!("chunk ({compression}, {dlen} bytes): {m}")))?;
                    self.chunk_at = at;
                    self.chunk_next = 0;
                    self.in_chunk = true;
                    self.chunks_read += 1;
                }
                OP_CONNECTION => {
                    let (id, c) = connection(&f, &self.raw).map_err(|m| self.err(at, m))?;
                    self.add_connection(id, c).map_err(|m| self.err(at, m))?;
                }
                OP_MSG_DATA => {
                    // Messages outside chunks: not written by rosbag, but valid records.
                    let id = f.u32("conn").map_err(|m| self.err(at, m))?;
                    if self.selected(id).map_err(|m| self.err(at, m))? {
                        let (start, count, size) = event_array(&self.raw).map_err(|m| self.err(at, m))?;
                        std::mem::swap(&mut self.chunk, &mut self.raw);
                        self.chunk_next = self.chunk.len();
                        self.start_message((at, None), start, count, size);
                        return Ok(true);
                    }
                }
                OP_INDEX_DATA | OP_CHUNK_INFO | OP_BAG_HEADER => {}
                op => return Err(self.err(at, format!("unknown record type (op {op})"))),
            }
        }
    }

    /// Records connection `id`; the index's copy and the data's must agree (one of them is
    /// corrupt otherwise, and the topic choice may rest on it).
    fn add_connection(&mut self, id: u32, c: BagTopic) -> Result<(), String> {
        match self.conns.get(&id) {
            Some(known) if *known != c => Err(format!(
                "connection {id} is {} ({}) here but {} ({}) in the index: the bag is corrupt",
                c.topic, c.msg_type, known.topic, known.msg_type
            )),
            Some(_) => Ok(()),
            None => {
                self.conns.insert(id, c);
                Ok(())
            }
        }
    }

    fn start_message(&mut self, at: (u64, Option<usize>), start: usize, count: usize, size: Option<SensorSize>) {
        self.msg_at = at;
        self.ev_start = start;
        self.ev_count = count;
        self.ev_next = 0;
        self.messages_read += 1;
        if self.sensor.is_none() {
            self.sensor = size;
        }
    }

    /// At the end of the data: checks the counts the index promised.
    fn finish(&mut self) -> Result<bool, ReadError> {
        if let Some((chunks, messages)) = self.expected {
            if chunks != self.chunks_read || messages != self.messages_read {
                return Err(self.err(
                    self.data_end,
                    format!(
                        "the index lists {chunks} chunks and {messages} messages on '{}', but the data holds {} and {}",
                        self.chosen.as_deref().unwrap_or(""),
                        self.chunks_read,
                        self.messages_read
                    ),
                ));
            }
        }
        Ok(false)
    }
}

impl EventSource for BagReader {
    fn next_event(&mut self) -> Option<Result<Event, ReadError>> {
        while self.ev_next >= self.ev_count {
            if self.done {
                return None;
            }
            match self.next_message() {
                Ok(true) => {}
                Ok(false) => {
                    self.done = true;
                    return None;
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
        // `event_array` checked that every event lies inside the message.
        let b = &self.chunk[o..o + EVENT_BYTES];
        let x = u16::from_le_bytes([b[0], b[1]]);
        let y = u16::from_le_bytes([b[2], b[3]]);
        let secs = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
        let nsecs = u32::from_le_bytes([b[8], b[9], b[10], b[11]]);
        let p = b[12];
        if p > 1 {
            self.done = true;
            let (at, rec) = self.msg_at;
            let where_ = rec.map(|r| format!("in the chunk's data at offset {r}: ")).unwrap_or_default();
            return Some(Err(self.err(at, format!("{where_}event {i} of the message: polarity byte {p} (0 or 1)"))));
        }
        let t_us = u64::from(secs) * 1_000_000 + (u64::from(nsecs) + 500) / 1000;
        Some(Ok(Event { t_us, x, y, polarity: p == 1 }))
    }

    fn progress_bytes(&self) -> u64 {
        self.pos
    }

    fn notes(&self) -> Vec<String> {
        self.notes.clone()
    }
}

/// Decompresses a chunk's data into `out`, which must come to `size` bytes.
fn decompress(compression: &str, raw: &[u8], size: u64, out: &mut Vec<u8>) -> Result<(), String> {
    let codec = match compression {
        "none" => Codec::None,
        "bz2" => Codec::Bz2,
        "lz4" => Codec::Lz4,
        other => return Err(format!("unknown compression '{other}' (known: none, bz2, lz4)")),
    };
    out.reserve(size as usize);
    codec::decompress(codec, raw, size, out)?;
    if out.len() as u64 != size {
        return Err(format!("the chunk header says {size} bytes uncompressed, its data gives {}", out.len()));
    }
    Ok(())
}

/// The topic to read among `topics` (all the bag's): `wanted`, else the only EventArray topic,
/// else `/dvs/events`.
fn choose_topic(topics: &[BagTopic], wanted: Option<&str>) -> Result<String, String> {
    let chosen = match wanted {
        Some(w) => topics.iter().find(|t| t.topic == w),
        None => {
            let ev: Vec<&BagTopic> = topics.iter().filter(|t| t.msg_type == EVENT_ARRAY).collect();
            match ev.as_slice() {
                [one] => Some(*one),
                _ => ev.into_iter().find(|t| t.topic == DEFAULT_TOPIC),
            }
        }
    };
    let c = chosen.ok_or_else(|| no_topic_message(topics, wanted))?;
    if c.msg_type != EVENT_ARRAY {
        return Err(format!(
            "topic '{}' has type {}; evcal reads {EVENT_ARRAY}; {}",
            c.topic,
            c.msg_type,
            list(topics)
        ));
    }
    Ok(c.topic.clone())
}

fn list(topics: &[BagTopic]) -> String {
    let l: Vec<String> = topics.iter().map(|t| format!("{} ({})", t.topic, t.msg_type)).collect();
    format!("the bag's topics: [{}]", l.join(", "))
}

fn no_topic_message(topics: &[BagTopic], wanted: Option<&str>) -> String {
    let n_ev = topics.iter().filter(|t| t.msg_type == EVENT_ARRAY).count();
    match wanted {
        Some(w) => format!("no topic '{w}' in the bag; {}", list(topics)),
        None if n_ev == 0 => format!("no {EVENT_ARRAY} topic in the bag; {}", list(topics)),
        None => format!(
            "several {EVENT_ARRAY} topics and none is {DEFAULT_TOPIC}: choose one with --topic; {}",
            list(topics)
        ),
    }
}

#[cfg(test)]
mod test {
    use super::*;

    fn t(topic: &str, ty: &str) -> BagTopic {
        BagTopic { topic: topic.into(), msg_type: ty.into() }
    }

    #[test]
    fn topic_choice() {
        let imu = t("/dvs/imu", "sensor_msgs/Imu");
        let a = t("/dvs/events", EVENT_ARRAY);
        let b = t("/right/events", EVENT_ARRAY);
        assert_eq!(choose_topic(&[imu.clone(), b.clone()], None).unwrap(), "/right/events");
        assert_eq!(choose_topic(&[imu.clone(), a.clone(), b.clone()], None).unwrap(), "/dvs/events");
        assert_eq!(choose_topic(&[a.clone(), b.clone()], Some("/right/events")).unwrap(), "/right/events");
        let e = choose_topic(&[imu.clone(), a.clone()], Some("/cam0/events")).unwrap_err();
        assert!(e.contains("no topic '/cam0/events'") && e.contains("/dvs/imu (sensor_msgs/Imu)"), "{e}");
        let e = choose_topic(&[imu.clone(), a.clone()], Some("/dvs/imu")).unwrap_err();
        assert!(e.contains("has type sensor_msgs/Imu"), "{e}");
        let e = choose_topic(std::slice::from_ref(&imu), None).unwrap_err();
        assert!(e.contains("no dvs_msgs/EventArray topic"), "{e}");
        let e = choose_topic(&[b.clone(), t("/left/events", EVENT_ARRAY)], None).unwrap_err();
        assert!(e.contains("--topic"), "{e}");
    }

    #[test]
    fn event_array_layout() {
        let mut m = Vec::new();
        m.extend(7u32.to_le_bytes()); // seq
        m.extend([0u8; 8]); // stamp
        m.extend(3u32.to_le_bytes());
        m.extend(b"cam");
        m.extend(260u32.to_le_bytes());
        m.extend(346u32.to_le_bytes());
        m.extend(2u32.to_le_bytes());
        m.extend([0u8; 26]);
        assert_eq!(event_array(&m).unwrap(), (31, 2, Some(SensorSize::DAVIS346)));
        let e = event_array(&m[..m.len() - 1]).unwrap_err();
        assert!(e.contains("2 events takes 57 bytes, the message has 56"), "{e}");
        assert!(event_array(&m[..20]).unwrap_err().contains("cut short"));
        m[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(event_array(&m).is_err());
    }

    #[test]
    fn header_fields() {
        let mut h = Vec::new();
        for f in [&b"op=\x05"[..], b"compression=lz4", b"size=\x10\x00\x00\x00"] {
            h.extend((f.len() as u32).to_le_bytes());
            h.extend(f);
        }
        let f = Fields::parse(&h).unwrap();
        assert_eq!(f.op(), Ok(OP_CHUNK));
        assert_eq!(f.string("compression").unwrap(), "lz4");
        assert_eq!(f.u32("size"), Ok(16));
        assert!(f.u64("size").is_err());
        assert!(Fields::parse(&h[..h.len() - 1]).is_err());
        assert!(Fields::parse(&[3, 0, 0, 0, b'a', b'b', b'c']).unwrap_err().contains("'='"));
    }
}
