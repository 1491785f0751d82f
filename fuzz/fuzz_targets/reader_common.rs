// Shared by the host reader targets: the fuzzer's bytes read as a recording, through a
// stream (as a pipe gives them) and, for the formats read as they come, from a file too.
// Nothing may panic, and the stream must give the same events and the same first error
// as the file: what the peek buffer saw while choosing the format is never lost.

use evcal_core::event::Event;
use evcal_host::input::recording::{OpenOptions, ReadError, Recording};
use std::{
    io::Cursor,
    path::{Path, PathBuf},
    sync::OnceLock,
};

/// Events read at most: a few kB of EVT 3.0 vectors can hold a million events.
const MAX_EVENTS: usize = 1 << 20;

fn collect(r: Result<Recording, ReadError>) -> Result<(Vec<Event>, Option<String>), String> {
    let rec = r.map_err(|e| e.message)?;
    let mut events = Vec::new();
    for e in rec.take(MAX_EVENTS) {
        match e {
            Ok(e) => events.push(e),
            Err(e) => return Ok((events, Some(e.message))),
        }
    }
    Ok((events, None))
}

/// Reads `data` as a recording named `name`; `compare`: also from a file, which must agree.
pub fn read(name: &str, data: &[u8], compare: bool) {
    let opts = OpenOptions::default();
    let streamed = collect(Recording::from_reader(Path::new(name), Box::new(Cursor::new(data.to_vec())), &opts));
    if !compare {
        return;
    }
    // One folder for the whole run, named for the process (scripts/fuzz.sh removes it
    // afterwards): making and removing one per input was most of an input's time. It sits
    // on a RAM disk where fuzz.sh finds one. Made again if something removed it meanwhile
    // (another run's clean-up): a long run must not die of a missing folder.
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| std::env::temp_dir().join(format!("evcal-fuzz-{}", std::process::id())));
    let path = dir.join(name);
    if std::fs::write(&path, data).is_err() {
        std::fs::create_dir_all(dir).expect("a temporary folder");
        std::fs::write(&path, data).expect("a temporary file");
    }
    let from_file = collect(Recording::open_with(&path, &opts));
    match (&streamed, &from_file) {
        (Ok((a, _)), Ok((b, _))) => assert!(a == b, "{} events from a stream, {} from the file", a.len(), b.len()),
        (Err(_), Err(_)) => {}
        (a, b) => panic!("stream {:?}, file {:?}", a.as_ref().map(|r| r.0.len()), b.as_ref().map(|r| r.0.len())),
    }
}
