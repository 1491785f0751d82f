//! Fuzzes the input filter's time ordering on arbitrary event times (steps forward and back,
//! stray times far ahead, the hold left full): nothing may panic, what comes out is in time
//! order, never more than went in, and every event is counted once.
#![no_main]

use evcal_core::event::{Event, InputFilter, SensorSize};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&head, body)) = data.split_first() else { return };
    // The first byte: whether the caller pops after every push (or leaves the hold to fill).
    let pops = head & 1 == 1;
    let mut f: InputFilter<8> = InputFilter::new(SensorSize::new(64, 64));
    let mut big: InputFilter = InputFilter::new(SensorSize::new(64, 64));
    let (mut out, mut out_big) = (Vec::new(), Vec::new());
    let mut t = 0u64;
    let mut n = 0u64;
    // Events of 4 bytes: a time step (kind and size), x, y.
    for e in body.chunks_exact(4) {
        let step = u64::from(e[1]);
        t = match e[0] % 4 {
            0 | 1 => t.saturating_add(step),
            2 => t.saturating_sub(step),
            // A stray time far ahead (or anywhere), not moving the stream on.
            _ => {
                let stray = t.wrapping_add(step << (e[0] / 4 % 64));
                push(&mut f, stray, e, pops, &mut out);
                push(&mut big, stray, e, true, &mut out_big);
                n += 1;
                continue;
            }
        };
        push(&mut f, t, e, pops, &mut out);
        push(&mut big, t, e, true, &mut out_big);
        n += 1;
    }
    for (f, out) in [(&mut f as &mut dyn Finish, &mut out), (&mut big as &mut dyn Finish, &mut out_big)] {
        f.end(out);
        assert!(out.windows(2).all(|w| w[0] <= w[1]), "out of time order");
        assert!(out.len() as u64 <= n);
        let (accepted, dropped) = f.counts();
        assert_eq!(accepted, out.len() as u64);
        assert_eq!(accepted + dropped, n);
    }
});

fn push<const H: usize>(f: &mut InputFilter<H>, t: u64, e: &[u8], pops: bool, out: &mut Vec<u64>) {
    let ev = Event { t_us: t, x: u16::from(e[2] % 72), y: u16::from(e[3] % 72), polarity: true };
    out.extend(f.push(ev).map(|e| e.t_us));
    if pops {
        while let Some(e) = f.pop() {
            out.push(e.t_us);
        }
    }
}

/// The end of the input, for filters of any hold.
trait Finish {
    fn end(&mut self, out: &mut Vec<u64>);
    fn counts(&self) -> (u64, u64);
}

impl<const H: usize> Finish for InputFilter<H> {
    fn end(&mut self, out: &mut Vec<u64>) {
        self.finish();
        while let Some(e) = self.pop() {
            out.push(e.t_us);
        }
    }

    fn counts(&self) -> (u64, u64) {
        (self.stats().accepted, self.stats().dropped())
    }
}
