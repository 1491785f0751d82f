//! Joining the pieces of one circle: crescents DBSCAN keeps apart, by the algebraic circle
//! through their union; then clusters whose fits overlap, fitted as one.

use super::*;

/// Largest RMS distance, px, of two clusters' events from the circle through their union for
/// the clusters to be joined: the edge's own spread (about half a pixel) and the motion
/// within a window, with room to spare, but well below what two neighbouring circles or a
/// circle and clutter leave.
pub(super) const JOIN_MAX_RMS: f32 = 1.0;

/// Joins clusters whose events lie on one circle (the crescents of a circle that DBSCAN
/// keeps apart, see [`process`]) and leaves the events grouped by the joined clusters.
/// Candidates are pairs whose bounding boxes are no further apart than the smaller box is
/// wide; they join when the algebraic circle through their union ([`Moments`]) passes within
/// [`JOIN_MAX_RMS`] of the events of each and is no larger than the union. Returns how many
/// clusters were joined to another; `starts` receives the algebraic circle of each
/// cluster as it is then (joined or not), to start its fit from, and `extents` its events'
/// [`Extent`].
pub(super) fn join_crescents<const N: usize, const C: usize>(
    clusterer: &mut Clusterer<N, C>,
    events: &mut [WindowEvent],
    t_ref: u32,
    starts: &mut heapless::Vec<Option<Circle>, C>,
    extents: &mut heapless::Vec<Extent, C>,
) -> u16 {
    let mut boxes: heapless::Vec<[u16; 4], C> = heapless::Vec::new();
    let mut sums: heapless::Vec<Moments, C> = heapless::Vec::new();
    extents.clear();
    for r in clusterer.group(events) {
        let part = slice(events, r);
        let (m, x) = Moments::of_with_extent(part, t_ref);
        let _ = boxes.push([x.x_lo, x.y_lo, x.x_hi, x.y_hi]);
        let _ = sums.push(m);
        let _ = extents.push(x);
    }
    let k = boxes.len();
    // Union-find over clusters, each root the lowest index of its set.
    let mut into = [0u16; C];
    for (c, slot) in into.iter_mut().enumerate() {
        *slot = c as u16;
    }
    let merged = join_pairs(&boxes, &sums, &mut into);
    // The joined clusters' sums, in the order `merge` numbers them (by their lowest member).
    // The extents are joined in place: a set's slot is at most its lowest member's index,
    // and every member comes after it, so no extent is overwritten before it is read.
    let mut joined: heapless::Vec<Moments, C> = heapless::Vec::new();
    let mut slot = [0u16; C];
    for c in 0..k {
        let r = root(&into, c);
        let own = extents.get(c).copied().unwrap_or(Extent::EMPTY);
        if r == c {
            slot[c] = joined.len() as u16;
            if let Some(x) = extents.get_mut(joined.len()) {
                *x = own;
            }
            let _ = joined.push(sums[c]);
        } else {
            if let Some(m) = joined.get_mut(usize::from(slot[r])) {
                m.add(&sums[c]);
            }
            if let Some(x) = extents.get_mut(usize::from(slot[r])) {
                x.join(&own);
            }
        }
    }
    extents.truncate(joined.len());
    starts.clear();
    for m in &joined {
        let _ = starts.push(m.circle());
    }
    if merged > 0 {
        clusterer.merge(events, &into[..k]);
    }
    merged
}

/// The root of cluster `c` in `into` (each root the lowest index of its set).
pub(super) fn root(into: &[u16], mut c: usize) -> usize {
    while let Some(&p) = into.get(c).filter(|&&p| usize::from(p) != c) {
        c = usize::from(p);
    }
    c
}

