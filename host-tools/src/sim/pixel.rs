//! One DVS pixel over one step: its state, the events its log intensity's change fires (an
//! ideal pixel's, or one with a photoreceptor's lag and a leaking reference), and how long a
//! still pixel may be left alone.

/// Threshold crossings (pixel, time, +1/−1).
pub(super) type Crossings = Vec<(usize, f64, f64)>;

#[derive(Debug, Clone, Copy)]
pub(super) struct PixelState {
    /// Log intensity at the last evaluation.
    pub(super) level: f64,
    /// Log intensity of the last event (the reference the thresholds count from).
    pub(super) reference: f64,
    pub(super) on: f64,
    pub(super) off: f64,
    /// Time of the last event, s.
    pub(super) last: f64,
    /// The photoreceptor's output, log units: `level` filtered by the photoreceptor's low-pass
    /// ([`PixelModel::photoreceptor_hz`](super::PixelModel::photoreceptor_hz)); the level events are fired from. Equal to `level`
    /// without physics.
    pub(super) lp: f64,
    /// Time of the last evaluation, s: a skipped pixel's filter and leak are brought from there
    /// to the step that next evaluates it. Unused without physics.
    pub(super) evaluated: f64,
    /// How fast the reference leaks down, log units per second (the leak rate times the ON
    /// threshold).
    pub(super) leak: f64,
}

impl PixelState {
    /// The level of the next event a pixel at `level` fires, and its sign (+1 ON, −1 OFF):
    /// a threshold away from the reference; `None` within both thresholds.
    fn crossing(&self, level: f64) -> Option<(f64, f64)> {
        if level - self.reference >= self.on {
            Some((self.reference + self.on, 1.0))
        } else if self.reference - level >= self.off {
            Some((self.reference - self.off, -1.0))
        } else {
            None
        }
    }
}

/// Longest a skipped pixel with leak waits before it is looked at again, s: bounds how far
/// the leak can move its reference unseen (see [`quiet_for`]).
const LEAK_LOOK_S: f64 = 0.5;

/// An ideal pixel (unlimited bandwidth, no leak) from `t0` to `t1`, its log intensity moving
/// linearly to `l1`: the threshold crossings of the log intensity itself, interpolated within
/// the step, pushed to `events` as pixel `p`'s.
pub(super) fn ideal_update(
    st: &mut PixelState,
    l1: f64,
    t0: f64,
    t1: f64,
    refractory: f64,
    p: usize,
    events: &mut Crossings,
) {
    let l0 = st.level;
    while let Some((level, sign)) = st.crossing(l1) {
        let span = l1 - l0;
        let frac = if span.abs() > 1e-12 { ((level - l0) / span).clamp(0.0, 1.0) } else { 1.0 };
        let tc = (t0 + frac * (t1 - t0)).max(st.last + refractory);
        if tc > t1 {
            break; // still blind: fires in a later step if the change persists
        }
        events.push((p, tc, sign));
        st.reference = level;
        st.last = tc;
    }
    st.level = l1;
    st.lp = l1;
}

/// The photoreceptor's time constant over a step in which the log intensity moves linearly
/// from `l0` to `l1`, s ([`PixelModel::photoreceptor_hz`](super::PixelModel::photoreceptor_hz); 0 for an unlimited bandwidth).
/// The filter's rate is proportional to the intensity, so its mean over the step is taken: the
/// logarithmic mean of the intensities at the ends.
fn tau_over(cutoff_hz: f64, l0: f64, l1: f64) -> f64 {
    if !cutoff_hz.is_finite() {
        return 0.0;
    }
    let (i0, i1) = (l0.exp(), l1.exp());
    let mean = if (l1 - l0).abs() > 1e-9 { (i1 - i0) / (l1 - l0) } else { 0.5 * (i0 + i1) };
    1.0 / (std::f64::consts::TAU * cutoff_hz * mean)
}

/// The photoreceptor's output `h` seconds into a step that starts at `y0` with input
/// `x0 + s·h`: the exact solution of dy/dt = (x − y)/τ for a linear input,
/// y = x0 + s·(h − τ) + (y0 − x0 + s·τ)·e^(−h/τ), written with expm1 so that a slow filter
/// (τ of seconds in a step of microseconds) keeps its precision. τ = 0 follows the input.
fn filtered(y0: f64, x0: f64, s: f64, tau: f64, h: f64) -> f64 {
    if tau <= 0.0 {
        return x0 + s * h;
    }
    y0 + (x0 - y0 - s * tau) * -(-h / tau).exp_m1() + s * h
}

