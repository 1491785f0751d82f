//! Where a recording's bytes come from: a file, or a stream (a pipe, a FIFO, a device,
//! standard input as `-`).
//!
//! A stream cannot be rewound, so the format is chosen from bytes peeked into a buffer that
//! the reader then consumes first ([`Peeked`]): nothing read while guessing is lost. Formats
//! that need random access (HDF5, AEDAT4's data table, a bag's index) copy a stream to a
//! temporary file first; a second pass over a stream (guessing the sensor size before
//! detecting) reads a copy kept while the first pass read ([`Tee`]). Both cost disk, never
//! memory: the first up to [`SPOOL_MAX_BYTES`], in a file that [`remove_spools`] removes
//! when the process is interrupted; the second in a file without a name, gone with the
//! process.

use super::types::{Position, ReadError};
use std::{
    cell::RefCell,
    fs::File,
    io::{Read, Seek, SeekFrom, Write},
    path::{Path, PathBuf},
    rc::Rc,
    sync::Mutex,
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
            return Err(ReadError::new(path, Position::File, "is a directory, not a recording"));
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

    /// Copies the whole input into a temporary file (for readers that need random access),
    /// up to [`SPOOL_MAX_BYTES`].
    pub fn spool(self) -> Result<Spool, ReadError> {
        self.spool_up_to(SPOOL_MAX_BYTES)
    }

    /// [`Input::spool`] with a cap of `max` bytes.
    fn spool_up_to(self, max: u64) -> Result<Spool, ReadError> {
        let name = self.name.clone();
        let err = |e: std::io::Error| {
            ReadError::new(&name, Position::File, format!("cannot copy the stream to a temporary file: {e}"))
        };
        let (mut file, spool) = Spool::new().map_err(err)?;
        let mut r = self.into_reader().take(max.saturating_add(1));
        let copied = std::io::copy(&mut r, &mut file).map_err(err)?;
        if copied > max {
            return Err(ReadError::new(
                &name,
                Position::File,
                format!(
                    "a stream in a format that needs random access is copied to a temporary file first, up to {} MiB, and this one is longer: give the file's path instead of a pipe",
                    max >> 20
                ),
            ));
        }
        file.flush().map_err(err)?;
        Ok(spool)
    }
}

/// The most bytes of a stream copied to a temporary file (`Input::spool`): 4 GiB. A
/// temporary folder is often in memory (tmpfs, half the RAM); a file larger than this is
/// read from its path, where it is already on disk.
pub const SPOOL_MAX_BYTES: u64 = 4 << 30;

/// The spools on disk, for [`remove_spools`]; a spool is created and removed under the lock,
/// so that none is made between their removal and the process's end.
static SPOOLS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary copy of a stream, removed when dropped (or by [`remove_spools`]).
pub struct Spool(Option<tempfile::TempPath>);

impl Spool {
    /// A new empty spool in the temporary folder, registered, and its file to write to.
    fn new() -> std::io::Result<(File, Self)> {
        let mut spools = SPOOLS.lock().unwrap_or_else(|p| p.into_inner());
        let (file, path) = tempfile::NamedTempFile::new()?.into_parts();
        spools.push(path.to_path_buf());
        Ok((file, Self(Some(path))))
    }
}

impl std::ops::Deref for Spool {
    type Target = Path;

    fn deref(&self) -> &Path {
        self.0.as_deref().unwrap_or(Path::new(""))
    }
}

impl AsRef<Path> for Spool {
    fn as_ref(&self) -> &Path {
        self
    }
}

impl Drop for Spool {
    fn drop(&mut self) {
        let mut spools = SPOOLS.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(path) = self.0.take() {
            spools.retain(|p| p.as_path() != &*path);
            // Removes the file, under the lock.
            drop(path);
        }
    }
}

/// Removes every temporary copy of a stream still on disk, and keeps any more from being
/// made: for a process about to end on Ctrl-C or SIGTERM, where no destructor runs. Waits
/// for a spool being created or removed.
pub fn remove_spools() {
    let spools = SPOOLS.lock().unwrap_or_else(|p| p.into_inner());
    for p in spools.iter() {
        let _ = std::fs::remove_file(p);
    }
    // The lock is held until the process ends: no spool is made after this.
    std::mem::forget(spools);
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
    fn spools_are_capped_and_removed() {
        let data = vec![7u8; 3000];
        let i = Input::stream(Path::new("<stdin>"), Box::new(std::io::Cursor::new(data.clone())));
        let spool = i.spool_up_to(3000).unwrap();
        assert_eq!(std::fs::read(&*spool).unwrap(), data);
        let path = spool.to_path_buf();
        assert!(SPOOLS.lock().unwrap().contains(&path));
        drop(spool);
        assert!(!path.exists() && !SPOOLS.lock().unwrap().contains(&path));
        let i = Input::stream(Path::new("<stdin>"), Box::new(std::io::Cursor::new(data)));
        let e = i.spool_up_to(2999).err().unwrap().to_string();
        assert!(e.starts_with("<stdin>: ") && e.contains("give the file's path"), "{e}");
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
