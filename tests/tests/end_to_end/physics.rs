//! A corner of the physics sweep (`evcal_tests::sweep`, all of it: `cargo run --release -p
//! evcal-tests --example physics_sweep`), held to its targets: a slow photoreceptor in good
//! light on the spiral (little tilt: the focal length rests on how the image scales with
//! distance), a fast one in low light on the cone, and the cone out of focus. Each is a
//! continuous 8 s simulation, about a minute of CPU: the slow tier runs them ([`slow`]), and
//! CI's fast tier a smoke case ([`cone_low_light_1000_hz_smoke`]).

use evcal_host::sim::{Light, Trajectory};
use evcal_tests::sweep::{self, Case};

/// Runs `seconds` of `case` and holds it to the sweep's targets for it, with at least
/// `min_views` views.
fn hold(case: Case, seconds: f64, min_views: usize) {
    let o = sweep::run(&case, "davis346", seconds, None).unwrap_or_else(|e| panic!("{case:?}: no calibration: {e}"));
    println!("{case:?} {seconds} s: {o:?}");
    let misses = o.misses(&case.targets());
    assert!(misses.is_empty(), "{case:?}: {o:?}: {}", misses.join("; "));
    assert!(o.views >= min_views, "{case:?}: only {} views", o.views);
}

/// The fast pixel in low light on 3 s of the cone: the slow tier's case at a third of its
/// length, held to the same targets (the cone's tilt fixes the focal length within them on
/// 3 s too).
#[test]
fn cone_low_light_1000_hz_smoke() {
    hold(Case::base(Trajectory::Cone, Light::Low, 1000.0), 3.0, 40);
}

/// The three corners at full length (8 s, some 100 views or more each).
mod slow {
    use super::*;

    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn spiral_good_light_300_hz() {
        hold(Case::base(Trajectory::Spiral, Light::Good, 300.0), 8.0, 100);
    }

    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn cone_low_light_1000_hz() {
        hold(Case::base(Trajectory::Cone, Light::Low, 1000.0), 8.0, 100);
    }

    #[test]
    #[ignore = "slow tier: bash scripts/test-slow.sh"]
    fn cone_good_light_300_hz_out_of_focus() {
        hold(Case { blur_px: Some(2.5), ..Case::base(Trajectory::Cone, Light::Good, 300.0) }, 8.0, 100);
    }
}
