//! Writing outputs without clobbering anything (issue 46). Each output is checked before any
//! work: not a symbolic link, not a folder, not one of the command's inputs. Then it is written
//! to a temporary file in its own folder, flushed to disk and renamed over the target.
//!
//! The rename is what makes a write safe: an interrupted or failed write leaves the target as
//! it was (never a torn file), and a link planted at the target's name meanwhile is replaced
//! rather than followed (in a shared folder such a link would have a root run overwrite
//! whatever it points to). Pipes and character devices (`/dev/null`, a FIFO) hold nothing to
//! protect and cannot be renamed over: they are written in place.
//!
//! ```no_run
//! use evcal_host::export::atomic::{check_output, AtomicFile};
//! use std::{io::Write, path::Path};
//! # fn run() -> Result<(), Box<dyn std::error::Error>> {
//! let (input, out) = (Path::new("rec.txt"), Path::new("detections.jsonl"));
//! check_output(out, "--out", &[("the recording", input)])?; // before any work
//! let mut f = AtomicFile::create(out)?;
//! writeln!(f, "{{\"seq\": 0}}")?;
//! f.commit()?; // detections.jsonl appears whole, or not at all
//! # Ok(()) }
//! ```

use std::{
    fs::{self, File},
    io::{self, Write},
    path::{Path, PathBuf},
    sync::{Mutex, MutexGuard},
};

/// Why an output was refused or could not be written. Each error names the file.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output is a symbolic link.
    #[error("{what} {}: is a symbolic link{}; evcal does not write through links (one planted in a shared folder would have it overwrite what it points to): remove the link or give another name", path.display(), to.as_ref().map(|t| format!(" to {}", t.display())).unwrap_or_default())]
    Symlink {
        /// The option or role of the output (`--out`).
        what: String,
        /// The output.
        path: PathBuf,
        /// Where the link points.
        to: Option<PathBuf>,
    },
    /// The output is a folder.
    #[error("{what} {}: is a directory; give a file name", path.display())]
    Directory {
        /// The option or role of the output.
        what: String,
        /// The output.
        path: PathBuf,
    },
    /// The output is something that is neither a file, a pipe nor a character device.
    #[error("{what} {}: is a {kind}, not a file; give a file name", path.display())]
    Special {
        /// The option or role of the output.
        what: String,
        /// The output.
        path: PathBuf,
        /// What it is.
        kind: &'static str,
    },
    /// The output's folder does not exist.
    #[error("{what} {}: the folder {} does not exist", path.display(), folder.display())]
    NoFolder {
        /// The option or role of the output.
        what: String,
        /// The output.
        path: PathBuf,
        /// Its folder.
        folder: PathBuf,
    },
    /// The output is the same file as an input, or as another output of the same command.
    #[error("{what} {}: is the same file as {other} {}, which writing it would destroy; give another name", path.display(), other_path.display())]
    SameFile {
        /// The option or role of the output.
        what: String,
        /// The output.
        path: PathBuf,
        /// What the other file is (`the recording`, `--json`).
        other: String,
        /// The other file as the user named it.
        other_path: PathBuf,
    },
    /// A file could not be looked at, written or renamed.
    #[error("{}: {what}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What could not be done.
        what: &'static str,
        /// The system's error.
        #[source]
        source: io::Error,
    },
}

fn io_at(path: &Path, what: &'static str) -> impl FnOnce(io::Error) -> OutputError {
    let path = path.to_path_buf();
    move |source| OutputError::Io { path, what, source }
}

/// The folder `path` lies in (`.` for a bare name).
pub fn folder_of(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// Whether a file of type `t` (not followed) is written in place: a pipe or a character device.
fn in_place(t: &fs::FileType) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        t.is_fifo() || t.is_char_device()
    }
    #[cfg(not(unix))]
    {
        let _ = t;
        false
    }
}

/// What a file of type `t` is, for an error, when it is neither a file, a folder, a link nor
/// something written in place.
fn kind(t: &fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_block_device() {
            return "block device";
        }
        if t.is_socket() {
            return "socket";
        }
    }
    let _ = t;
    "special file"
}

