//! Groups of views for the standard deviations: views of one stretch of a recording err
//! alike (a centre's error persists while the motion and the light it sees change little),
//! so the σ also comes from how such groups pull on the parameters, and that σ is widened
//! for how few groups there are.

/// Views within a stretch of this many seconds of the recording form one group for the
/// standard deviations ([`Options::view_times`](super::Options::view_times)). A centre's
/// error persists while the motion and the light it sees change little: far longer than a
/// window (33 ms) or the smoothing's reach (70 ms); half a second still leaves 8 groups in
/// 4 s of recording. Views in fewer stretches get shorter ones ([`group_seconds`]).
pub const GROUP_SECONDS: f64 = 0.5;
/// The shortest stretch a group of views may span, s: just over the 0.14 s over which
/// smoothing lets neighbouring views share windows, so that no view shares its events with
/// a group beyond the next. With it, 1.2 s of recording still make [`GROUPS_WANTED`] groups;
/// on 1.5 s of a simulated cone (8 seeds) their σ covered every error within 3σ, where the
/// points' own left cx beyond it in 3 seeds (docs/accuracy.md, "Short recordings").
pub const MIN_GROUP_SECONDS: f64 = 0.15;

/// How many groups the stretch is shortened for ([`group_seconds`]): from 8 groups up the
/// widening for so few ([`few_groups_factor`]) is at most ×1.6.
pub const GROUPS_WANTED: usize = 8;

/// Fewest groups of views a grouped covariance is made from. Fewer groups make a wider σ
/// ([`few_groups_factor`]: ×6.4 with 3, ×3.4 with 4), not a smaller one; two groups'
/// scatter is a single difference, which Student's t with one degree of freedom (a Cauchy)
/// would widen 78 times.
pub const MIN_GROUPS: usize = 3;

/// How many standard deviations evcal's claims are made in: its targets and its users read
/// an error within this many σ as covered.
pub const COVERAGE_SIGMAS: f64 = 3.0;

/// What the grouped covariance's σ is widened by, with `groups` groups of views.
///
/// A σ estimated from the scatter of G groups is itself uncertain, and an error over it
/// follows Student's t with G − 1 degrees of freedom, not a normal: with 16 groups (8 s of
/// recording) an error beyond 3 such σ is 3.3 times as likely as a normal's beyond 3σ. So
/// the grouped σ is scaled by t_{G−1}'s quantile over the normal's at [`COVERAGE_SIGMAS`],
/// so that the printed 3σ covers what a normal's does (Cameron and Miller 2015, on
/// cluster-robust inference with few clusters): ×6.4 with 3 groups, ×1.51 with 8, ×1.20
/// with 16, ×1.02 with 120 (a minute).
pub fn few_groups_factor(groups: usize) -> f64 {
    if groups < 2 {
        return f64::INFINITY;
    }
    student_t_quantile(normal_tail(COVERAGE_SIGMAS), (groups - 1) as f64) / COVERAGE_SIGMAS
}

/// The probability a standard normal lies beyond `z`.
fn normal_tail(z: f64) -> f64 {
    0.5 * statrs::function::erf::erfc(z / std::f64::consts::SQRT_2)
}

/// Student's t quantile with `nu` (> 0) degrees of freedom above which `tail` (in (0, 1)) of
/// it lies (statrs inverts the regularised incomplete beta function); NaN for no such `nu`.
/// Taken as minus the quantile below which `tail` lies, which the t is symmetric about 0
/// for: `1 − tail` would round away the digits of a small tail.
fn student_t_quantile(tail: f64, nu: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    StudentsT::new(0.0, 1.0, nu).map_or(f64::NAN, |t| -t.inverse_cdf(tail))
}

