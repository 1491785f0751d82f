//! Every numeric option of every command with hostile values (issue 46, item 6): each is
//! refused with a message naming the option, or taken; never a panic, never a hang. Before,
//! `replay --connect-timeout 1e300` and its kind panicked converting to a `Duration`.

use super::link::Device;
use super::{evcal_command, fixture, s, window};
use proptest::prelude::*;
use std::{
    io::Read,
    path::Path,
    process::Stdio,
    time::{Duration, Instant},
};

/// The values every option is tried with, besides its ordinary one.
const HOSTILE: [&str; 13] = [
    "0",
    "-1",
    "-0",
    "NaN",
    "inf",
    "-inf",
    "1e300",
    "-1e300",
    "1e-300",
    "18446744073709551616",
    "340282366920938463463374607431768211456",
    "99999999999999999999999999999999999999999999999999999999999999999999999999999999",
    "4294967296",
];

/// A command and how to run it on tiny inputs: its arguments as (option, value) pairs (the
/// one tried is left out of them), and whether it runs until stopped (`device`).
#[derive(Clone, Copy, PartialEq)]
enum Cmd {
    Detect,
    Calibrate,
    Simulate,
    Demo,
    Replay,
    Collect,
    Device,
}

/// (command, option, an ordinary value; "{}" in the option's value stands for the value
/// tried: `--sensor {}x{}`).
const OPTIONS: &[(Cmd, &str, &str)] = &[
    (Cmd::Detect, "--step-ms", "10"),
    (Cmd::Detect, "--eps", "0.02"),
    (Cmd::Detect, "--min-pts", "5"),
    (Cmd::Detect, "--eps-t", "0.5"),
    (Cmd::Detect, "--events-per-window", "300"),
    (Cmd::Detect, "--sensor", "346"),
    (Cmd::Calibrate, "--spacing", "0.03"),
    (Cmd::Calibrate, "--radius", "0.008"),
    (Cmd::Calibrate, "--min-change-px", "2"),
    (Cmd::Calibrate, "--max-views", "100"),
    (Cmd::Calibrate, "--pattern", "5"),
    (Cmd::Calibrate, "--step-ms", "10"),
    (Cmd::Calibrate, "--eps", "0.02"),
    (Cmd::Calibrate, "--min-pts", "5"),
    (Cmd::Calibrate, "--eps-t", "0.5"),
    (Cmd::Calibrate, "--events-per-window", "300"),
    (Cmd::Simulate, "--seconds", "0.03"),
    (Cmd::Simulate, "--seed", "7"),
    (Cmd::Simulate, "--events-per-window", "300"),
    (Cmd::Simulate, "--step-ms", "10"),
    (Cmd::Simulate, "--photoreceptor-hz", "300"),
    (Cmd::Simulate, "--threshold", "0.3"),
    (Cmd::Simulate, "--mismatch", "0.05"),
    (Cmd::Simulate, "--leak-hz", "0.1"),
    (Cmd::Simulate, "--shot-noise-hz", "1"),
    (Cmd::Simulate, "--illumination", "0.5"),
    (Cmd::Demo, "--seconds", "0.03"),
    (Cmd::Replay, "--step-ms", "10"),
    (Cmd::Replay, "--eps", "0.02"),
    (Cmd::Replay, "--min-pts", "5"),
    (Cmd::Replay, "--eps-t", "0.5"),
    (Cmd::Replay, "--events-per-window", "300"),
    (Cmd::Replay, "--baud", "9600"),
    (Cmd::Replay, "--connect-timeout", "2"),
    (Cmd::Replay, "--hello-timeout", "2"),
    (Cmd::Replay, "--retry-ms", "500"),
    (Cmd::Collect, "--baud", "9600"),
    (Cmd::Collect, "--connect-timeout", "2"),
    (Cmd::Collect, "--seconds", "0.2"),
    (Cmd::Collect, "--windows", "3"),
    (Cmd::Device, "--idle-timeout", "5"),
];

/// The longest a run may take (a simulation of a few hundredths of a second, a replay of
/// 2000 events).
const RUN_LIMIT: Duration = Duration::from_secs(15);