/// Checks before any work that `path` may be written as the output `what` (`--out`): not a
/// symbolic link (never followed), not a folder, its folder exists, and it is not the same
/// file as any of `inputs` (each a description and a path, `-` for standard input): the same
/// device and inode, so that `./x` for `x`, a hard link or a link to the input are caught.
/// `-` (standard output) always may.
pub fn check_output(path: &Path, what: &str, inputs: &[(&str, &Path)]) -> Result<(), OutputError> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    let what = what.to_string();
    match fs::symlink_metadata(path) {
        Ok(m) => {
            let t = m.file_type();
            if t.is_symlink() {
                return Err(OutputError::Symlink { what, path: path.into(), to: fs::read_link(path).ok() });
            }
            if t.is_dir() {
                return Err(OutputError::Directory { what, path: path.into() });
            }
            if in_place(&t) {
                // Nothing in it to destroy, nor an input to be (a pipe is read once).
                return Ok(());
            }
            if !t.is_file() {
                return Err(OutputError::Special { what, path: path.into(), kind: kind(&t) });
            }
            for &(other, input) in inputs {
                if input_is(input, &m) {
                    let other_path =
                        if input.as_os_str() == "-" { PathBuf::from("- (standard input)") } else { input.into() };
                    return Err(OutputError::SameFile {
                        what,
                        path: path.into(),
                        other: other.to_string(),
                        other_path,
                    });
                }
            }
            Ok(())
        }
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            // A file that does not exist yet is no input.
            let folder = folder_of(path);
            if folder.is_dir() {
                Ok(())
            } else {
                Err(OutputError::NoFolder { what, path: path.into(), folder: folder.into() })
            }
        }
        Err(e) => Err(io_at(path, "cannot look at it")(e)),
    }
}

/// Whether the input `input` (`-`: standard input) is the regular file `out` describes.
fn input_is(input: &Path, out: &fs::Metadata) -> bool {
    let m = if input.as_os_str() == "-" { stdin_metadata() } else { fs::metadata(input).ok() };
    m.is_some_and(|m| m.is_file() && same_identity(&m, out, input))
}

