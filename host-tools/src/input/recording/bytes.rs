//! Where a recording's bytes come from: a file, or a stream (a pipe, a FIFO, a device,
//! standard input as `-`).
//!
//! A stream cannot be rewound, so the format is chosen from bytes peeked into a buffer that
//! the reader then consumes first ([`Peeked`]): nothing read while guessing is lost. Formats
//! that need random access (HDF5, AEDAT4's data table, a bag's index) copy a stream to a
//! temporary file first; a second pass over a stream (guessing the sensor size before
//! detecting) reads a copy kept while the first pass read ([`Tee`]). Both cost disk, never
//! memory.

use super::ReadError;
use std::{
    cell::RefCell,
    fs::File,
    io::{Read, Seek, SeekFrom, Write},
    path::{Path, PathBuf},
    rc::Rc,
};

/// The name standard input is given in messages.
pub const STDIN_NAME: &str = "<stdin>";

/// An opened input: its name, its first bytes, and the rest.
pub(crate) struct Input {
    /// The name messages use (the path, or [`STDIN_NAME`]).
    pub name: PathBuf,
    /// The path to reopen, for a regular file.
    pub path: Option<PathBuf>,
    /// Bytes read so far, still to be consumed by the reader.
    pub head: Vec<u8>,
    /// Everything after `head`.
    pub rest: Box<dyn Read>,
    /// The size, for a regular file.
    pub len: Option<u64>,
}

impl Input {
    /// Opens `path`; `-` is standard input.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        if path.as_os_str() == "-" {
            return Ok(Self::stream(Path::new(STDIN_NAME), Box::new(std::io::stdin())));
        }
        let f = File::open(path).map_err(|e| ReadError::io(path, e))?;
        let meta = f.metadata().map_err(|e| ReadError::io(path, e))?;
        if meta.is_dir() {
            return Err(ReadError::new(path, super::Position::File, "is a directory, not a recording"));
        }
        if meta.is_file() {
            Ok(Self {
                name: path.to_path_buf(),
                path: Some(path.to_path_buf()),
                head: Vec::new(),
                rest: Box::new(f),
                len: Some(meta.len()),
            })
        } else {
            Ok(Self::stream(path, Box::new(f)))
        }
    }

    /// A stream named `name`.
    pub fn stream(name: &Path, r: Box<dyn Read>) -> Self {
        Self { name: name.to_path_buf(), path: None, head: Vec::new(), rest: r, len: None }
    }

    /// A regular file already open (a spooled copy), named `name` in messages.
    pub fn from_file(name: &Path, path: Option<PathBuf>, mut f: File) -> Result<Self, ReadError> {
        f.seek(SeekFrom::Start(0)).map_err(|e| ReadError::io(name, e))?;
        let len = f.metadata().map_err(|e| ReadError::io(name, e))?.len();
        Ok(Self { name: name.to_path_buf(), path, head: Vec::new(), rest: Box::new(f), len: Some(len) })
    }

    /// Reads until `head` holds at least `n` bytes or the input ends.
    pub fn peek(&mut self, n: usize) -> Result<&[u8], ReadError> {
        if self.head.len() < n {
            // Grown as bytes come: a short input costs its size, not `n`.
            let want = (n - self.head.len()) as u64;
            (&mut self.rest).take(want).read_to_end(&mut self.head).map_err(|e| ReadError::io(&self.name, e))?;
        }
        Ok(&self.head)
    }

    /// The head then the rest, as one reader.
    pub fn into_reader(self) -> Peeked {
        Peeked { head: self.head, at: 0, rest: self.rest }
    }

    /// Copies the whole input into a temporary file (for readers that need random access).
    pub fn spool(self) -> Result<tempfile::TempPath, ReadError> {
        let name = self.name.clone();
        let err = |e: std::io::Error| {
            ReadError::new(&name, super::Position::File, format!("cannot copy the stream to a temporary file: {e}"))
        };
        let mut tmp = tempfile::NamedTempFile::new().map_err(err)?;
        let mut r = self.into_reader();
        std::io::copy(&mut r, tmp.as_file_mut()).map_err(err)?;
        tmp.as_file_mut().flush().map_err(err)?;
        Ok(tmp.into_temp_path())
    }
}

