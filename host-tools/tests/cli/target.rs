//! `evcal target`: the printable board, written whole at true scale and said on standard
//! error; bad input is refused with the reason, a non-zero status, and nothing written.

use std::{path::Path, process::Command};

fn evcal(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_evcal")).args(args).current_dir(dir).output().unwrap()
}

fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().into_string().unwrap()).collect();
    n.sort();
    n
}

#[test]
fn writes_the_board_and_says_its_size() {
    let dir = tempfile::tempdir().unwrap();
    let out = evcal(&["target", "--pattern", "4x11", "--spacing", "0.02", "--out", "board.svg"], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(out.stdout.is_empty());
    assert!(err.contains("wrote board.svg") && err.contains("A4 landscape (297 x 210 mm)"), "{err}");
    assert!(err.contains("spacing 0.02 m") && err.contains("radius 0.006 m"), "{err}");
    // Nothing but the board: no temporary file left beside it.
    assert_eq!(names(dir.path()), ["board.svg"]);
    let svg = std::fs::read_to_string(dir.path().join("board.svg")).unwrap();
    assert!(svg.contains(r#"width="297mm" height="210mm" viewBox="0 0 297 210""#), "{svg}");
    assert_eq!(svg.matches("<circle").count(), 44);
    assert!(svg.contains("spacing 20 mm, circle diameter 12 mm: print at 100 %, no fit-to-page"));

    // A given radius and paper; standard output with `-`.
    let out = evcal(
        &["target", "--pattern", "3x9", "--spacing", "0.015", "--radius", "0.004", "--paper", "letter", "--out", "-"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let svg = String::from_utf8(out.stdout).unwrap();
    assert!(svg.starts_with("<?xml") && svg.contains(r#"width="215.9mm""#), "{svg}");
    assert_eq!(svg.matches(r#" r="4""#).count(), 27);
    assert!(String::from_utf8_lossy(&out.stderr).contains("wrote standard output"));

    // A PDF by its name.
    let out = evcal(&["target", "--pattern", "4x11", "--spacing", "0.024", "--out", "board.PDF"], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("A3 landscape (420 x 297 mm)"), "{err}");
    let pdf = std::fs::read(dir.path().join("board.PDF")).unwrap();
    assert!(pdf.starts_with(b"%PDF-") && String::from_utf8_lossy(&pdf).contains("/MediaBox [0 0 1190.5"));
    assert_eq!(names(dir.path()), ["board.PDF", "board.svg"]);
}

#[test]
fn bad_input_is_refused_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("board.svg"), "earlier").unwrap();
    std::fs::create_dir(dir.path().join("folder.svg")).unwrap();
    let base = ["target", "--pattern", "4x11", "--spacing", "0.02", "--out", "board.svg"];
    let with = |i: usize, v: &'static str| {
        let mut a = base.to_vec();
        a[i] = v;
        a
    };
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (with(4, "0"), "spacing 0: must be a positive length"),
        (with(4, "-1"), "spacing -1: must be a positive length"),
        (with(4, "NaN"), "spacing NaN: must be a positive length"),
        (with(4, "inf"), "spacing inf: must be a positive length"),
        (with(4, "20"), "metres, not millimetres? (20 mm is --spacing 0.02)"),
        (with(4, "0.05"), "holds it in neither orientation: give --spacing 0.0291 or less"),
        (with(2, "0x3"), "pattern 0x3: an asymmetric circle grid needs 2 to 64 rows"),
        (with(2, "4-11"), "expected ROWSxCOLS"),
        (with(6, "folder.svg"), "--out folder.svg: is a directory"),
        (with(6, "."), "--out .: is a directory"),
        (with(6, "board.png"), "give a name ending in .svg or .pdf"),
        (with(6, "missing/board.svg"), "the folder missing does not exist"),
        ([&base[..], &["--radius", "0.02"]].concat(), "below 0.0141 m (half the diagonal spacing"),
        ([&base[..], &["--radius", "NaN"]].concat(), "--radius NaN"),
        ([&base[..], &["--paper", "a5"]].concat(), "invalid value 'a5'"),
    ];
    for (args, want) in cases {
        let out = evcal(&args, dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(out.stdout.is_empty());
    }
    assert_eq!(std::fs::read_to_string(dir.path().join("board.svg")).unwrap(), "earlier");
    assert_eq!(names(dir.path()), ["board.svg", "folder.svg"]);
}