/// Bisections that place a crossing within a step: 2⁻²⁴ of a step of at most 2 ms is far
/// below the timestamps' microsecond.
const CROSSING_ITERATIONS: usize = 24;

/// A pixel with physics ([`PixelModel::physics`](super::PixelModel::physics)) from `t0` to `t1`, its log intensity moving
/// linearly to `l1`: its photoreceptor filtered exactly over the step, its reference leaking,
/// and the threshold crossings of the filtered level pushed to `events` as pixel `p`'s.
#[allow(clippy::too_many_arguments)]
pub(super) fn physical_update(
    st: &mut PixelState,
    l1: f64,
    t0: f64,
    t1: f64,
    refractory: f64,
    cutoff_hz: f64,
    p: usize,
    events: &mut Crossings,
) {
    let l0 = st.level;
    if st.evaluated < t0 {
        // Skipped since: its input stayed at its level, and no crossing was due (quiet_for).
        let gap = t0 - st.evaluated;
        st.lp = filtered(st.lp, l0, 0.0, tau_over(cutoff_hz, l0, l0), gap);
        st.reference -= st.leak * gap;
    }
    let dt = (t1 - t0).max(0.0);
    let s = if dt > 0.0 { (l1 - l0) / dt } else { 0.0 };
    let tau = tau_over(cutoff_hz, l0, l1);
    let (y0, k) = (st.lp, st.leak);
    // The leak moves the reference down at k; within the step the reference is held and the
    // level raised instead, z = y + k·h, so that crossings are those of one curve.
    let z = |h: f64| filtered(y0, l0, s, tau, h) + k * h;
    // Without a filter the step ends at l1 itself, not at l0 + s·dt a rounding away: the
    // ideal pixel's comparisons, bit for bit.
    let y1 = if tau <= 0.0 { l1 } else { filtered(y0, l0, s, tau, dt) };
    let z1 = y1 + k * dt;
    let mut from = 0.0;
    while let Some((level, sign)) = st.crossing(z1) {
        let h = if tau <= 0.0 {
            // Linear: interpolated as the ideal pixel does.
            let (za, span) = (z(from), z1 - z(from));
            let frac = if span.abs() > 1e-12 { ((level - za) / span).clamp(0.0, 1.0) } else { 1.0 };
            from + frac * (dt - from)
        } else {
            // z(from) has not reached the level, z(dt) has.
            let (mut lo, mut hi) = (from, dt);
            for _ in 0..CROSSING_ITERATIONS {
                let mid = 0.5 * (lo + hi);
                if (z(mid) - level) * sign >= 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            hi
        };
        let tc = (t0 + h).max(st.last + refractory);
        if tc > t1 {
            break; // still blind: fires in a later step
        }
        events.push((p, tc, sign));
        st.reference = level;
        st.last = tc;
        from = h;
    }
    st.reference -= k * dt;
    st.level = l1;
    st.lp = y1;
    st.evaluated = t1;
}

/// How long after its last evaluation a pixel whose input stays at its level fires no event,
/// s, `most` at most: a lower bound of the time its settling filter and leaking reference
/// take to a threshold crossing, so that it can be skipped until then.
pub(super) fn quiet_for(st: &PixelState, cutoff_hz: f64, most: f64) -> f64 {
    let (l, y, k) = (st.level, st.lp, st.leak);
    let tau = tau_over(cutoff_hz, l, l);
    // When the settling filter, y(h) = l + (y − l)·e^(−h/τ), first reaches v from below and
    // from above.
    let up = |v: f64| {
        if y >= v {
            0.0
        } else if v < l && tau > 0.0 {
            tau * ((l - y) / (l - v)).ln()
        } else {
            f64::INFINITY
        }
    };
    let down = |v: f64| {
        if y <= v {
            0.0
        } else if v > l && tau > 0.0 {
            tau * ((y - l) / (v - l)).ln()
        } else {
            f64::INFINITY
        }
    };
    let on_level = st.reference + st.on;
    // ON fires when y + k·h reaches on_level. y stays below max(y, l), which bounds h from
    // the leak's side; and within a horizon the leak adds at most k·horizon, which bounds it
    // from the filter's side. The leak's look-ahead is kept short so that bound stays tight.
    let on = if k > 0.0 {
        let horizon = most.min(LEAK_LOOK_S);
        ((on_level - y.max(l)) / k).max(horizon.min(up(on_level - k * horizon)))
    } else {
        up(on_level)
    };
    // The leak only delays OFF.
    let off = down(st.reference - st.off);
    most.min(on).min(off).max(0.0)
}

#[cfg(test)]
mod test {
    use super::*;
    use crate::sim::scene;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A pixel with thresholds of 0.25 at rest at log intensity `l`, its last event long ago.
    fn pixel_at(l: f64) -> PixelState {
        PixelState {
            level: l,
            reference: l,
            on: 0.25,
            off: 0.25,
            last: f64::NEG_INFINITY,
            lp: l,
            evaluated: 0.0,
            leak: 0.0,
        }
    }

    /// The events of a pixel at rest at `from` whose light steps to `to` at time 0, followed
    /// for `seconds` in steps of `dt`, with the photoreceptor at `cutoff_hz`.
    fn step_response(from: f64, to: f64, cutoff_hz: f64, seconds: f64, dt: f64) -> Crossings {
        let mut st = pixel_at(from);
        st.level = to; // the step: the input is at `to` from the first instant
        let mut events = Vec::new();
        let mut t = 0.0;
        while t < seconds {
            physical_update(&mut st, to, t, t + dt, 100e-6, cutoff_hz, 0, &mut events);
            t += dt;
        }
        events
    }

    /// First-order filter: y = ΔL·(1 − e^(−t/τ)) reaches θ at τ·ln(ΔL / (ΔL − θ)).
    fn first_order_delay(from: f64, to: f64, cutoff_hz: f64) -> f64 {
        let tau = 1.0 / (std::f64::consts::TAU * cutoff_hz * to.exp());
        let dl = (to - from).abs();
        tau * (dl / (dl - 0.25)).ln()
    }

    #[test]
    fn a_step_of_light_fires_after_the_first_order_filter_delay_and_later_in_the_dark() {
        let mut last_delay = 0.0;
        // The same contrast (a doubling of light) at falling light levels.
        for bright in [0.8f64, 0.2, 0.05, 0.01] {
            let (from, to) = ((bright / 2.0).ln(), bright.ln());
            let expected = first_order_delay(from, to, 300.0);
            let ev = step_response(from, to, 300.0, 20.0 * expected, expected / 7.3);
            let (_, t, sign) = ev[0];
            assert_eq!(sign, 1.0);
            // The bisection places it within 2⁻²⁴ of a step.
            assert!((t - expected).abs() < 2e-8 * expected, "light {bright}: {t} s, model {expected} s");
            assert!(t > last_delay, "light {bright}: {t} s is not later than {last_delay} s");
            last_delay = t;
            // The filter settles at ΔL = ln 2: two thresholds, two events.
            assert_eq!(ev.len(), 2, "light {bright}");
        }
        // 300 Hz at light 0.8: τ = 0.66 ms and the first event after 0.30 ms; at 0.01,
        // τ = 53 ms and 24 ms.
        assert!(last_delay > 0.02, "{last_delay}");
    }

    #[test]
    fn off_edges_into_the_dark_lag_more_than_on_edges_into_the_bright() {
        let (paper, ink) = ((scene::PAPER + 0.004f64).ln(), (scene::INK + 0.004f64).ln());
        for (illumination, cutoff) in [(1.0f64, 300.0), (0.05, 300.0), (1.0, 1000.0)] {
            let (paper, ink) = (paper + illumination.ln(), ink + illumination.ln());
            let on = step_response(ink, paper, cutoff, 1.0, 1e-5);
            let off = step_response(paper, ink, cutoff, 1.0, 1e-5);
            assert!(on.iter().all(|e| e.2 > 0.0) && off.iter().all(|e| e.2 < 0.0));
            // Each edge steps ln(0.854 / 0.064) = 2.6: ten thresholds.
            assert_eq!((on.len(), off.len()), (10, 10));
            let (t_on, t_off) = (on[0].1, off[0].1);
            assert!((t_on - first_order_delay(ink, paper, cutoff)).abs() < 2e-6, "{t_on}");
            assert!((t_off - first_order_delay(paper, ink, cutoff)).abs() < 2e-6, "{t_off}");
            // The filter is as much faster as the light is brighter.
            assert!((t_off / t_on - (paper - ink).exp()).abs() < 0.05 * (paper - ink).exp(), "{t_on} {t_off}");
            // And the whole edge: its last event.
            assert!(off[9].1 > 3.0 * on[9].1, "{} {}", on[9].1, off[9].1);
        }
    }

    #[test]
    fn unlimited_bandwidth_without_leak_is_the_ideal_pixel() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (mut a, mut b) = (pixel_at(0.0), pixel_at(0.0));
        let (mut ea, mut eb) = (Vec::new(), Vec::new());
        let mut t = 0.0;
        for _ in 0..10_000 {
            let l1 = (a.level + rng.random_range(-0.3..0.3)).clamp(-4.0, 0.0);
            let dt = rng.random_range(1e-5..1e-3);
            ideal_update(&mut a, l1, t, t + dt, 100e-6, 0, &mut ea);
            physical_update(&mut b, l1, t, t + dt, 100e-6, f64::INFINITY, 0, &mut eb);
            t += dt;
        }
        assert!(ea.len() > 1000);
        // The same crossings, interpolated from the step's start or from the crossing before.
        same_times(&ea, &eb);
        assert_eq!(a.level, b.level);
        assert!((a.reference - b.reference).abs() < 1e-12);
    }

    /// A still pixel followed on a grid of `dt` steps, evaluated at every step or only when
    /// [`quiet_for`] says it could fire (as the simulator skips it).
    fn still_pixel(mut st: PixelState, cutoff_hz: f64, seconds: f64, dt: f64, skip: bool) -> (Crossings, usize) {
        let (mut events, mut evaluations) = (Vec::new(), 0);
        let l = st.level;
        let mut next = 0.0;
        let mut t = 0.0;
        while t < seconds {
            if !skip || next <= t + dt {
                physical_update(&mut st, l, t, t + dt, 100e-6, cutoff_hz, 0, &mut events);
                evaluations += 1;
                next = t + dt + quiet_for(&st, cutoff_hz, 10.0);
            }
            t += dt;
        }
        (events, evaluations)
    }

    fn same_times(a: &Crossings, b: &Crossings) {
        assert_eq!(a.len(), b.len(), "different numbers of events");
        for (x, y) in a.iter().zip(b) {
            assert_eq!(x.2, y.2);
            assert!((x.1 - y.1).abs() < 1e-9, "{} vs {}", x.1, y.1);
        }
    }

    #[test]
    fn leak_fires_on_events_at_its_rate_and_skipping_misses_none() {
        let mut st = pixel_at(-1.0);
        st.leak = 0.2 * st.on; // 0.2 Hz
        st.reference -= 0.1;
        let (dense, _) = still_pixel(st, 300.0, 60.0, 1e-3, false);
        let (skipped, evaluations) = still_pixel(st, 300.0, 60.0, 1e-3, true);
        assert!(dense.iter().all(|e| e.2 > 0.0));
        assert_eq!(dense.len(), 12); // the first after (0.25 − 0.1)/0.05 = 3 s, then every 5 s
        assert!((dense[0].1 - 3.0).abs() < 1e-6 && (dense[1].1 - 8.0).abs() < 1e-6, "{:?}", &dense[..2]);
        same_times(&dense, &skipped);
        assert!(evaluations < 400, "{evaluations} evaluations in 60 s");
    }

    #[test]
    fn a_settling_filter_fires_when_skipped_as_when_followed() {
        // Just past an OFF edge into ink in a dim room: the filter has far to go (τ ≈ 0.1 s).
        let mut st = pixel_at((0.05f64 * 0.06 + 0.004).ln());
        st.lp = st.level + 2.0;
        st.reference = st.lp - 0.1;
        st.leak = 0.1 * st.on;
        let (dense, _) = still_pixel(st, 300.0, 3.0, 1e-4, false);
        let (skipped, evaluations) = still_pixel(st, 300.0, 3.0, 1e-4, true);
        // (2 − 0.1) / 0.25: seven OFF events as it settles.
        assert_eq!(dense.len(), 7);
        assert!(dense.iter().all(|e| e.2 < 0.0));
        same_times(&dense, &skipped);
        assert!(evaluations < 100, "{evaluations} evaluations of 30000 steps");
    }
}
