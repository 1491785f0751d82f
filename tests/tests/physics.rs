//! A corner of the physics sweep (`evcal_tests::sweep`, all of it: `cargo run --release -p
//! evcal-tests --example physics_sweep`), held to its targets: a slow photoreceptor in good
//! light on the spiral (little tilt: the focal length rests on how the image scales with
//! distance), a fast one in low light on the cone, and the cone out of focus. Each is a
//! continuous 8 s simulation, about a minute of CPU.

use evcal_host::sim::{Light, Trajectory};
use evcal_tests::sweep::{self, Case};

fn hold(case: Case) {
    let o = sweep::run(&case, "davis346", 8.0, None).unwrap_or_else(|e| panic!("{case:?}: no calibration: {e}"));
    let misses = o.misses(&case.targets());
    assert!(misses.is_empty(), "{case:?}: {o:?}: {}", misses.join("; "));
    assert!(o.views >= 100, "{case:?}: only {} views", o.views);
}

#[test]
fn spiral_good_light_300_hz() {
    hold(Case::base(Trajectory::Spiral, Light::Good, 300.0));
}

#[test]
fn cone_low_light_1000_hz() {
    hold(Case::base(Trajectory::Cone, Light::Low, 1000.0));
}

#[test]
fn cone_good_light_300_hz_out_of_focus() {
    hold(Case { blur_px: Some(2.5), ..Case::base(Trajectory::Cone, Light::Good, 300.0) });
}
