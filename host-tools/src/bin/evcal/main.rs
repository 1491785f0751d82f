//! `evcal`: calibrate event cameras from an asymmetric circle grid.
//!
//! One module per command; `common` holds what several commands share.

// One `unsafe` call, allowed where it stands: `_exit` on a second Ctrl-C (`common::handle_signals`).
#![deny(unsafe_code)]

mod calibrate;
mod collect;
mod common;
mod demo;
mod detect;
mod device;
mod info;
mod ranges;
mod replay;
mod simulate;
mod simulation;
mod target;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "evcal",
    version,
    about = "Calibrate event cameras (DAVIS346, DVXplorer, Prophesee) from raw events on an asymmetric circle grid",
    long_about = "evcal finds the circles of an asymmetric circle grid in raw event-camera data, \
following the E-Calib method: events are cut into windows, clustered per circle (DBSCAN \
on the pixel grid), and each circle's slanted cylinder in (x, y, t) is fitted by reweighted least squares \
(eRWLS) to give sub-pixel centres. The same fixed-memory core runs on a microcontroller beside \
the sensor and here on the host.",
    after_help = "Examples:\n  evcal simulate --sensor davis346 --pattern 4x11 --seconds 5 --out rec.txt\n  \
evcal detect rec.txt --sensor 346x260 > detections.jsonl\n  evcal info recording.raw\n  \
evcal replay rec.txt --port tcp:127.0.0.1:7878 --out detections.jsonl\n  evcal collect --port /dev/ttyACM0 --out detections.jsonl\n  \
evcal calibrate detections.jsonl --pattern 4x11 --spacing 0.024\n  evcal demo\n  \
evcal target --pattern 4x11 --spacing 0.02 --out board.svg"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the detection core over a recording and print one JSON object per window.
    ///
    /// Output lines: {"seq", "t_ref_us", "events", "noise", "centers": [{"u", "v", "r",
    /// "spread", "n", "converged"}]}. Centres are in pixels at the window's reference time
    /// (the middle of its events' span), with (0,0) the centre of the top-left pixel.
    Detect(detect::DetectArgs),
    /// Simulate an event camera sweeping a circle grid; write the recording and truth.json.
    ///
    /// The recording is text (`t x y p`, first line `W H`) or, for a .h5 name, E-Calib's
    /// HDF5 layout. truth.json, written beside it, holds the camera (K, distortion, size),
    /// the grid, and for every window the detector will cut (same --events-per-window and
    /// --step-ms) the pose and each circle's true image centre at the window's t_ref: the
    /// projected ellipse's centre and the projection of the circle's centre. A truth.json there
    /// of another recording is left alone (an error): --truth FILE writes it elsewhere.
    Simulate(simulate::SimulateArgs),
    /// The main job on a built-in default: simulate a DAVIS346 with known intrinsics sweeping
    /// a 4x11 grid, run every window through the detection core on a virtual device (its
    /// protocol loop and the wire codec), find the grid, calibrate, and print the result beside
    /// the truth.
    ///
    /// Writes into --out (./evcal-out): calibration.json, opencv.yaml, camera_info.yaml,
    /// kalibr_camchain.yaml, report.png (as `evcal calibrate`) and detections.jsonl.
    Demo(demo::DemoArgs),
    /// Calibrate from a recording (the detection core runs over it first) or from detections
    /// collected earlier (JSON lines from `evcal detect`, `replay` or `collect`).
    ///
    /// Finds the grid in every window, keeps a view from each (up to --max-views), solves fx, fy, cx, cy and k1, k2, p1, p2, k3 (OpenCV's model) with
    /// the views' poses, sets aside views that do not fit (each with its reason), and says what
    /// the views leave uncovered. Writes into --out:
    ///   calibration.json      the result for programs: fx, fy, cx, cy, k1, k2, p1, p2, k3,
    ///                         rms_px, views_used, windows, detections, per_view, ...
    ///   opencv.yaml           cv::FileStorage: camera_matrix, distortion_coefficients,
    ///                         image_width, image_height
    ///   camera_info.yaml      ROS camera_info (as camera_calibration_parsers writes it)
    ///   kalibr_camchain.yaml  Kalibr: pinhole + radtan (no k3: solved with k3 = 0 when k3
    ///                         matters, and said so)
    ///   report.png            per-view error, residuals, sensor coverage, detections over time
    ///
    /// The last line is the verdict, and the exit status follows it:
    ///   verdict: good                 (0) fx, fy within 0.1 % (1σ), cx, cy within 1 px,
    ///                                 no distortion σ moving a sensor corner by over 0.5 px,
    ///                                 a distant point's projection σ within 1 px over 95 %
    ///                                 of the sensor,
    ///                                 points on at least 60 % of the sensor, 10 views or
    ///                                 more, RMS reprojection error within 0.5 px
    ///   verdict: usable, but ...      (4) a calibration that misses one of those; up to three
    ///                                 things to do about it, the most useful first
    ///   verdict: not a calibration    (3) the views leave fx, fy beyond 5 % or cx, cy beyond
    ///                                 5 % of the sensor (1σ): the files are named *.failed.*
    ///                                 and hold no camera matrix a program would load
    /// Other errors (an input that cannot be read, no grid in any window) exit with 1.
    #[command(
        verbatim_doc_comment,
        after_help = "Examples:\n  evcal calibrate rec.h5 --pattern 4x11 --spacing 0.024\n  \
evcal calibrate detections.jsonl --pattern 3x9 --spacing 0.027 --out cam0 --json cam0.json\n  \
evcal calibrate rec.txt --sensor davis346 --pattern 4x11 --spacing 0.024 --fix-k3"
    )]
    Calibrate(calibrate::CalibrateArgs),
    /// What a recording holds: format, sensor size, events, time span, event rate over time,
    /// polarity balance, and what the reader skipped or assumed.
    ///
    /// --json prints one object with (at least) "format", "width", "height", "events",
    /// "t_first_us", "t_last_us".
    Info(info::InfoArgs),
    /// Stream a recording into a device over serial or TCP and collect its detections.
    ///
    /// Hardware-in-the-loop: the device (firmware on a board, the firmware under QEMU, or
    /// `evcal device`) runs the detection core; this sends it the recording's events under its
    /// flow control and writes the windows it reports as JSON lines, the same lines `evcal
    /// detect` prints for the recording. Nothing is sent before the device's Hello (or
    /// --hello-timeout of silence). Frames the device reports damaged are sent again;
    /// detections damaged on the way back are counted as lost. Ctrl-C stops cleanly with
    /// everything received so far written (exit status 130).
    #[command(after_help = "Examples:\n  evcal replay rec.txt --port tcp:127.0.0.1:7878 --out detections.jsonl\n  \
