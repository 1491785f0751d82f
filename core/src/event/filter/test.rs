use super::*;
use proptest::prelude::*;
use std::vec::Vec;

fn ev(t_us: u64) -> Event {
    Event { t_us, x: 1, y: 1, polarity: true }
}

/// Everything `f` passes on for `events`, the input ended after them.
fn run<const H: usize>(f: &mut InputFilter<H>, events: &[Event]) -> Vec<u64> {
    let mut out = Vec::new();
    for &e in events {
        out.extend(f.push(e).map(|e| e.t_us));
        while let Some(e) = f.pop() {
            out.push(e.t_us);
        }
    }
    f.finish();
    while let Some(e) = f.pop() {
        out.push(e.t_us);
    }
    out
}

/// `n` events 10 µs apart from `t0`.
fn steady(t0: u64, n: u64) -> Vec<u64> {
    (0..n).map(|k| t0 + 10 * k).collect()
}

fn events(ts: &[u64]) -> Vec<Event> {
    ts.iter().map(|&t| ev(t)).collect()
}

#[test]
fn out_of_sensor_and_back_in_time_are_counted_and_dropped() {
    let mut f: InputFilter = InputFilter::new(SensorSize::new(10, 5));
    let e = |t, x, y| Event { t_us: t, x, y, polarity: true };
    // The first event is held until enough events after it confirm its time.
    let mut input = vec![e(5, 0, 0), e(6, 10, 0), e(6, 0, 5), e(4, 9, 4), e(5, 9, 4)];
    input.extend((0..20).map(|k| e(6 + k, 1, 1)));
    let out = run(&mut f, &input);
    assert_eq!(&out[..2], &[5, 5], "equal timestamps are fine");
    assert_eq!(out.len(), 22);
    let s = f.stats();
    assert_eq!((s.accepted, s.out_of_sensor, s.time_backwards, s.time_jumps, s.dropped()), (22, 2, 1, 0, 3));
}

#[test]
fn one_stray_time_ahead_is_dropped_and_the_rest_kept() {
    let clean = steady(1_000_000, 200);
    let mut glitched = clean.clone();
    // An hour ahead, at a tenth of the way.
    glitched.insert(20, 3_600_000_000);
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&glitched)), clean);
    let s = f.stats();
    assert_eq!((s.accepted, s.time_backwards, s.time_jumps), (200, 0, 1));
    assert_eq!(s.largest_jump_us, 3_600_000_000 - clean[19]);
}

#[test]
fn a_stray_first_event_is_dropped() {
    // 9.3e12 s, in µs.
    let clean = steady(500, 100);
    let mut glitched = clean.clone();
    glitched.insert(0, 9_300_000_000_000_000_000);
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&glitched)), clean);
    let s = f.stats();
    assert_eq!((s.accepted, s.time_jumps, s.largest_jump_us), (100, 1, 9_300_000_000_000_000_000 - 500));
}

#[test]
fn a_stream_that_starts_out_of_order_is_back_in_time_not_stray() {
    // Reversed: nothing is far ahead of what follows, so the first event stands.
    let ts: Vec<u64> = steady(1_000_000, 100).into_iter().rev().collect();
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&ts)), [ts[0]]);
    assert_eq!((f.stats().time_backwards, f.stats().time_jumps), (99, 0));
}

#[test]
fn a_real_pause_passes() {
    // Ten seconds without an event, then the recording goes on.
    let mut ts = steady(0, 50);
    ts.extend(steady(10_000_000, 50));
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&ts)), ts);
    assert_eq!(f.stats().dropped(), 0);
    // Even a pause at the very end, with a single event after it.
    ts.push(20_000_000);
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&ts)), ts);
}

#[test]
fn a_burst_within_the_hold_is_dropped_a_longer_one_taken_as_real() {
    type F = InputFilter<8>;
    let confirm = F::CONFIRM as u64;
    let clean = steady(0, 100);
    // A burst of `confirm` events a minute ahead, at 30.
    let burst = |n: u64| {
        let mut ts = clean.clone();
        for k in 0..n {
            ts.insert(30 + k as usize, 60_000_000 + k);
        }
        ts
    };
    let mut f = F::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&burst(confirm))), clean);
    assert_eq!(f.stats().time_jumps, confirm);
    // One more and it is as many as the events that confirm a time: taken as real, and the
    // events after it are back in time (counted).
    let mut f = F::new(SensorSize::DAVIS346);
    let out = run(&mut f, &events(&burst(confirm + 1)));
    assert_eq!(out.len(), 30 + confirm as usize + 1);
    assert_eq!(f.stats().time_backwards, 70);
}

#[test]
fn equal_timestamps_after_a_pause_confirm_it() {
    let mut ts = steady(0, 10);
    ts.extend([5_000_000; 20]);
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    assert_eq!(run(&mut f, &events(&ts)), ts);
}

#[test]
fn a_full_hold_decides_without_pop_and_never_panics() {
    let mut f: InputFilter<4> = InputFilter::new(SensorSize::DAVIS346);
    let mut out = 0;
    for t in [9u64 << 60, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10] {
        out += usize::from(f.push(ev(t)).is_some());
    }
    f.finish();
    while f.pop().is_some() {
        out += 1;
    }
    let s = f.stats();
    assert_eq!(out as u64, s.accepted);
    assert_eq!(s.accepted + s.dropped(), 11);
    assert_eq!(s.time_jumps, 1);
}