/// The command's arguments on tiny inputs in `dir` (made by [`inputs`]), without `option`,
/// with `value` for it; the device to talk to for `replay` and `collect`.
fn command_line(cmd: Cmd, option: &str, value: &str, dir: &Path, device: Option<&Device>) -> Vec<String> {
    let rec = fixture("events.txt");
    let det = dir.join("det.jsonl");
    let port = device.map(Device::port).unwrap_or_default();
    // Outputs of their own: runs go on side by side.
    static RUNS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let own = dir.join(format!("run{}", RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed)));
    let (head, pairs): (Vec<String>, Vec<(&str, String)>) = match cmd {
        Cmd::Detect => (vec!["detect".into(), s(&rec).into()], vec![("-o", "/dev/null".into())]),
        Cmd::Calibrate => (
            vec!["calibrate".into(), s(&det).into()],
            vec![
                ("--sensor", "346x260".into()),
                ("--pattern", "4x11".into()),
                ("--spacing", "0.024".into()),
                ("--out", s(&own.join("cal")).into()),
            ],
        ),
        Cmd::Simulate => {
            (vec!["simulate".into()], vec![("--seconds", "0.03".into()), ("-o", s(&own.join("rec.txt")).into())])
        }
        Cmd::Demo => (vec!["demo".into()], vec![("--seconds", "0.03".into()), ("--out", s(&own).into())]),
        Cmd::Replay => (
            vec!["replay".into(), s(&rec).into()],
            vec![("--port", port), ("--sensor", "346x260".into()), ("-o", "/dev/null".into())],
        ),
        Cmd::Collect => {
            (vec!["collect".into()], vec![("--port", port), ("--seconds", "0.2".into()), ("-o", "/dev/null".into())])
        }
        Cmd::Device => (vec!["device".into()], vec![("--listen", "127.0.0.1:0".into())]),
    };
    let mut args = head;
    args.push("--quiet".into());
    if cmd == Cmd::Device {
        args.pop();
    }
    for (o, v) in pairs.into_iter().filter(|(o, _)| *o != option) {
        args.extend([o.to_string(), v]);
    }
    let value = match option {
        "--sensor" | "--pattern" => format!("{value}x{value}"),
        _ => value.to_string(),
    };
    // `--opt=value`: a value starting with '-' is the option's, not another option.
    args.push(format!("{option}={value}"));
    args
}

/// The tiny inputs the command lines read.
fn inputs() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("det.jsonl"), window(0, 100) + &window(1, 40_000)).unwrap();
    dir
}

/// Runs one command line and checks that it ends in time without a panic.
fn check(cmd: Cmd, option: &str, value: &str, dir: &Path) -> Result<(), String> {
    let device = matches!(cmd, Cmd::Replay | Cmd::Collect).then(|| Device::start(&["--idle-timeout", "0.5"]));
    let args = command_line(cmd, option, value, dir, device.as_ref());
    let mut child =
        evcal_command().args(&args).stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let started = Instant::now();
    // A device runs until stopped: a second shows it did not die on its options.
    let limit = if cmd == Cmd::Device { Duration::from_secs(1) } else { RUN_LIMIT };
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break Some(st);
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let err = reader.join().unwrap();
    let line = args.join(" ");
    match status {
        None if cmd == Cmd::Device => Ok(()),
        None => Err(format!("{line}: still running after {limit:?}")),
        Some(st) if st.code() == Some(101) || err.contains("panicked") => Err(format!("{line}: panicked: {err}")),
        Some(st) if st.code().is_none() => Err(format!("{line}: killed by a signal ({st}): {err}")),
        // A refusal says which option.
        Some(st) if st.code() == Some(2) && !err.contains(option) => {
            Err(format!("{line}: refused without naming it: {err}"))
        }
        Some(_) => Ok(()),
    }
}

