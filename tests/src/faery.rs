//! The real sensor recordings of faery's source distribution (fetched by
//! `scripts/fetch-faery.sh`, never committed) and what its `tests/assets.py` says they hold.

use std::{
    path::{Path, PathBuf},
    process::Command,
};

/// The directory of faery's `tests/data`, fetching it if need be.
///
/// `None` (after a loud message) only when the data cannot be had and this is not CI; on CI
/// (`CI` set) a missing data set fails the test, since CI fetches it first.
pub fn data_dir() -> Option<PathBuf> {
    if let Ok(d) = std::env::var("EVCAL_FAERY_DATA") {
        return Some(PathBuf::from(d));
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = Command::new("bash").arg(root.join("scripts/fetch-faery.sh")).current_dir(&root).output();
    match out {
        Ok(o) if o.status.success() => Some(PathBuf::from(String::from_utf8_lossy(&o.stdout).trim())),
        other => {
            let why = match other {
                Ok(o) => String::from_utf8_lossy(&o.stderr).into_owned(),
                Err(e) => e.to_string(),
            };
            if std::env::var_os("CI").is_some() {
                panic!("faery's recordings are needed on CI and could not be fetched: {why}");
            }
            eprintln!("\n!!!!!!!! SKIPPED: faery's real recordings could not be fetched ({why}); run scripts/fetch-faery.sh\n");
            None
        }
    }
}

/// One file's entry in faery's `assets.py`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Asset {
    /// SHA3-224 of each field (`t`, `x`, `y`, `on`) as faery decodes it.
    pub digests: Vec<(String, String)>,
    /// Width and height.
    pub dimensions: Option<(u16, u16)>,
    /// First event's time and (exclusive) end, in µs.
    pub time_range: (u64, u64),
}

/// `HH:MM:SS.ffffff` to µs.
fn parse_time(s: &str) -> u64 {
    let mut parts = s.split(':');
    let (h, m, sec) = (parts.next().unwrap(), parts.next().unwrap(), parts.next().unwrap());
    let (sec, frac) = sec.split_once('.').unwrap();
    ((h.parse::<u64>().unwrap() * 60 + m.parse::<u64>().unwrap()) * 60 + sec.parse::<u64>().unwrap()) * 1_000_000
        + frac.parse::<u64>().unwrap()
}

/// Reads the entry of `file` (e.g. `evt3.raw`) from `assets.py` beside the data directory.
pub fn asset(data: &Path, file: &str) -> Asset {
    let text = std::fs::read_to_string(data.join("../assets.py")).expect("faery's tests/assets.py");
    let start = text.find(&format!("\"data\" / \"{file}\"")).unwrap_or_else(|| panic!("{file} in assets.py"));
    let block = &text[start..];
    let block = &block[..block[1..].find("File(").map_or(block.len(), |e| e + 1)];
    let quoted = |s: &str| -> Vec<String> { s.split('"').skip(1).step_by(2).map(str::to_string).collect() };
    let digests_src = &block[block.find("field_to_digest={").unwrap()..];
    let digests_src = &digests_src[..digests_src.find('}').unwrap()];
    let q = quoted(digests_src);
    let digests = q.chunks(2).map(|c| (c[0].clone(), c[1].clone())).collect();
    let dim_src = &block[block.find("dimensions=").unwrap() + 11..];
    let dimensions = dim_src.strip_prefix('(').map(|d| {
        let d = &d[..d.find(')').unwrap()];
        let (w, h) = d.split_once(',').unwrap();
        (w.trim().parse().unwrap(), h.trim().parse().unwrap())
    });
    let tr = &block[block.find("time_range=(").unwrap()..];
    let tr = quoted(&tr[..tr.find(')').unwrap()]);
    Asset { digests, dimensions, time_range: (parse_time(&tr[0]), parse_time(&tr[1])) }
}
