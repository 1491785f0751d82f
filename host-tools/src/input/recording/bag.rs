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
//! The reader streams chunk by chunk, each decompressed as its records are read
//! ([`super::bagrecords`]): memory does not grow with a chunk's size. From the index section it learns the topics before
//! reading (to pick one, or list them in the error) and how many chunks and messages to
//! expect: reading fewer is an error, never a silent loss. An unindexed bag is read to its
//! end, the topic chosen when its connection first appears.
//!
//! `dvs_msgs/EventArray`: `std_msgs/Header` (`u32` seq, `u32` secs, `u32` nsecs, string
//! frame_id), `u32` height, `u32` width, `Event[]` (`u32` count, then 13 bytes each: `u16` x,
//! `u16` y, `u32` secs, `u32` nsecs, `u8` polarity). Times become µs rounded to nearest.

pub use super::bagrecords::BagTopic;
use super::{
    bagrecords::{connection, ChunkStream, EventArrayHead, Fields, MAX_HELD},
    codec::Codec,
    types::{EventSource, Position, ReadError},
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

const OP_MSG_DATA: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_INDEX_DATA: u8 = 0x04;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

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
    /// The data of the top-level record just read, when kept (connections, chunk infos).
    raw: Vec<u8>,
    /// The chunk being read, decompressed as it is read (or the data of a message outside
    /// chunks), and the file offset of its record.
    stream: Option<ChunkStream>,
    chunk_at: u64,
    in_chunk: bool,
    /// The message being read: where its record starts in the chunk (or in the file, for a
    /// message outside chunks), its event count, the next one.
    msg_at: (u64, Option<u64>),
    ev_count: u64,
    ev_next: u64,
    sensor: Option<SensorSize>,
    notes: Vec<String>,
    chunks_read: u64,
    messages_read: u64,
    done: bool,
}

