//! An earlier run's results, when this run ends without its own: `evcal calibrate` into a
//! folder that holds yesterday's files must not leave them looking like today's result.
//! Only files evcal can tell it wrote are removed; links are never touched.

use super::{report::PNG_SOFTWARE, FAILED_FILE_NAMES, FILE_NAMES};
use std::{
    fs,
    io::Read,
    path::{Path, PathBuf},
};

/// How every YAML file evcal writes ends: this and the version (`# written by evcal 0.1.0`).
pub const YAML_MARK: &str = "# written by evcal";

/// The calibration JSON's first keys, which never change (docs/formats.md): a JSON file with
/// all of them is evcal's result, of any version.
const JSON_KEYS: [&str; 14] =
    ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "rms_px", "views_used", "windows", "detections", "per_view"];

/// Larger files are no result of evcal's (a calibration.json of 500 views is about 200 kB),
/// and are not read to find out.
const MAX_RESULT_BYTES: u64 = 64 << 20;
/// How much of a PNG is searched for its `Software` text, which evcal writes before the image.
const PNG_HEAD: u64 = 4096;

/// What [`remove_stale`] did.
#[derive(Debug, Default)]
pub struct Stale {
    /// Files evcal wrote in an earlier run, removed.
    pub removed: Vec<PathBuf>,
    /// Files under evcal's names that it cannot tell it wrote (another program's, an older
    /// evcal's YAML or report, a link): left as they are.
    pub left: Vec<PathBuf>,
    /// Files evcal wrote that could not be removed, with why.
    pub failed: Vec<(PathBuf, std::io::Error)>,
}

/// Removes the results an earlier run left in `dir` (a calibration's, [`FILE_NAMES`], and a
/// failed run's, [`FAILED_FILE_NAMES`]) and at `json` (the `--json` copy), for a run that
/// ends without writing its own. Each file is removed only when [`written_by_evcal`] knows
/// it.
pub fn remove_stale(dir: &Path, json: Option<&Path>) -> Stale {
    let names: Vec<&str> = FILE_NAMES.iter().chain(&FAILED_FILE_NAMES).copied().collect();
    remove_named(dir, &names, json)
}

/// [`remove_stale`] of the files `names` in `dir`, and `json`.
pub(super) fn remove_named(dir: &Path, names: &[&str], json: Option<&Path>) -> Stale {
    let mut s = Stale::default();
    let named = names.iter().map(|n| dir.join(n)).chain(json.map(Path::to_path_buf));
    for p in named {
        // Nothing there, or the same file twice (--json naming the folder's own).
        if fs::symlink_metadata(&p).is_err() || s.removed.contains(&p) {
            continue;
        }
        if !written_by_evcal(&p) {
            s.left.push(p);
            continue;
        }
        match fs::remove_file(&p) {
            Ok(()) => s.removed.push(p),
            Err(e) => s.failed.push((p, e)),
        }
    }
    s
}

/// Whether evcal wrote the result file at `path` (never following a link): a JSON file with
/// the calibration's first keys, a YAML file ending with [`YAML_MARK`], a PNG whose software
/// is evcal.
pub fn written_by_evcal(path: &Path) -> bool {
    let Ok(m) = fs::symlink_metadata(path) else { return false };
    if !m.is_file() || m.len() > MAX_RESULT_BYTES {
        return false;
    }
    let Ok(f) = fs::File::open(path) else { return false };
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "png" => {
            let mut head = Vec::new();
            if f.take(PNG_HEAD).read_to_end(&mut head).is_err() {
                return false;
            }
            let text = format!("tEXtSoftware\0{PNG_SOFTWARE}");
            head.starts_with(b"\x89PNG") && head.windows(text.len()).any(|w| w == text.as_bytes())
        }
        "yaml" | "yml" => {
            let mut text = String::new();
            if f.take(MAX_RESULT_BYTES).read_to_string(&mut text).is_err() {
                return false;
            }
            text.lines().rev().find(|l| !l.trim().is_empty()).is_some_and(|l| l.starts_with(YAML_MARK))
        }
        _ => match serde_json::from_reader::<_, serde_json::Value>(std::io::BufReader::new(f)) {
            Ok(serde_json::Value::Object(o)) => JSON_KEYS.iter().all(|k| o.contains_key(*k)),
            _ => false,
        },
    }
}

#[cfg(test)]
mod test {
    use super::super::testdata::*;
    use super::super::{write_all, Export};
    use super::*;

    #[test]
    fn only_evcal_s_own_results_are_removed() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let json = dir.path().join("cam0.json");
        let export = Export { json_copy: Some(&json), ..Export::new(&cal, &views, &origins, &timeline) };
        let written = write_all(dir.path(), &export).unwrap();
        for p in written.paths.iter().chain([&json]) {
            assert!(written_by_evcal(p), "{}", p.display());
        }
        // Another program's files under evcal's names, and one of its own.
        std::fs::write(dir.path().join("opencv.yaml"), "%YAML:1.0\n---\nimage_width: 346\n").unwrap();
        std::fs::write(dir.path().join("calibration.json"), r#"{"fx": 1}"#).unwrap();
        std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
        let s = remove_stale(dir.path(), Some(&json));
        let name = |p: &PathBuf| p.file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(
            s.removed.iter().map(name).collect::<Vec<_>>(),
            ["camera_info.yaml", "kalibr_camchain.yaml", "report.png", "cam0.json"]
        );
        assert_eq!(s.left.iter().map(name).collect::<Vec<_>>(), ["calibration.json", "opencv.yaml"]);
        assert!(s.failed.is_empty());
        let mut left: Vec<String> =
            std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
        left.sort();
        assert_eq!(left, ["calibration.json", "notes.txt", "opencv.yaml"]);
        assert_eq!(std::fs::read(dir.path().join("opencv.yaml")).unwrap(), b"%YAML:1.0\n---\nimage_width: 346\n");
    }

    #[cfg(unix)]
    #[test]
    fn a_link_under_an_evcal_name_is_left_and_its_target_too() {
        let (views, cal, origins, timeline) = setup(&TRUTH, false);
        let dir = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        write_all(elsewhere.path(), &Export::new(&cal, &views, &origins, &timeline)).unwrap();
        let target = elsewhere.path().join("calibration.json");
        std::os::unix::fs::symlink(&target, dir.path().join("calibration.json")).unwrap();
        let s = remove_stale(dir.path(), None);
        assert!(s.removed.is_empty() && s.left.len() == 1, "{s:?}");
        assert!(target.exists());
    }
}