/// The pairs test of [`join_crescents`]: clusters with bounding boxes `boxes` (`[x_lo, y_lo,
/// x_hi, y_hi]`) and power sums `sums` that lie on one circle are joined in the union-find
/// `into` (each entry at first its own index). Returns how many joins were made.
pub(super) fn join_pairs<const C: usize>(boxes: &[[u16; 4]], sums: &[Moments], into: &mut [u16; C]) -> u16 {
    let k = boxes.len().min(sums.len()).min(C);
    // Each box's larger side: two crescents of one circle are no further apart than either
    // spans.
    let mut sizes = [0u16; C];
    for (s, b) in sizes.iter_mut().zip(boxes) {
        *s = b[2].wrapping_sub(b[0]).max(b[3].wrapping_sub(b[1]));
    }
    // The clusters by their boxes' top rows (DBSCAN numbers them nearly so: insertion is
    // quick), so that each meets only the boxes that start within its reach below it. The
    // sets that come out are the connected components of the pairs that join, whatever the
    // order the pairs are tried in, and every pair is tried as (lower index, higher index).
    let mut order = [0u16; C];
    for c in 0..k {
        let mut at = c;
        while at > 0 && boxes[usize::from(order[at - 1])][1] > boxes[c][1] {
            order[at] = order[at - 1];
            at -= 1;
        }
        order[at] = c as u16;
    }
    let mut merged = 0u16;
    for (p, &oi) in order[..k].iter().enumerate() {
        let oi = usize::from(oi);
        let (top_a, reach) = (boxes[oi], sizes[oi]);
        for &oj in &order[p + 1..k] {
            let oj = usize::from(oj);
            // Every later box starts at least this far below this one.
            if boxes[oj][1].saturating_sub(top_a[3]) > reach {
                break;
            }
            let (i, j) = if oi < oj { (oi, oj) } else { (oj, oi) };
            let (a, b) = (boxes[i], boxes[j]);
            let gap = a[0].max(b[0]).saturating_sub(a[2].min(b[2])).max(a[1].max(b[1]).saturating_sub(a[3].min(b[3])));
            if gap > sizes[i].min(sizes[j]) {
                continue;
            }
            let (ri, rj) = (root(&into[..], i), root(&into[..], j));
            if ri == rj {
                continue;
            }
            let extent = f32::from(a[2].max(b[2]) - a[0].min(b[0])).max(f32::from(a[3].max(b[3]) - a[1].min(b[1])));
            let joins = sums[i]
                .joint_radius(&sums[j])
                .is_some_and(|(r, ra, rb)| r > 0.5 && r <= extent && ra <= JOIN_MAX_RMS && rb <= JOIN_MAX_RMS);
            if joins {
                let (lo, hi) = if ri < rj { (ri, rj) } else { (rj, ri) };
                into[hi] = lo as u16;
                merged += 1;
            }
        }
    }
    merged
}

/// Whether two fits may be fragments of one circle: each centre lies inside the other circle
/// (two circles of a grid never overlap like that).
fn overlapping(a: &Centre, b: &Centre) -> bool {
    let (du, dv) = (a.u - b.u, a.v - b.v);
    // The larger radius, without a library call (fitted radii are never NaN).
    let r = if a.r < b.r { b.r } else { a.r };
    du * du + dv * dv <= r * r
}

/// Weighted spread, px, beyond which a cluster's own fit gives up from its second pass on
/// (see [`fit_within`](crate::fit::fit_within); tighter than [`MAX_SPREAD`](crate::fit::MAX_SPREAD)). A circle's
/// edge leaves well under a pixel (simulated DAVIS346 cone: no fit that matched a circle
/// ended beyond 0.88 px), and fragments that join stay within 1.5 px (see
/// [`JOIN_MAX_PART_SPREAD`]); the fits beyond are clutter, which ran its remaining
/// iterations only to end between 1.5 and 3 px. The detection tests (DAVIS346 cone good and
/// low light, DVXplorer spiral): 1.75 px changed one circle of 984 in low light (found 80.8
/// -> 80.7 %, centre RMS 0.317 -> 0.316 px), nothing else; 1.5 px lost three (80.6 %, 0.318
/// px; 92.0 -> 91.9 % on the spiral). On the M4F it saves 0.11 M instructions a window.
pub(super) const CLUSTER_GIVE_UP: f32 = 1.75 * JOIN_MAX_SPREAD;

/// Largest weighted spread, px, of the fit to two joined fragments for the join to stand.
const JOIN_MAX_SPREAD: f32 = 1.0;