#[test]
fn reset_starts_afresh() {
    let mut f: InputFilter = InputFilter::new(SensorSize::DAVIS346);
    let _ = run(&mut f, &events(&[5, 3, 1 << 40]));
    f.push(ev(7));
    f.reset(SensorSize::new(4, 4));
    assert_eq!((f.stats(), f.held(), f.sensor()), (InputStats::default(), 0, SensorSize::new(4, 4)));
}

/// A glitch: where it is inserted (before the real event of that index), ahead or back,
/// and by how much.
#[derive(Debug, Clone, Copy)]
struct Glitch {
    at: usize,
    ahead: bool,
    by: u64,
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// A monotone stream (steps of up to 2 ms, now and then a real pause of up to a day)
    /// with single-event glitches inserted, ahead or back in time, no two adjacent, none
    /// where a real pause follows within a hold (its followers could not tell it from the
    /// pause) and none within the last half-hold (nothing after it to tell): every real
    /// event is kept, in order, the output is in time order, and nothing is invented.
    #[test]
    fn every_event_but_the_glitches_is_kept(
        t0 in 0u64..1_000_000_000_000,
        steps in proptest::collection::vec((0u64..2000, 0u8..60, 100_000u64..86_400_000_000), 20..400),
        glitches in proptest::collection::vec((0usize..400, any::<bool>(), 0u64..1_000_000_000_000), 0..12),
    ) {
        type F = InputFilter<16>;
        let (hold, confirm) = (16usize, F::CONFIRM);
        let mut real = Vec::with_capacity(steps.len());
        let mut pause = Vec::with_capacity(steps.len());
        let mut t = t0;
        for (k, &(dt, p, long)) in steps.iter().enumerate() {
            let paused = k > 0 && p == 0;
            t += if paused { MAX_STEP_US + long } else { dt };
            real.push(t);
            pause.push(paused);
        }
        let n = real.len();
        let mut chosen: Vec<Glitch> = Vec::new();
        for &(at, ahead, by) in &glitches {
            let at = at % n;
            let calm = !pause[at..(at + hold + 1).min(n)].iter().any(|&p| p);
            let apart = chosen.iter().all(|g| g.at.abs_diff(at) >= 3);
            if at + confirm < n && calm && apart && (ahead || at > 0) {
                chosen.push(Glitch { at, ahead, by });
            }
        }
        chosen.sort_by_key(|g| g.at);
        let mut input = Vec::new();
        let mut is_glitch = Vec::new();
        let mut next = chosen.iter().peekable();
        for (k, &t) in real.iter().enumerate() {
            if let Some(g) = next.next_if(|g| g.at == k) {
                let before = if k == 0 { real[0] } else { real[k - 1] };
                // Ahead of the events before and after it by more than MAX_STEP_US (the
                // first event: of those after it).
                let gt = if g.ahead {
                    before.saturating_add(2 * MAX_STEP_US + g.by)
                } else {
                    before.saturating_sub(1 + g.by)
                };
                input.push(ev(gt));
                is_glitch.push(true);
            }
            input.push(ev(t));
            is_glitch.push(false);
        }
        let mut f = F::new(SensorSize::DAVIS346);
        let out = run(&mut f, &input);
        prop_assert!(out.windows(2).all(|w| w[0] <= w[1]), "out of order");
        // Every real event, in order, is in the output, which is a subsequence of the input.
        let mut it = out.iter().peekable();
        for (e, &g) in input.iter().zip(&is_glitch) {
            match it.peek() {
                Some(&&o) if o == e.t_us => {
                    it.next();
                }
                _ => prop_assert!(g, "real event at {} lost", e.t_us),
            }
        }
        prop_assert!(it.next().is_none(), "an event out that did not go in");
        let s = f.stats();
        prop_assert_eq!(s.accepted, out.len() as u64);
        prop_assert_eq!(s.accepted + s.dropped(), input.len() as u64);
        prop_assert_eq!(f.held(), 0);
    }

    /// Whatever the times: no panic, the output in time order, no more out than in, and
    /// every event counted once.
    #[test]
    fn any_stream_comes_out_in_order(
        ts in proptest::collection::vec(prop_oneof![0u64..1000, 0u64..10_000_000, any::<u64>()], 0..300),
        pops in any::<bool>(),
    ) {
        let mut f: InputFilter<8> = InputFilter::new(SensorSize::DAVIS346);
        let mut out = Vec::new();
        for &t in &ts {
            out.extend(f.push(ev(t)).map(|e| e.t_us));
            if pops {
                while let Some(e) = f.pop() {
                    out.push(e.t_us);
                }
            }
        }
        f.finish();
        while let Some(e) = f.pop() {
            out.push(e.t_us);
        }
        prop_assert!(out.windows(2).all(|w| w[0] <= w[1]));
        prop_assert!(out.len() <= ts.len());
        let s = f.stats();
        prop_assert_eq!(s.accepted, out.len() as u64);
        prop_assert_eq!(s.accepted + s.dropped(), ts.len() as u64);
    }
}