evcal replay rec.h5 --port /dev/ttyACM0 --baud 921600 --sensor davis346\n  \
evcal replay rec.txt --port tcp:127.0.0.1:7878 --all-events -q > detections.jsonl")]
    Replay(replay::ReplayArgs),
    /// Record the detections of a device that has its own sensor, as JSON lines.
    ///
    /// Listens only. Live counts of windows, centres and windows lost (gaps in the device's
    /// window numbers). Ctrl-C stops cleanly with everything received so far written (exit
    /// status 130).
    #[command(after_help = "Examples:\n  evcal collect --port /dev/ttyACM0 --out detections.jsonl\n  \
evcal collect --port tcp:127.0.0.1:7878 --seconds 60 > detections.jsonl")]
    Collect(collect::CollectArgs),
    /// Run a virtual device on a TCP port: the firmware's protocol loop and detection core,
    /// here on the host, one connection at a time (each gets a fresh device).
    ///
    /// A board has one serial line: while a host is connected, another is closed at once
    /// (`replay` then says the device is busy with another host). A host that sends nothing
    /// for --idle-timeout seconds is dropped, so that a silent or vanished one does not keep
    /// the device.
    #[command(after_help = "Example (two terminals):\n  evcal device --listen 127.0.0.1:7878\n  \
evcal replay rec.txt --port tcp:127.0.0.1:7878 > detections.jsonl")]
    Device(device::DeviceArgs),
    /// Write the asymmetric circle grid to print, as SVG or PDF at true scale: black circles on
    /// white, a white margin of a spacing around them, the pattern, spacing and diameter
    /// printed under it, and a 50 mm scale bar to check the print with a ruler.
    ///
    /// The page is laid out as evcal expects the board seen from the front (the layout
    /// `evcal calibrate` echoes): circle 0 at the top left, columns to the right, each odd
    /// column a spacing lower. Print at 100 % ("actual size", no fit-to-page), measure the
    /// scale bar, and give `evcal calibrate` the same --pattern, --spacing and --radius (the
    /// caption says them). Glue the print flat on a rigid board.
    #[command(after_help = "Examples:\n  evcal target --pattern 4x11 --spacing 0.02 --out board.svg\n  \
evcal target --pattern 4x11 --spacing 0.024 --paper a3 --out board.pdf\n  \
evcal target --pattern 3x9 --spacing 0.027 --radius 0.008 --paper letter --out board.svg\n\n\
What --spacing means: S is the distance between neighbouring columns; circles in one column are \
2·S apart and diagonal neighbours S·√2 (board point (i, j) at (i·S, (2j + i mod 2)·S)). It is \
OpenCV's squareSize for CALIB_CB_ASYMMETRIC_GRID and Kalibr's spacingMeters with asymmetricGrid: \
true; evcal's 4x11 is OpenCV's patternSize (4, 11) and Kalibr's targetCols: 4, targetRows: 11.")]
    Target(target::TargetArgs),
}

fn main() {
    let cli = Cli::try_parse().unwrap_or_else(|e| exit_quoting_values_short(e));
    common::handle_signals();
    let r = match cli.command {
        Command::Detect(a) => detect::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Calibrate(a) => calibrate::run(a),
        Command::Info(a) => info::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Collect(a) => collect::run(a),
        Command::Device(a) => device::run(a),
        Command::Target(a) => target::run(a),
    };
    if let Err(e) = r {
        if e.chain().any(|c| c.is::<common::StdoutClosed>()) {
            // The reader has what it wanted (`evcal ... | head`): a quiet, successful end,
            // as the shell's own tools give.
            return;
        }
        eprintln!("evcal: error: {e:#}");
        std::process::exit(1);
    }
}

/// Longest option value an error quotes back, bytes.
const QUOTE: usize = 40;

/// Ends with clap's error `e`, any value it quotes cut to [`QUOTE`] bytes: a mistyped
/// 300-digit number is not worth a screenful.
fn exit_quoting_values_short(e: clap::Error) -> ! {
    use clap::error::{ContextKind, ContextValue};
    let long = match e.get(ContextKind::InvalidValue) {
        Some(ContextValue::String(v)) if v.len() > QUOTE => v.clone(),
        _ => e.exit(),
    };
    let short = evcal_host::input::recording::quote(long.as_bytes(), QUOTE);
    eprint!("{}", e.render().to_string().replace(&long, &short));
    std::process::exit(e.exit_code())
}