/// The stretch of the recording, s, whose views form one group for the standard deviations,
/// given each view's time (s): [`GROUP_SECONDS`], or the longest shorter one (the views'
/// span over a whole number, down to [`MIN_GROUP_SECONDS`]) that parts the views into
/// [`GROUPS_WANTED`] groups ([`groups_of`]). Views part into few groups when they span little
/// of the recording, or when the grid was seen in bursts (dim discs on part of a cone: the
/// views of 5 s in 5 half-seconds). Without groups the σ would take every point's error as
/// independent: on 3 s of a simulated cone that σ left the error of fy beyond 3σ in 5 of 8
/// seeds, and on 5 s of dim discs cy 5σ off (docs/notes/solve.md, "Short recordings",
/// "Views seen in bursts").
pub fn group_seconds(times: &[f64]) -> f64 {
    let (lo, hi) = times.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
    let span = hi - lo;
    if !span.is_finite() {
        return GROUP_SECONDS;
    }
    let enough = |g: f64| groups_of(times, g, 0.0).1 >= GROUPS_WANTED;
    if enough(GROUP_SECONDS) {
        return GROUP_SECONDS;
    }
    // The candidates are `span / n` for n from GROUPS_WANTED up while at least the floor;
    // the answer is the first that is at most GROUP_SECONDS and makes enough groups. Both
    // tests hold from some n on (fewer seconds make no fewer groups: [`groups_of`] starts a
    // group at the first view at least a stretch after the last start, and a shorter stretch
    // moves no start later), so the first is found by bisection: a walk through every n is
    // linear in the span, endless for a stray time centuries away.
    // The span is finite and at least 0 here: no stretch is NaN.
    let stretch = |n: u64| span / n as f64;
    let wanted = GROUPS_WANTED as u64;
    if stretch(wanted) < MIN_GROUP_SECONDS {
        return MIN_GROUP_SECONDS;
    }
    // The last n whose stretch is at least the floor (n as f64 exact below 2^53).
    let mut last = (span / MIN_GROUP_SECONDS).clamp(wanted as f64, MAX_EXACT_COUNT as f64) as u64;
    while last > wanted && stretch(last) < MIN_GROUP_SECONDS {
        last -= 1;
    }
    while last < MAX_EXACT_COUNT && stretch(last + 1) >= MIN_GROUP_SECONDS {
        last += 1;
    }
    let fits = |n: u64| stretch(n) <= GROUP_SECONDS && enough(stretch(n));
    if !fits(last) {
        return MIN_GROUP_SECONDS;
    }
    let (mut lo, mut hi) = (wanted, last);
    if fits(lo) {
        return stretch(lo);
    }
    // fits(lo) is false, fits(hi) true.
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    stretch(hi)
}

/// Largest count of stretches [`group_seconds`] divides a span by: beyond it the count is
/// not exact as an `f64` (2^53; a span of 2^63 µs over the floor is 6·10^13).
const MAX_EXACT_COUNT: u64 = 1 << 53;

/// Each view's group (in the order of `times`) and how many groups there are. In time order,
/// a group is a view and the views after it less than `group_s` seconds later; the next view
/// starts the next. So groups start at views, not at fixed times: a burst of views shorter
/// than a stretch, more than a stretch after the views before it, is one group (fixed cuts
/// of the recording could make two groups of one moment), and groups that start `group_s`
/// apart share no windows beyond their neighbours'. The
/// first group reaches `lead` seconds (less than `group_s`) back before the first view, so
/// that it ends that much sooner: where the groups' bounds fall is a choice, and
/// [`GROUP_PLACEMENTS`] of them are averaged.
pub fn groups_of(times: &[f64], group_s: f64, lead: f64) -> (Vec<u32>, usize) {
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].total_cmp(&times[b]));
    let mut groups = vec![0; times.len()];
    let (mut count, mut start) = (0u32, f64::NEG_INFINITY);
    for i in order {
        if count == 0 {
            (count, start) = (1, times[i] - lead);
        } else if times[i] - start >= group_s {
            // A NaN time (sorted last) joins the last group rather than starting its own.
            (count, start) = (count + 1, times[i]);
        }
        groups[i] = count - 1;
    }
    (groups, count as usize)
}

/// How many placements of the groups' bounds the grouped σ averages over: the first group
/// led by 0, ¼, ½ and ¾ of a stretch ([`groups_of`]). A σ from one placement is itself an
/// estimate from some sixteen sums, and which placement is arbitrary: on the simulator's
/// sweep moving the bounds alone moved σ(fx) by up to a quarter (docs/notes/solve.md,
/// "Views seen in bursts"). Averaging the placements' covariances, as overlapping batch
/// means do (Meketon and Schmeiser 1984), keeps what each says and less of its chance. Where
/// the views make fewer than [`GROUPS_WANTED`] groups, only the first placement is used: a
/// led one may cut a burst of views in two.
pub const GROUP_PLACEMENTS: usize = 4;

#[cfg(test)]
mod test {
    use super::*;

    fn every_33_ms(from: f64, to: f64) -> impl Iterator<Item = f64> {
        (0..((to - from) / 0.033) as u64).map(move |k| from + 0.033 * k as f64)
    }

