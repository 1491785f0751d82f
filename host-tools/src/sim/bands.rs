//! Work over the sensor's pixels in bands that the threads take as they come free, the
//! results in band order: the same output whatever the number of threads.

/// Pixels in a band of work that [`in_bands`] hands out: small enough that the threads share
/// the pixels near edges evenly (the board covers a part of the image), large enough that
/// handing out bands costs little.
pub(super) const BAND_PIXELS: usize = 1024;

/// `f` of every range of `band` in `0..n` (the last one shorter), the ranges shared among the
/// threads as they come free; the results in the ranges' order, whatever the threads.
pub(super) fn in_bands<T: Send>(n: usize, band: usize, f: impl Fn(std::ops::Range<usize>) -> T + Sync) -> Vec<T> {
    let band = band.max(1);
    let bands = n.div_ceil(band);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(8).min(bands);
    let next = std::sync::atomic::AtomicUsize::new(0);
    let work = || {
        let mut out = Vec::new();
        loop {
            let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if k >= bands {
                return out;
            }
            out.push((k, f(k * band..((k + 1) * band).min(n))));
        }
    };
    let mut done = if threads > 1 {
        std::thread::scope(|s| {
            let helpers: Vec<_> = (1..threads).map(|_| s.spawn(work)).collect();
            let mut done = work();
            for h in helpers {
                done.extend(h.join().expect("simulator band panicked"));
            }
            done
        })
    } else {
        work()
    };
    done.sort_unstable_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, r)| r).collect()
}