/// What standard input is, when it can be told (a file redirected with `<`).
fn stdin_metadata() -> Option<fs::Metadata> {
    #[cfg(unix)]
    {
        use std::os::fd::AsFd;
        let fd = io::stdin().as_fd().try_clone_to_owned().ok()?;
        File::from(fd).metadata().ok()
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// Whether `a` and `b` are one file. `path_a` serves where the system has no inode numbers.
fn same_identity(a: &fs::Metadata, b: &fs::Metadata, path_a: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        let _ = path_a;
        (a.dev(), a.ino()) == (b.dev(), b.ino())
    }
    #[cfg(not(unix))]
    {
        // Without inode numbers only the metadata can be compared; `same_file` by path does
        // better where both paths are known.
        let _ = path_a;
        a.len() == b.len() && a.modified().ok() == b.modified().ok() && a.created().ok() == b.created().ok()
    }
}

/// Whether two outputs of one command name the same file, existing or not: the same device
/// and inode when both exist, else the same folder (canonical) and name.
pub fn same_file(a: &Path, b: &Path) -> bool {
    if let (Ok(x), Ok(y)) = (fs::metadata(a), fs::metadata(b)) {
        #[cfg(unix)]
        return same_identity(&x, &y, a);
        #[cfg(not(unix))]
        {
            let _ = (x, y);
            return fs::canonicalize(a).ok() == fs::canonicalize(b).ok();
        }
    }
    match (full_name(a), full_name(b)) {
        (Some(x), Some(y)) => x == y,
        _ => false,
    }
}

/// `path` as its folder's canonical path and its name; the folder as written (made absolute)
/// when it does not exist yet.
fn full_name(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?;
    let folder = folder_of(path);
    let folder = fs::canonicalize(folder).or_else(|_| std::path::absolute(folder)).ok()?;
    Some(folder.join(name))
}

/// The temporary files being written, so that an interrupted command can remove them
/// ([`remove_unfinished`]); `closed` once it has.
struct Unfinished {
    paths: Vec<PathBuf>,
    closed: bool,
}

static UNFINISHED: Mutex<Unfinished> = Mutex::new(Unfinished { paths: Vec::new(), closed: false });

fn unfinished() -> MutexGuard<'static, Unfinished> {
    // A panic elsewhere while the list was held leaves it usable.
    UNFINISHED.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Removes every temporary file still being written and refuses new ones: for a Ctrl-C
/// handler to call before ending the process, so that an interruption leaves each target as
/// it was and no temporary file behind. Returns how many it removed.
pub fn remove_unfinished() -> usize {
    let mut u = unfinished();
    u.closed = true;
    let n = u.paths.len();
    for p in u.paths.drain(..) {
        let _ = fs::remove_file(p);
    }
    n
}

/// An output being written: into a temporary file beside the target, renamed over it by
/// [`AtomicFile::commit`]; dropped uncommitted, the temporary file is removed and the target
/// left as it was. A pipe or character device is written in place.
pub struct AtomicFile {
    inner: Option<Inner>,
    target: PathBuf,
}

enum Inner {
    Staged(tempfile::NamedTempFile),
    InPlace(File),
}

/// The end of a temporary file's name: `.NAME.XXXXXX.evcal-tmp`, hidden, and plainly
/// evcal's to whoever finds one left by a killed run.
pub const TEMP_SUFFIX: &str = ".evcal-tmp";

impl AtomicFile {
    /// Starts writing `target`. Checks nothing of [`check_output`]'s: that is for before
    /// the work; a link at `target` now is replaced at the commit, not followed.
    pub fn create(target: &Path) -> Result<Self, OutputError> {
        if let Ok(m) = fs::symlink_metadata(target) {
            if m.is_dir() {
                // Said now: found at the rename, files staged with it would be half put in place.
                let e = io::Error::new(io::ErrorKind::IsADirectory, "is a directory");
                return Err(io_at(target, "cannot write")(e));
            }
            if in_place(&m.file_type()) {
                let f = fs::OpenOptions::new().write(true).open(target).map_err(io_at(target, "cannot open"))?;
                return Ok(Self { inner: Some(Inner::InPlace(f)), target: target.into() });
            }
        }
        let Some(name) = target.file_name() else {
            let e = io::Error::new(io::ErrorKind::InvalidInput, "not a file name");
            return Err(io_at(target, "cannot write")(e));
        };
        let prefix = format!(".{}.", name.to_string_lossy());
        let mut b = tempfile::Builder::new();
        b.prefix(&prefix).suffix(TEMP_SUFFIX);
        #[cfg(unix)]
        {
            // As `File::create` makes files: the umask applies (tempfile's own 0600 would
            // leave a calibration unreadable to the user's other accounts and services).
            use std::os::unix::fs::PermissionsExt;
            b.permissions(fs::Permissions::from_mode(0o666));
        }
        let mut u = unfinished();
        if u.closed {
            let e = io::Error::new(io::ErrorKind::Interrupted, "interrupted");
            return Err(io_at(target, "cannot write")(e));
        }
        let tmp = b
            .tempfile_in(folder_of(target))
            .map_err(io_at(target, "cannot create a temporary file in its folder to write it"))?;
        u.paths.push(tmp.path().to_path_buf());
        Ok(Self { inner: Some(Inner::Staged(tmp)), target: target.into() })
    }

    /// Where the bytes go until the commit: the temporary file (or the target itself, for a
    /// pipe or device). For writers that open files by name (the HDF5 library).
    pub fn path(&self) -> &Path {
        match &self.inner {
            Some(Inner::Staged(t)) => t.path(),
            _ => &self.target,
        }
    }

    /// The output.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Flushes the bytes to disk and renames the temporary file over the target (replacing a
    /// link there, never following it). An existing target's permissions are kept.
    pub fn commit(mut self) -> Result<(), OutputError> {
        let target = self.target.clone();
        let cannot_write = io_at(&target, "cannot write");
        match self.inner.take() {
            None => Ok(()),
            Some(Inner::InPlace(mut f)) => f.flush().map_err(cannot_write),
            Some(Inner::Staged(mut tmp)) => {
                tmp.as_file_mut().flush().map_err(io_at(&target, "cannot write"))?;
                if let Ok(m) = fs::symlink_metadata(&target) {
                    if m.is_file() {
                        // Best effort: a file of another owner's cannot always take them.
                        let _ = tmp.as_file().set_permissions(m.permissions());
                    }
                }
                tmp.as_file().sync_all().map_err(cannot_write)?;
                let temp = tmp.path().to_path_buf();
                // Held through the rename: an interruption now waits for it, and then finds
                // nothing of this file's to remove.
                let mut u = unfinished();
                u.paths.retain(|p| *p != temp);
                if u.closed {
                    drop(tmp);
                    let e = io::Error::new(io::ErrorKind::Interrupted, "interrupted");
                    return Err(io_at(&target, "not written")(e));
                }
                // On failure the temporary file comes back inside the error and goes with it.
                tmp.persist(&target).map_err(|e| io_at(&target, "cannot put the written file in place")(e.error))?;
                drop(u);
                sync_folder(folder_of(&target));
                Ok(())
            }
        }
    }
}

/// Makes a rename in `folder` durable (a crash after it keeps the new file); best effort.
fn sync_folder(folder: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(folder) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = folder;
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match &mut self.inner {
            Some(Inner::Staged(t)) => t.write(buf),
            Some(Inner::InPlace(f)) => f.write(buf),
            None => Err(io::Error::other("already committed")),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match &mut self.inner {
            Some(Inner::Staged(t)) => t.flush(),
            Some(Inner::InPlace(f)) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(Inner::Staged(t)) = &self.inner {
            let temp = t.path().to_path_buf();
            unfinished().paths.retain(|p| *p != temp);
        }
        // The NamedTempFile removes its file as it drops.
    }
}

/// Writes `bytes` to `path` through a temporary file renamed over it.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes).map_err(io_at(path, "cannot write"))?;
    f.commit()
}

#[cfg(test)]
mod test {
    use super::*;

    /// The names in `dir`, sorted.
    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn a_commit_renames_the_temporary_file_and_leaves_none() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.txt");
        fs::write(&out, "old").unwrap();
        let mut f = AtomicFile::create(&out).unwrap();
        let temp = f.path().to_path_buf();
        assert_eq!(temp.parent(), Some(dir.path()), "in the target's own folder");
        assert!(temp.file_name().unwrap().to_string_lossy().ends_with(TEMP_SUFFIX));
        f.write_all(b"new").unwrap();
        // Until the commit the target is as it was.
        assert_eq!(fs::read(&out).unwrap(), b"old");
        f.commit().unwrap();
        assert_eq!(fs::read(&out).unwrap(), b"new");
        assert!(!temp.exists());
        assert_eq!(names(dir.path()), ["out.txt"]);
        assert!(unfinished().paths.iter().all(|p| *p != temp));
    }

    #[test]
    fn an_abandoned_or_failed_write_leaves_the_target_and_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.txt");
        fs::write(&out, "old").unwrap();
        let mut f = AtomicFile::create(&out).unwrap();
        f.write_all(b"half").unwrap();
        drop(f);
        assert_eq!(fs::read(&out).unwrap(), b"old");
        assert_eq!(names(dir.path()), ["out.txt"]);
        // The rename fails: the target became a folder meanwhile.
        let blocked = dir.path().join("blocked");
        let mut f = AtomicFile::create(&blocked).unwrap();
        f.write_all(b"x").unwrap();
        fs::create_dir(&blocked).unwrap();
        fs::write(blocked.join("inside"), "keep").unwrap();
        let e = f.commit().unwrap_err().to_string();
        assert!(e.contains("blocked"), "{e}");
        assert_eq!(names(dir.path()), ["blocked", "out.txt"]);
        assert_eq!(fs::read(blocked.join("inside")).unwrap(), b"keep");
        // write_file into a folder that does not exist: an error naming it, nothing made.
        let e = write_file(&dir.path().join("none/x"), b"x").unwrap_err().to_string();
        assert!(e.contains("none"), "{e}");
        assert_eq!(names(dir.path()), ["blocked", "out.txt"]);
    }

    #[cfg(unix)]
    #[test]
    fn a_link_planted_meanwhile_is_replaced_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        fs::write(&victim, "precious").unwrap();
        let out = dir.path().join("calibration.json");
        let mut f = AtomicFile::create(&out).unwrap();
        f.write_all(b"{}").unwrap();
        std::os::unix::fs::symlink(&victim, &out).unwrap();
        f.commit().unwrap();
        assert_eq!(fs::read(&victim).unwrap(), b"precious");
        assert!(!fs::symlink_metadata(&out).unwrap().file_type().is_symlink());
        assert_eq!(fs::read(&out).unwrap(), b"{}");
    }

    #[cfg(unix)]
    #[test]
    fn permissions_are_those_of_a_created_file_or_kept() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        // What File::create gives under this process's umask.
        let plain = dir.path().join("plain");
        File::create(&plain).unwrap();
        let want = fs::metadata(&plain).unwrap().permissions().mode() & 0o777;
        let new = dir.path().join("new");
        write_file(&new, b"x").unwrap();
        assert_eq!(fs::metadata(&new).unwrap().permissions().mode() & 0o777, want);
        fs::set_permissions(&new, fs::Permissions::from_mode(0o640)).unwrap();
        write_file(&new, b"y").unwrap();
        assert_eq!(fs::metadata(&new).unwrap().permissions().mode() & 0o777, 0o640);
    }

    #[cfg(unix)]
    #[test]
    fn outputs_that_are_links_folders_or_inputs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let rec = dir.path().join("rec.txt");
        fs::write(&rec, "346 260\n").unwrap();
        let inputs = [("the recording", rec.as_path())];
        // The input under another spelling, and a hard link to it.
        let dotted = dir.path().join(".").join("rec.txt");
        let e = check_output(&dotted, "--out", &inputs).unwrap_err().to_string();
        assert!(e.contains("--out") && e.contains("same file as the recording") && e.contains("rec.txt"), "{e}");
        let hard = dir.path().join("hard.txt");
        fs::hard_link(&rec, &hard).unwrap();
        assert!(matches!(check_output(&hard, "--out", &inputs), Err(OutputError::SameFile { .. })));
        // A link, wherever it points (here to nothing), is refused before anything is written.
        let link = dir.path().join("link.txt");
        std::os::unix::fs::symlink(dir.path().join("elsewhere"), &link).unwrap();
        let e = check_output(&link, "--out", &[]).unwrap_err().to_string();
        assert!(e.contains("symbolic link") && e.contains("elsewhere"), "{e}");
        assert!(matches!(check_output(dir.path(), "--out", &[]), Err(OutputError::Directory { .. })));
        assert!(matches!(check_output(&dir.path().join("no/x"), "--out", &[]), Err(OutputError::NoFolder { .. })));
        // New files, other files, standard output and /dev/null are fine.
        check_output(&dir.path().join("new.jsonl"), "--out", &inputs).unwrap();
        fs::write(dir.path().join("other.txt"), "x").unwrap();
        check_output(&dir.path().join("other.txt"), "--out", &inputs).unwrap();
        check_output(Path::new("-"), "--out", &inputs).unwrap();
        check_output(Path::new("/dev/null"), "--out", &inputs).unwrap();
        // Two outputs by two spellings, existing or not.
        let a = dir.path().join("sub/../t.json");
        fs::create_dir(dir.path().join("sub")).unwrap();
        assert!(same_file(&a, &dir.path().join("t.json")));
        assert!(!same_file(&a, &dir.path().join("u.json")));
        assert!(same_file(&hard, &rec));
    }

    #[cfg(unix)]
    #[test]
    fn a_device_is_written_in_place() {
        let mut f = AtomicFile::create(Path::new("/dev/null")).unwrap();
        assert_eq!(f.path(), Path::new("/dev/null"));
        f.write_all(b"gone").unwrap();
        f.commit().unwrap();
        use std::os::unix::fs::FileTypeExt;
        assert!(fs::symlink_metadata("/dev/null").unwrap().file_type().is_char_device());
    }
}