    #[test]
    fn short_recordings_get_short_groups_down_to_the_floor() {
        let views = |seconds: f64| -> Vec<f64> { every_33_ms(0.0, seconds).collect() };
        assert_eq!(group_seconds(&views(8.0)), GROUP_SECONDS);
        assert_eq!(group_seconds(&views(4.2)), GROUP_SECONDS);
        assert_eq!(group_seconds(&views(1.0)), MIN_GROUP_SECONDS);
        assert_eq!(group_seconds(&views(0.3)), MIN_GROUP_SECONDS);
        assert_eq!(group_seconds(&[]), GROUP_SECONDS);
        // From 1.2 s of views up, the groups are short enough to be as many as a grouped σ needs.
        for seconds in [1.25, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0] {
            let times = views(seconds);
            let g = group_seconds(&times);
            assert!((MIN_GROUP_SECONDS..=GROUP_SECONDS).contains(&g), "{seconds} s: {g}");
            assert!(
                groups_of(&times, g, 0.0).1 >= GROUPS_WANTED,
                "{seconds} s: {} groups of {g} s",
                groups_of(&times, g, 0.0).1
            );
        }
    }

    #[test]
    fn a_group_is_a_view_and_those_within_the_stretch_after_it() {
        let (groups, count) = groups_of(&[0.9, 0.0, 0.1, 0.52, 0.6, 1.03], 0.5, 0.0);
        assert_eq!((groups, count), (vec![1, 0, 0, 1, 1, 2], 3));
        // A burst is one group wherever it lies on the clock.
        for t0 in [0.0, 0.49, 0.995] {
            let burst: Vec<f64> = (0..4).map(|k| t0 + 0.01 * k as f64).collect();
            assert_eq!(groups_of(&burst, 0.15, 0.0).1, 1, "burst at {t0}");
        }
        assert_eq!(groups_of(&[], 0.5, 0.0).1, 0);
        assert_eq!(groups_of(&[0.0, f64::NAN, 1.0], 0.5, 0.0).1, 2);
        // A lead ends the first group sooner and moves every bound after it.
        let (groups, count) = groups_of(&[0.0, 0.1, 0.3, 0.45, 0.6, 0.9], 0.5, 0.25);
        assert_eq!((groups, count), (vec![0, 0, 1, 1, 1, 2], 3));
    }

    #[test]
    fn views_in_bursts_get_groups_short_enough_to_be_enough() {
        // 5 s of a dim cone whose discs were found at its start and its end only: 0.5 s
        // stretches hold the views in 5 groups, too few for a grouped σ.
        let times: Vec<f64> =
            every_33_ms(0.0, 0.45).chain(every_33_ms(3.15, 3.85)).chain(every_33_ms(4.15, 5.0)).collect();
        assert!(groups_of(&times, GROUP_SECONDS, 0.0).1 < GROUPS_WANTED);
        let g = group_seconds(&times);
        assert!((MIN_GROUP_SECONDS..GROUP_SECONDS).contains(&g), "{g}");
        assert!(groups_of(&times, g, 0.0).1 >= GROUPS_WANTED, "{} groups of {g} s", groups_of(&times, g, 0.0).1);
        // The longest such stretch: the next longer candidate is one too few.
        let span = times[times.len() - 1] - times[0];
        let n = (span / g).round() as usize;
        assert!(groups_of(&times, span / (n - 1) as f64, 0.0).1 < GROUPS_WANTED);
        // Two bursts too short for any stretch to part them into enough groups: the floor.
        let few: Vec<f64> = every_33_ms(0.0, 0.3).chain(every_33_ms(4.0, 4.3)).collect();
        assert_eq!(group_seconds(&few), MIN_GROUP_SECONDS);
    }