/// Largest weighted spread, px, of either fragment's own fit for their union to be fitted.
/// A subset of events is fitted at least as closely by its own circle as by any other, so a
/// fragment spread this much (clutter, or a straight edge fitted as a huge circle whose
/// centre then lies inside every circle nearby) makes a union that cannot meet
/// [`JOIN_MAX_SPREAD`]; fitting it anyway cost a few windows several times the usual. On
/// four simulated recordings (349 windows) no join had a fragment beyond 1.5 px, and this
/// skips 1261 of the 1509 union fits that failed, 95 % of their events.
const JOIN_MAX_PART_SPREAD: f32 = 2.0 * JOIN_MAX_SPREAD;

/// Weighted spread, px, beyond which a union's fit gives up from its second pass on (see
/// [`fit_within`](crate::fit::fit_within)): the join could not stand. Measured on five simulated recordings (DAVIS346
/// cone good and low light, 4x11, and square low light, 3x7; DVXplorer spiral 3x9; 465 union
/// fits that joined, 111 that failed): a union that joined was within 1.37 px at its second
/// pass (low light; within 1.01 px on the others), and giving up beyond 1.75 px loses none
/// of them while it skips most of the failed unions' passes, the costliest work of the
/// slowest windows.
const JOIN_GIVE_UP: f32 = 1.75 * JOIN_MAX_SPREAD;

/// The second joining stage: clusters whose robust fits overlap (a crescent that DBSCAN also
/// tied to a little clutter or noise, which the algebraic test of [`join_crescents`] cannot
/// see past, or two sparse crescents each fitted as a smaller circle) are fitted as one; the
/// join stands when that fit is good (spread within [`JOIN_MAX_SPREAD`]). The events of the
/// later cluster are moved next to the earlier one's. Returns how many were joined.
pub(super) fn join_fitted<const C: usize>(
    events: &mut [WindowEvent],
    ranges: &mut heapless::Vec<ClusterRange, C>,
    extents: &mut heapless::Vec<Extent, C>,
    fits: &mut heapless::Vec<Option<Centre>, C>,
    t_ref: u32,
    cfg: &FitConfig,
    scratch: &mut [[f32; 3]],
) -> u16 {
    let mut merged = 0u16;
    let mut i = 0;
    while i < ranges.len() {
        let mut j = i + 1;
        let mut grew = false;
        while j < ranges.len() {
            // Borrowed, not copied: most pairs are far apart.
            let candidate = match (fits.get(i), fits.get(j)) {
                (Some(Some(a)), Some(Some(b))) => {
                    overlapping(a, b) && !(a.spread > JOIN_MAX_PART_SPREAD || b.spread > JOIN_MAX_PART_SPREAD)
                }
                _ => false,
            };
            if !candidate {
                j += 1;
                continue;
            }
            let (ri, rj) = (ranges[i], ranges[j]);
            let extent = match (extents.get(i), extents.get(j)) {
                (Some(a), Some(b)) => Some({
                    let mut x = *a;
                    x.join(b);
                    x
                }),
                _ => None,
            };
            let parts = [slice(events, &ri), slice(events, &rj)];
            let union = fit_in(&parts, extent.as_ref(), None, t_ref, cfg, scratch, JOIN_GIVE_UP);
            let Some(u) = union.filter(|u| u.spread <= JOIN_MAX_SPREAD) else {
                j += 1;
                continue;
            };
            // Ranges are in event order: rotate j's events to just after i's.
            let len_j = rj.end - rj.start;
            if let Some(seg) = events.get_mut(usize::from(ri.end)..usize::from(rj.end)) {
                seg.rotate_right(usize::from(len_j));
            }
            for r in ranges.iter_mut().take(j).skip(i + 1) {
                r.start += len_j;
                r.end += len_j;
            }
            ranges[i].end += len_j;
            ranges.remove(j);
            if let (Some(x), Some(slot)) = (extent, extents.get_mut(i)) {
                *slot = x;
            }
            if j < extents.len() {
                extents.remove(j);
            }
            fits.remove(j);
            fits[i] = Some(u);
            merged += 1;
            grew = true;
        }
        // The union's fit may now overlap clusters passed over before.
        if !grew {
            i += 1;
        }
    }
    merged
}