/// The bytes peeked while choosing the format, then the rest of the input.
pub(crate) struct Peeked {
    head: Vec<u8>,
    at: usize,
    rest: Box<dyn Read>,
}

impl Peeked {
    /// Drops the first `n` bytes of the head (a header already parsed from it).
    pub fn skip_head(&mut self, n: usize) {
        self.at = (self.at + n).min(self.head.len());
    }
}

impl Read for Peeked {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.at < self.head.len() {
            let n = buf.len().min(self.head.len() - self.at);
            buf[..n].copy_from_slice(&self.head[self.at..self.at + n]);
            self.at += n;
            if self.at == self.head.len() {
                // The head can be a megabyte (a Prophesee header's limit): not kept once read.
                self.head = Vec::new();
                self.at = 0;
            }
            return Ok(n);
        }
        self.rest.read(buf)
    }
}

/// A stream read through, with a copy of every byte kept in an unlinked temporary file, so
/// that the recording can be read a second time.
pub(crate) struct Tee {
    inner: Box<dyn Read>,
    copy: File,
}

/// A shared handle on a [`Tee`]: the reader reads through it; the recording drains the
/// rest into the copy when asked to start again.
#[derive(Clone)]
pub(crate) struct TeeHandle(pub Rc<RefCell<Tee>>);

impl TeeHandle {
    /// Starts keeping a copy of `inner`, beginning with `head` (already read from it).
    pub fn new(head: &[u8], inner: Box<dyn Read>) -> std::io::Result<Self> {
        let mut copy = tempfile::tempfile()?;
        copy.write_all(head)?;
        Ok(Self(Rc::new(RefCell::new(Tee { inner, copy }))))
    }

    /// Reads the rest of the stream into the copy and returns the copy, from its start.
    pub fn finish(&self) -> std::io::Result<File> {
        let mut t = self.0.borrow_mut();
        let Tee { inner, copy } = &mut *t;
        std::io::copy(inner, copy)?;
        copy.flush()?;
        let mut f = copy.try_clone()?;
        f.seek(SeekFrom::Start(0))?;
        Ok(f)
    }
}

impl Read for TeeHandle {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut t = self.0.borrow_mut();
        let n = t.inner.read(buf)?;
        t.copy.write_all(&buf[..n])?;
        Ok(n)
    }
}

/// Reads until `buf` is full or the input ends; the count read.
pub(crate) fn read_up_to(r: &mut dyn Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Up to `max` bytes of `b` for a message: invisible characters escaped (a byte-order mark
/// shows as `\u{feff}`), bytes that are not UTF-8 as `\xNN`, `…` when cut.
pub fn quote(b: &[u8], max: usize) -> String {
    let cut = b.len() > max;
    let mut q = String::new();
    for chunk in b[..b.len().min(max)].utf8_chunks() {
        q.extend(chunk.valid().chars().flat_map(char::escape_debug));
        for byte in chunk.invalid() {
            q.push_str(&format!("\\x{byte:02x}"));
        }
    }
    if cut {
        q.push('…');
    }
    q
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn quotes_show_what_is_invisible() {
        assert_eq!(quote("\u{feff}0.1 2".as_bytes(), 40), "\\u{feff}0.1 2");
        assert_eq!(quote(b"\0\xff a", 40), "\\0\\xff a");
        assert_eq!(quote(&[b'a'; 100], 4), "aaaa…");
    }

    #[test]
    fn peeked_bytes_are_read_first() {
        let mut i = Input::stream(Path::new("s"), Box::new(&b"0123456789"[..]));
        assert_eq!(i.peek(4).unwrap(), b"0123");
        assert_eq!(i.peek(2).unwrap(), b"0123", "peeking less keeps what was read");
        let mut all = Vec::new();
        i.into_reader().read_to_end(&mut all).unwrap();
        assert_eq!(all, b"0123456789");
    }
}