    /// [`group_seconds`] as it was written first: every candidate stretch in turn (linear in
    /// the views' span).
    fn group_seconds_by_walk(times: &[f64]) -> f64 {
        let (lo, hi) = times.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| (lo.min(t), hi.max(t)));
        let span = hi - lo;
        if !span.is_finite() {
            return GROUP_SECONDS;
        }
        let enough = |g: f64| groups_of(times, g, 0.0).1 >= GROUPS_WANTED;
        if enough(GROUP_SECONDS) {
            return GROUP_SECONDS;
        }
        (GROUPS_WANTED..)
            .map(|n| span / n as f64)
            .take_while(|&g| g >= MIN_GROUP_SECONDS)
            .find(|&g| g <= GROUP_SECONDS && enough(g))
            .unwrap_or(MIN_GROUP_SECONDS)
    }

    #[test]
    fn the_stretch_is_found_by_bisection_as_the_walk_found_it_and_far_times_take_no_time() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(46);
        let mut cases: Vec<Vec<f64>> = Vec::new();
        for tenths in 1..=60 {
            cases.push(every_33_ms(0.0, tenths as f64 * 0.1).collect());
        }
        // Views in bursts, with views missed at random, some seen twice at one time.
        for _ in 0..300 {
            let mut times = Vec::new();
            let mut t = rng.random_range(0.0..100.0);
            for _ in 0..rng.random_range(1..8) {
                let len = rng.random_range(0.0..1.5);
                times.extend(every_33_ms(t, t + len).filter(|_| rng.random_range(0.0..1.0) < 0.8));
                t += len + rng.random_range(0.0..3.0);
            }
            if let Some(&first) = times.first() {
                times.push(first);
            }
            cases.push(times);
        }
        for times in &cases {
            assert_eq!(group_seconds(times).to_bits(), group_seconds_by_walk(times).to_bits(), "{times:?}");
        }
        // A view a stray time away (1e14 µs, 2^63 µs): the stretch still makes enough groups.
        for far in [1e8, 2f64.powi(63) * 1e-6] {
            let mut times: Vec<f64> = every_33_ms(0.0, 2.0).collect();
            times.push(far);
            let g = group_seconds(&times);
            assert!((MIN_GROUP_SECONDS..=GROUP_SECONDS).contains(&g), "{g}");
            assert!(groups_of(&times, g, 0.0).1 >= GROUPS_WANTED, "{far}: {g}");
            let next_longer = far / ((far / g).round() - 1.0);
            assert!(next_longer > GROUP_SECONDS || groups_of(&times, next_longer, 0.0).1 < GROUPS_WANTED, "{far}");
            // Too few views for enough groups at any stretch: the floor.
            assert_eq!(group_seconds(&[0.0, 0.5, far]), MIN_GROUP_SECONDS);
        }
    }

    /// Student's t quantile by the Cornish–Fisher expansion in 1/ν to its fourth term
    /// (Abramowitz and Stegun 26.7.5), at the probability a standard normal has below `z`:
    /// an independent reference for many degrees of freedom.
    fn cornish_fisher(z: f64, nu: f64) -> f64 {
        let (z3, z5, z7, z9) = (z.powi(3), z.powi(5), z.powi(7), z.powi(9));
        z + (z3 + z) / (4.0 * nu)
            + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * nu * nu)
            + (3.0 * z7 + 19.0 * z5 + 17.0 * z3 - 15.0 * z) / (384.0 * nu.powi(3))
            + (79.0 * z9 + 776.0 * z7 + 1482.0 * z5 - 1920.0 * z3 - 945.0 * z) / (92160.0 * nu.powi(4))
    }

    #[test]
    fn few_groups_widen_sigma_so_that_three_of_them_cover_as_a_normals_do() {
        // A standard normal beyond 3 (Abramowitz and Stegun, table 26.1).
        let p = normal_tail(COVERAGE_SIGMAS);
        assert!((p - 1.349_898e-3).abs() < 1e-9, "{p}");
        // One degree of freedom: a Cauchy, whose quantile is a tangent.
        let cauchy = (std::f64::consts::PI * (0.5 - p)).tan();
        assert!((student_t_quantile(p, 1.0) / cauchy - 1.0).abs() < 1e-9, "{}", student_t_quantile(p, 1.0));
        // Two: F(t) = 1/2 + t / (2 √(t² + 2)).
        let a = 1.0 - 2.0 * p;
        let two = a * 2f64.sqrt() / (1.0 - a * a).sqrt();
        assert!((few_groups_factor(3) * COVERAGE_SIGMAS / two - 1.0).abs() < 1e-9, "×{}", few_groups_factor(3));
        assert!((few_groups_factor(3) - 6.40).abs() < 0.01, "×{}", few_groups_factor(3));
        // Many: the series in 1/ν, within its 0.1 %.
        let mut last = f64::INFINITY;
        for groups in [3, 4, 5, 8, 12, 16, 41, 120] {
            let factor = few_groups_factor(groups);
            if groups >= 8 {
                let series = cornish_fisher(COVERAGE_SIGMAS, (groups - 1) as f64) / COVERAGE_SIGMAS;
                assert!((factor / series - 1.0).abs() < 1e-3, "{groups} groups: ×{factor} against ×{series}");
            }
            assert!(factor > 1.0 && factor < last, "{groups} groups: ×{factor}");
            last = factor;
        }
        assert!((few_groups_factor(16) - 1.195).abs() < 0.001, "{}", few_groups_factor(16));
        assert!(few_groups_factor(1).is_infinite());
        // The normal's limit: a million degrees of freedom, 3 (1 + 10 / (4 ν)) to first order.
        let limit = student_t_quantile(p, 1e6) / COVERAGE_SIGMAS;
        assert!((limit - 1.0 - 2.5e-6).abs() < 1e-8, "{limit}");
    }
}
