//! The link and signals (issue 46, items 6 to 8): Ctrl-C while a connection is retried, a
//! stream's temporary copy on Ctrl-C, a virtual device held by a silent host.

use super::{evcal_command, fixture, s};
use std::{
    io::{BufRead, BufReader, Read, Write},
    net::TcpStream,
    path::Path,
    process::{Child, ExitStatus, Stdio},
    sync::mpsc::{self, Receiver},
    time::{Duration, Instant},
};

/// `evcal device` on a free port, its standard error read line by line; killed when dropped.
pub struct Device {
    child: Child,
    /// `HOST:PORT` it listens on.
    pub addr: String,
    /// Its log lines after the first.
    pub log: Receiver<String>,
}

impl Device {
    pub fn start(extra: &[&str]) -> Self {
        let mut child = evcal_command()
            .args(["device", "--listen", "127.0.0.1:0"])
            .args(extra)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let first = lines.next().unwrap().unwrap();
        let addr = first.split("tcp:").nth(1).unwrap().split_whitespace().next().unwrap().to_string();
        let (send, log) = mpsc::channel();
        std::thread::spawn(move || {
            for l in lines.map_while(Result::ok) {
                if send.send(l).is_err() {
                    return;
                }
            }
        });
        Self { child, addr, log }
    }

    /// `tcp:HOST:PORT`.
    pub fn port(&self) -> String {
        format!("tcp:{}", self.addr)
    }

    /// The next log line holding `what`, within `limit`; the lines before it are passed.
    fn wait_for(&self, what: &str, limit: Duration) -> Option<String> {
        let until = Instant::now() + limit;
        while let Some(left) = until.checked_duration_since(Instant::now()) {
            match self.log.recv_timeout(left) {
                Ok(l) if l.contains(what) => return Some(l),
                Ok(_) => {}
                Err(_) => return None,
            }
        }
        None
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits up to `limit` for `child` to end; kills it if it does not (`None`).
fn wait_at_most(child: &mut Child, limit: Duration) -> Option<ExitStatus> {
    let started = Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return Some(st);
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn signal(child: &Child, sig: &str) {
    let ok = std::process::Command::new("kill").args([sig, &child.id().to_string()]).status().unwrap().success();
    assert!(ok, "kill {sig}");
}

/// A TCP port on which nothing listens: every connection is refused.
fn closed_port() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let a = l.local_addr().unwrap();
    drop(l);
    format!("tcp:{a}")
}

#[test]
fn a_signal_ends_connection_retries_at_once_with_status_130() {
    // Before: the retry loop never looked at Ctrl-C, and went on for all of
    // --connect-timeout (19 minutes until SIGKILL in the issue).
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("det.jsonl");
    let rec = fixture("events.txt");
    let port = closed_port();
    let replay = ["replay", s(&rec), "--port", &port, "--connect-timeout", "60", "--sensor", "346x260", "-o", s(&out)];
    let collect = ["collect", "--port", &port, "--connect-timeout", "60", "-o", s(&out)];
    for (args, sig) in [(&replay[..], "-INT"), (&collect[..], "-INT"), (&collect[..], "-TERM")] {
        let mut child = evcal_command().args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
        std::thread::sleep(Duration::from_millis(1000));
        assert!(child.try_wait().unwrap().is_none(), "{args:?}: still retrying");
        signal(&child, sig);
        let sent = Instant::now();
        let status = wait_at_most(&mut child, Duration::from_secs(3));
        let took = sent.elapsed();
        let mut err = String::new();
        child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
        let status = status.unwrap_or_else(|| panic!("{args:?} {sig}: still running 3 s after the signal"));
        assert_eq!(status.code(), Some(130), "{args:?} {sig}: {err}");
        assert!(took < Duration::from_secs(1), "{args:?} {sig}: {took:?}");
        assert!(err.contains("interrupted while connecting"), "{err}");
        assert!(!out.exists(), "nothing written: no detections came");
    }
}

/// Every file in `dir`.
fn files_in(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect()
}

#[test]
fn a_stream_copied_to_a_temporary_file_leaves_nothing_when_interrupted() {
    // HDF5 needs random access: a pipe is copied to $TMPDIR first. Before, Ctrl-C killed
    // evcal there and left the copy behind.
    let tmp = tempfile::tempdir().unwrap();
    let h5 = std::fs::read(fixture("ecalib.h5")).unwrap();
    for sig in ["-INT", "-TERM"] {
        let mut child = evcal_command()
            .args(["detect", "-", "--quiet", "-o", "/dev/null"])
            .env("TMPDIR", tmp.path())
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Part of the file, and the pipe left open: a slow producer.
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(&h5[..h5.len() / 2]).unwrap();
        stdin.flush().unwrap();
        let until = Instant::now() + Duration::from_secs(5);
        while files_in(tmp.path()).is_empty() && Instant::now() < until {
            std::thread::sleep(Duration::from_millis(20));
        }
        assert_eq!(files_in(tmp.path()).len(), 1, "the copy is being made");
        signal(&child, sig);
        let status = wait_at_most(&mut child, Duration::from_secs(3)).expect("ends on the signal");
        drop(stdin);
        assert_eq!(files_in(tmp.path()), Vec::<String>::new(), "{sig}: the copy is removed");
        assert_eq!(status.code(), Some(130), "{sig}");
    }
}

#[test]
fn a_device_held_by_a_silent_host_turns_others_away_then_drops_it() {
    // Before: the second host waited in the listener's backlog while the first held the
    // device for good, and the replay failed after 24 s with "the device did not answer
    // the configuration".
    let dev = Device::start(&["--idle-timeout", "1.5"]);
    let mut silent = TcpStream::connect(&dev.addr).unwrap();
    let connected = Instant::now();
    let line = dev.wait_for("host connected from", Duration::from_secs(2)).expect("the device logs the host");
    assert!(line.contains(&format!("from {}", silent.local_addr().unwrap())), "{line}");

    let rec = fixture("events.txt");
    let started = Instant::now();
    let mut replay = evcal_command()
        .args(["replay", s(&rec), "--port", &dev.port(), "--sensor", "346x260", "-o", "/dev/null"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status = wait_at_most(&mut replay, Duration::from_secs(5)).expect("the replay is told at once");
    let mut err = String::new();
    replay.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("the device is busy with another host"), "{err}");
    assert!(started.elapsed() < Duration::from_secs(2), "{:?}", started.elapsed());
    assert!(dev.wait_for("turned away: busy with", Duration::from_secs(1)).is_some());

    // The silent host is dropped after --idle-timeout: its connection ends.
    silent.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut rest = Vec::new();
    silent.read_to_end(&mut rest).expect("the device closes the connection");
    let held = connected.elapsed();
    assert!(held >= Duration::from_millis(1400) && held < Duration::from_secs(4), "{held:?}");
    assert!(!rest.is_empty(), "the device said Hello first");
    assert!(dev.wait_for("dropped: silent for 1.5 s", Duration::from_secs(1)).is_some());

    // The device is free again.
    let o = evcal_command()
        .args(["replay", s(&rec), "--port", &dev.port(), "--sensor", "346x260", "-o", "/dev/null", "-q"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