/// Runs `cases` on a few threads; every failure, or none.
fn check_all(cases: Vec<(Cmd, &'static str, String)>, dir: &Path) -> Vec<String> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failures = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..3 {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some((cmd, option, value)) = cases.get(i) else { return };
                if let Err(e) = check(*cmd, option, value, dir) {
                    failures.lock().unwrap().push(e);
                }
            });
        }
    });
    failures.into_inner().unwrap()
}

#[test]
fn every_numeric_option_takes_or_refuses_hostile_values_without_a_panic() {
    let dir = inputs();
    let started = Instant::now();
    let cases: Vec<_> = OPTIONS
        .iter()
        .flat_map(|&(cmd, option, ordinary)| {
            HOSTILE.iter().copied().chain([ordinary]).map(move |v| (cmd, option, v.to_string()))
        })
        .collect();
    let n = cases.len();
    let failures = check_all(cases, dir.path());
    assert!(failures.is_empty(), "{} of {n} runs failed:\n{}", failures.len(), failures.join("\n"));
    eprintln!("{n} runs in {:.1} s", started.elapsed().as_secs_f64());
}

/// Options whose every accepted value is cheap on the tiny inputs (a long simulation or wait
/// is a value's meaning, not a fault), for random values.
fn cheap(cmd: Cmd, option: &str) -> bool {
    !matches!(
        (cmd, option),
        (Cmd::Simulate | Cmd::Demo | Cmd::Device, _) | (Cmd::Collect, "--seconds") | (Cmd::Replay, "--retry-ms")
    )
}

/// Numbers as people and scripts write them: any double (NaN, infinities and subnormals
/// among them) plainly or in exponent form, any integer, long runs of digits.
fn numbers() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| format!("{v:e}")),
        any::<i64>().prop_map(|v| v.to_string()),
        "[0-9]{1,60}",
        "-?[0-9]{0,3}\\.[0-9]{0,4}(e-?[0-9]{1,3})?",
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]
    #[test]
    fn random_numbers_in_options_never_panic(
        i in 0..OPTIONS.iter().filter(|(c, o, _)| cheap(*c, o)).count(),
        value in numbers(),
    ) {
        let (cmd, option, _) = *OPTIONS.iter().filter(|(c, o, _)| cheap(*c, o)).nth(i).unwrap();
        let dir = inputs();
        let r = check(cmd, option, &value, dir.path());
        prop_assert!(r.is_ok(), "{}", r.unwrap_err());
    }
}

#[test]
fn refusals_say_the_range_and_why() {
    // Before: "--connect-timeout inf" was "must be a non-negative number"; --radius 1e-300
    // and --step-ms 1e300 were taken silently.
    let dir = inputs();
    let det = dir.path().join("det.jsonl");
    let rec = fixture("events.txt");
    let cal = ["calibrate", s(&det), "--sensor", "346x260", "--pattern", "4x11", "--spacing", "0.024"];
    for (args, code, said) in [
        (
            &["replay", s(&rec), "--port", "tcp:127.0.0.1:9", "--connect-timeout", "inf"][..],
            2,
            &["--connect-timeout", "not a finite number", "from 0 to 31536000", "a year"][..],
        ),
        (&["collect", "--port", "tcp:127.0.0.1:9", "--seconds", "1e300"], 2, &["--seconds", "out of range"]),
        (&["detect", s(&rec), "--step-ms", "1e300"], 2, &["--step-ms", "from 0 to 60000", "a minute"]),
        (&["detect", s(&rec), "--eps", "1e-300"], 2, &["--eps", "from 0.0001 to 0.5"]),
        (&[&cal[..], &["--radius", "1e-300"]].concat(), 1, &["--radius 1e-300:", "0.0012 m", "a twentieth"]),
        (&[&cal[..], &["--radius", "0.02"]].concat(), 1, &["below 0.0170 m", "overlap"]),
        (&["simulate", "-o", "x.txt", "--leak-hz", "1e4"], 2, &["--leak-hz", "from 0 to 100"]),
    ] {
        let o = evcal_command().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
        for s in said {
            assert!(err.contains(s), "{args:?}: {s:?} in {err}");
        }
        assert!(!err.contains("00000000000000000000"), "no long numbers quoted back: {err}");
    }
}
