//! Command-line pieces the examples share: `--cache DIR`, `--FLAG VALUE` options and the
//! simulator's preset names.

use evcal_host::{
    sim::{Light, SimConfig, Trajectory},
    views::grid::Pattern,
};
use std::path::PathBuf;

/// Removes `flag VALUE` from `args` wherever it is and returns the value, or `None` when the
/// flag is absent. A value missing or not accepted by `ok` ends the program with `need` (what
/// the flag needs) and status 2.
pub fn take_value<T: std::str::FromStr>(
    args: &mut Vec<String>,
    flag: &str,
    need: &str,
    ok: impl Fn(&T) -> bool,
) -> Option<T> {
    let i = args.iter().position(|a| a == flag)?;
    match args.get(i + 1).and_then(|s| s.parse::<T>().ok()).filter(|v| ok(v)) {
        Some(v) => {
            args.drain(i..i + 2);
            Some(v)
        }
        None => {
            eprintln!("{flag} needs {need}");
            std::process::exit(2);
        }
    }
}

/// Removes `--cache DIR` from `args` wherever it is and returns the directory.
pub fn take_cache(args: &mut Vec<String>) -> Option<PathBuf> {
    let i = args.iter().position(|a| a == "--cache")?;
    if i + 1 >= args.len() {
        return None;
    }
    let dir = args.remove(i + 1);
    args.remove(i);
    Some(PathBuf::from(dir))
}

/// The trajectory a preset name stands for (anything else: the cone).
pub fn trajectory(name: &str) -> Trajectory {
    match name {
        "spiral" => Trajectory::Spiral,
        "square" => Trajectory::Square,
        _ => Trajectory::Cone,
    }
}

/// The light a preset name stands for (anything but `low`: good).
pub fn light(name: &str) -> Light {
    if name == "low" {
        Light::Low
    } else {
        Light::Good
    }
}

/// The simulator preset `sensor` `pattern` and its grid, or a message and exit status 2 for
/// names no preset has.
pub fn preset_or_exit(
    sensor: &str,
    pattern: &str,
    trajectory: Trajectory,
    light: Light,
    seed: u64,
) -> (SimConfig, Pattern) {
    let Some(cfg) = SimConfig::preset(sensor, pattern, trajectory, light, seed) else {
        eprintln!("unknown sensor or pattern: {sensor} {pattern}");
        std::process::exit(2);
    };
    let grid = Pattern::new(cfg.board.rows, cfg.board.cols, cfg.board.spacing).expect("preset pattern");
    (cfg, grid)
}

/// The scenario the examples take as `SENSOR PATTERN cone|square|spiral good|low SECONDS
/// SEED` (the first six of `args`): its simulator configuration, grid and seconds, or the
/// `usage` line and exit status 2.
pub fn scenario_or_exit(args: &[String], usage: &str) -> (SimConfig, Pattern, f64) {
    if args.len() < 6 {
        eprintln!("usage: {usage}");
        std::process::exit(2);
    }
    let (Ok(seconds), Ok(seed)) = (args[4].parse::<f64>(), args[5].parse::<u64>()) else {
        eprintln!("SECONDS and SEED must be numbers");
        std::process::exit(2);
    };
    let (cfg, pattern) = preset_or_exit(&args[0], &args[1], trajectory(&args[2]), light(&args[3]), seed);
    (cfg, pattern, seconds)
}

#[cfg(test)]
mod test {
    use super::*;

    #[test]
    fn cache_is_taken_from_anywhere_and_a_bare_flag_is_left() {
        let mut a: Vec<String> = ["x", "--cache", "d", "y"].map(String::from).to_vec();
        assert_eq!(take_cache(&mut a), Some(PathBuf::from("d")));
        assert_eq!(a, ["x", "y"]);
        let mut b: Vec<String> = ["x", "--cache"].map(String::from).to_vec();
        assert_eq!(take_cache(&mut b), None);
        assert_eq!(b, ["x", "--cache"]);
        assert_eq!(trajectory("square"), Trajectory::Square);
        assert_eq!(light("low"), Light::Low);
    }
}