/// Reads an EventArray message held whole in `msg` (a test's).
#[cfg(test)]
fn event_array(msg: &[u8]) -> Result<EventArrayHead, String> {
    let n = msg.len() as u64;
    ChunkStream::new(Codec::None, std::io::Cursor::new(msg.to_vec()), n)?.event_array(n)
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
            raw: Vec::new(),
            stream: None,
            chunk_at: 0,
            in_chunk: false,
            msg_at: (0, None),
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

    fn err_in_chunk(&self, rec: u64, m: impl std::fmt::Display) -> ReadError {
        self.err(self.chunk_at, format!("in the chunk's uncompressed data at offset {rec}: {m}"))
    }

    /// Reads the top-level record at `self.pos` (which must end by `end`): its header, and its
    /// data into `self.raw` if `keep_data`, else skipped. `None` at `end`.
    fn read_record(&mut self, end: u64, keep_data: bool) -> Result<Option<(Vec<u8>, u64)>, ReadError> {
        let at = self.pos;
        let Some((header, dlen)) = self.read_record_head(end)? else { return Ok(None) };
        self.record_data(at, dlen, keep_data)?;
        Ok(Some((header, dlen)))
    }

    /// Reads the header of the top-level record at `self.pos` (which must end by `end`), and
    /// the length of its data; the file is left at the data, `self.pos` past it. `None` at
    /// `end`.
    fn read_record_head(&mut self, end: u64) -> Result<Option<(Vec<u8>, u64)>, ReadError> {
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
        if hlen > MAX_HELD {
            return Err(
                self.err(at, format!("corrupt record: a header of {hlen} bytes (evcal reads at most {MAX_HELD})"))
            );
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
        self.pos = at + 8 + u64::from(hlen) + dlen;
        Ok(Some((header, dlen)))
    }

    /// The data of the record at `at`, `dlen` bytes, at which the file stands: into `self.raw`
    /// if `keep_data`, else passed over.
    fn record_data(&mut self, at: u64, dlen: u64, keep_data: bool) -> Result<(), ReadError> {
        if keep_data {
            if dlen > u64::from(MAX_HELD) {
                return Err(self.err(
                    at,
                    format!("a record of {dlen} bytes outside chunks (evcal holds at most {MAX_HELD}): corrupt"),
                ));
            }
            self.raw.resize(dlen as usize, 0);
            let mut raw = std::mem::take(&mut self.raw);
            let r = self.file.read_exact(&mut raw);
            self.raw = raw;
            r.map_err(|e| self.err(at, e.to_string()))?;
        } else {
            self.file.seek_relative(dlen as i64).map_err(|e| self.err(at, e.to_string()))?;
        }
        Ok(())
    }

    /// The data of the record at `at`, which ends at `self.pos`, `dlen` bytes compressed by
    /// `codec` that come to `size`, read from a handle of its own as it is decompressed; the
    /// file is moved past it.
    fn data_stream(&mut self, at: u64, dlen: u64, codec: Codec, size: u64) -> Result<ChunkStream, ReadError> {
        let data_at = self.pos - dlen;
        let mut f = File::open(&self.path).map_err(|e| self.err(at, e.to_string()))?;
        f.seek(SeekFrom::Start(data_at)).map_err(|e| self.err(at, e.to_string()))?;
        self.file.seek_relative(dlen as i64).map_err(|e| self.err(at, e.to_string()))?;
        ChunkStream::new(codec, BufReader::with_capacity(1 << 16, f).take(dlen), size).map_err(|m| self.err(at, m))
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
                // Taken while its record is read (errors borrow `self`), put back unless it ended.
                let Some(mut stream) = self.stream.take() else {
                    self.in_chunk = false;
                    continue;
                };
                match self.chunk_record(&mut stream) {
                    Ok(Some(message)) => {
                        self.stream = Some(stream);
                        if message {
                            return Ok(true);
                        }
                    }
                    Ok(None) => self.in_chunk = false,
                    Err(e) => return Err(e),
                }
                continue;
            }
            let at = self.pos;
            let Some((h, dlen)) = self.read_record_head(self.data_end)? else { return self.finish() };
            let f = Fields::parse(&h).map_err(|m| self.err(at, m))?;
            match f.op().map_err(|m| self.err(at, m))? {
                OP_CHUNK => {
                    let compression = f.string("compression").map_err(|m| self.err(at, m))?;
                    let size = u64::from(f.u32("size").map_err(|m| self.err(at, m))?);
                    let codec = match compression.as_str() {
                        "none" => Codec::None,
                        "bz2" => Codec::Bz2,
                        "lz4" => Codec::Lz4,
                        other => {
                            return Err(self.err(
                                at,
                                format!(
                                    "chunk: unknown compression '{}' (known: none, bz2, lz4)",
                                    super::bytes::quote(other.as_bytes(), 40)
                                ),
                            ))
                        }
                    };
                    self.stream = Some(self.data_stream(at, dlen, codec, size)?);
                    self.chunk_at = at;
                    self.in_chunk = true;
                    self.chunks_read += 1;
                }
                OP_CONNECTION => {
                    self.record_data(at, dlen, true)?;
                    let (id, c) = connection(&f, &self.raw).map_err(|m| self.err(at, m))?;
                    self.add_connection(id, c).map_err(|m| self.err(at, m))?;
                }
                OP_MSG_DATA => {
                    // Messages outside chunks: not written by rosbag, but valid records.
                    let id = f.u32("conn").map_err(|m| self.err(at, m))?;
                    if !self.selected(id).map_err(|m| self.err(at, m))? {
                        self.record_data(at, dlen, false)?;
                        continue;
                    }
                    let mut stream = self.data_stream(at, dlen, Codec::None, dlen)?;
                    let head = stream.event_array(dlen).map_err(|m| self.err(at, m))?;
                    self.stream = Some(stream);
                    self.start_message((at, None), head).map_err(|m| self.err(at, m))?;
                    return Ok(true);
                }
                OP_INDEX_DATA | OP_CHUNK_INFO | OP_BAG_HEADER => self.record_data(at, dlen, false)?,
                op => return Err(self.err(at, format!("unknown record type (op {op})"))),
            }
        }
    }

    /// Reads the next record of the chunk `stream`: `Some(true)` if it is a message of the
    /// topic (its events next in the stream), `Some(false)` for another record, `None` at the
    /// end of the chunk.
    fn chunk_record(&mut self, stream: &mut ChunkStream) -> Result<Option<bool>, ReadError> {
        let Some(rec) = stream.next_record().map_err(|m| self.err_in_chunk(stream.position(), m))? else {
            return Ok(None);
        };
        let at = rec.at;
        let f = Fields::parse(&rec.header).map_err(|m| self.err_in_chunk(at, m))?;
        match f.op().map_err(|m| self.err_in_chunk(at, m))? {
            OP_CONNECTION => {
                let data = stream.held_data(rec.dlen).map_err(|m| self.err_in_chunk(at, m))?;
                let (id, c) = connection(&f, &data).map_err(|m| self.err_in_chunk(at, m))?;
                self.add_connection(id, c).map_err(|m| self.err_in_chunk(at, m))?;
                Ok(Some(false))
            }
            OP_MSG_DATA => {
                let id = f.u32("conn").map_err(|m| self.err_in_chunk(at, m))?;
                if !self.selected(id).map_err(|m| self.err_in_chunk(at, m))? {
                    stream.skip(rec.dlen).map_err(|m| self.err_in_chunk(at, m))?;
                    return Ok(Some(false));
                }
                let head = stream.event_array(rec.dlen).map_err(|m| self.err_in_chunk(at, m))?;
                self.start_message((self.chunk_at, Some(at)), head).map_err(|m| self.err_in_chunk(at, m))?;
                Ok(Some(true))
            }
            op => Err(self.err_in_chunk(at, format!("unexpected record (op {op}) inside a chunk"))),
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

    /// Starts reading the events of a message; the first gives the sensor size.
    fn start_message(&mut self, at: (u64, Option<u64>), head: EventArrayHead) -> Result<(), String> {
        if self.messages_read == 0 {
            self.sensor = head.sensor().map_err(|m| format!("the first {EVENT_ARRAY} message {m}"))?;
        }
        self.msg_at = at;
        self.ev_count = head.count;
        self.ev_next = 0;
        self.messages_read += 1;
        Ok(())
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
        let (at, rec) = self.msg_at;
        let where_ = rec.map(|r| format!("in the chunk's uncompressed data at offset {r}: ")).unwrap_or_default();
        // `event_array` checked that every event lies inside the message.
        let b = match self.stream.as_mut().map(ChunkStream::event) {
            Some(Ok(b)) => b,
            got => {
                self.done = true;
                let m = got.and_then(Result::err).unwrap_or_else(|| "no data".into());
                return Some(Err(self.err(at, format!("{where_}event {i} of the message: {m}"))));
            }
        };
        let x = u16::from_le_bytes([b[0], b[1]]);
        let y = u16::from_le_bytes([b[2], b[3]]);
        let secs = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
        let nsecs = u32::from_le_bytes([b[8], b[9], b[10], b[11]]);
        let p = b[12];
        if p > 1 {
            self.done = true;
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
        let head = event_array(&m).unwrap();
        assert_eq!((head.count, head.sensor()), (2, Ok(Some(SensorSize::DAVIS346))));
        let e = event_array(&m[..m.len() - 1]).unwrap_err();
        assert!(e.contains("2 events takes 57 bytes, the message has 56"), "{e}");
        assert!(event_array(&m[..20]).unwrap_err().contains("cut short"));
        m[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(event_array(&m).is_err());
    }
}
