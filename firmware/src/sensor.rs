//! A sensor's control lines: its reset line (an [`OutputPin`]) and its control bus (an
//! [`I2c`]), whatever board or HAL provides them.
//!
//! This is the minimal hook a sensor-fed device starts from, and all evcal does with a
//! sensor's control side: it pulses the reset line, finds which addresses answer on the bus
//! (an address-only write each, which no device acts on), and writes byte strings the caller
//! gives it in order ([`SensorControl::configure`]). evcal ships no sensor's register values:
//! what to write to bring a particular sensor up comes from its datasheet, and the event
//! stream itself arrives elsewhere (a parallel or SPI interface read as an
//! [`EvtSource`](crate::evt::EvtSource)).
//!
//! The reset line is taken as active low (held low, the sensor is in reset), as most image
//! sensors' reset inputs are.

use embedded_hal::{
    delay::DelayNs,
    digital::OutputPin,
    i2c::{Error as _, ErrorKind, I2c, SevenBitAddress},
};

/// How long the reset line is held low, and how long the sensor is left to start before the
/// bus is used. The defaults are generous round figures, not any sensor's datasheet: use the
/// sensor's own where they are known.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResetTiming {
    /// Reset held low, µs.
    pub low_us: u32,
    /// After release, before the first bus transfer, µs.
    pub settle_us: u32,
}

impl Default for ResetTiming {
    fn default() -> Self {
        Self { low_us: 1_000, settle_us: 10_000 }
    }
}

/// The 7-bit addresses a bus scan probes: all but the reserved 0x00–0x07 and 0x78–0x7F.
pub const SCAN_ADDRESSES: core::ops::RangeInclusive<SevenBitAddress> = 0x08..=0x77;

/// A set of 7-bit I2C addresses (a bus scan's answer).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AddressSet(u128);

impl AddressSet {
    /// Adds `address` (its low 7 bits).
    pub fn insert(&mut self, address: SevenBitAddress) {
        self.0 |= 1 << (address & 0x7F);
    }

    /// Whether `address` is in the set.
    pub const fn contains(&self, address: SevenBitAddress) -> bool {
        self.0 & (1 << (address & 0x7F)) != 0
    }

    /// How many addresses the set holds.
    pub const fn len(&self) -> u32 {
        self.0.count_ones()
    }

    /// Whether the set is empty.
    pub const fn is_empty(&self) -> bool {
        self.0 == 0
    }

    /// The addresses, in increasing order.
    pub fn iter(&self) -> impl Iterator<Item = SevenBitAddress> + '_ {
        (0..=0x7F).filter(|&a| self.contains(a))
    }
}

/// What went wrong on a sensor's control lines.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorError<P, B> {
    /// The reset line could not be driven.
    Reset(P),
    /// A bus transfer failed other than by a device not answering.
    Bus(B),
}

/// A sensor's reset line and control bus.
pub struct SensorControl<P, B> {
    reset: P,
    bus: B,
}

impl<P: OutputPin, B: I2c> SensorControl<P, B> {
    /// The sensor behind `reset` (active low) and `bus`. Drives nothing yet.
    pub const fn new(reset: P, bus: B) -> Self {
        Self { reset, bus }
    }

    /// Holds the sensor in reset (the line low) until [`SensorControl::reset`] releases it.
    pub fn hold_in_reset(&mut self) -> Result<(), SensorError<P::Error, B::Error>> {
        self.reset.set_low().map_err(SensorError::Reset)
    }

    /// Resets the sensor: the line low for `timing.low_us`, then high, then `timing.settle_us`
    /// for the sensor to start.
    pub fn reset(
        &mut self,
        delay: &mut impl DelayNs,
        timing: ResetTiming,
    ) -> Result<(), SensorError<P::Error, B::Error>> {
        self.reset.set_low().map_err(SensorError::Reset)?;
        delay.delay_us(timing.low_us);
        self.reset.set_high().map_err(SensorError::Reset)?;
        delay.delay_us(timing.settle_us);
        Ok(())
    }

    /// Whether a device acknowledges `address`: an address-only write (start, address, stop),
    /// which transfers no byte to it.
    pub fn probe(&mut self, address: SevenBitAddress) -> Result<bool, SensorError<P::Error, B::Error>> {
        match self.bus.write(address, &[]) {
            Ok(()) => Ok(true),
            Err(e) if matches!(e.kind(), ErrorKind::NoAcknowledge(_)) => Ok(false),
            Err(e) => Err(SensorError::Bus(e)),
        }
    }

    /// The addresses of [`SCAN_ADDRESSES`] that a device acknowledges.
    pub fn scan(&mut self) -> Result<AddressSet, SensorError<P::Error, B::Error>> {
        let mut found = AddressSet::default();
        for a in SCAN_ADDRESSES {
            if self.probe(a)? {
                found.insert(a);
            }
        }
        Ok(found)
    }

    /// The configuration hook: writes each of `writes` to the device at `address`, one bus
    /// transfer each, in order, stopping at the first that fails. What they hold (register
    /// addresses and values) is the sensor's datasheet's; evcal has none of its own.
    pub fn configure(
        &mut self,
        address: SevenBitAddress,
        writes: &[&[u8]],
    ) -> Result<(), SensorError<P::Error, B::Error>> {
        for w in writes {
            self.bus.write(address, w).map_err(SensorError::Bus)?;
        }
        Ok(())
    }

    /// The control bus, for transfers beyond these (reading a sensor's identification, say).
    pub fn bus(&mut self) -> &mut B {
        &mut self.bus
    }

    /// The reset line and the bus back.
    pub fn release(self) -> (P, B) {
        (self.reset, self.bus)
    }
}

#[cfg(test)]
mod test {
    use super::*;
    use core::convert::Infallible;
    use embedded_hal::i2c::{NoAcknowledgeSource, Operation};

    /// What the test doubles saw, in order.
    #[derive(Debug, PartialEq, Eq)]
    enum Seen {
        Pin(bool),
        Delay(u32),
        Write(u8, Vec<u8>),
    }

    struct Pin<'a>(&'a core::cell::RefCell<Vec<Seen>>);
    impl embedded_hal::digital::ErrorType for Pin<'_> {
        type Error = Infallible;
    }
    impl OutputPin for Pin<'_> {
        fn set_low(&mut self) -> Result<(), Infallible> {
            self.0.borrow_mut().push(Seen::Pin(false));
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Infallible> {
            self.0.borrow_mut().push(Seen::Pin(true));
            Ok(())
        }
    }

    struct Delay<'a>(&'a core::cell::RefCell<Vec<Seen>>);
    impl DelayNs for Delay<'_> {
        fn delay_ns(&mut self, ns: u32) {
            self.0.borrow_mut().push(Seen::Delay(ns / 1000));
        }
    }

    /// A bus with devices at `present`; `broken` fails every transfer to that address with
    /// a bus error.
    struct Bus<'a> {
        seen: &'a core::cell::RefCell<Vec<Seen>>,
        present: &'a [u8],
        broken: Option<u8>,
    }
    impl embedded_hal::i2c::ErrorType for Bus<'_> {
        type Error = ErrorKind;
    }
    impl I2c for Bus<'_> {
        fn transaction(&mut self, address: u8, ops: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
            if self.broken == Some(address) {
                return Err(ErrorKind::Bus);
            }
            if !self.present.contains(&address) {
                return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
            }
            for op in ops {
                if let Operation::Write(b) = op {
                    self.seen.borrow_mut().push(Seen::Write(address, b.to_vec()));
                }
            }
            Ok(())
        }
    }

    #[test]
    fn reset_pulses_low_then_high_with_the_timing() {
        let seen = core::cell::RefCell::new(Vec::new());
        let bus = Bus { seen: &seen, present: &[], broken: None };
        let mut s = SensorControl::new(Pin(&seen), bus);
        s.reset(&mut Delay(&seen), ResetTiming { low_us: 5, settle_us: 70 }).unwrap();
        assert_eq!(*seen.borrow(), [Seen::Pin(false), Seen::Delay(5), Seen::Pin(true), Seen::Delay(70)]);
    }

    #[test]
    fn scan_finds_the_devices_that_answer_and_stops_on_bus_errors() {
        let seen = core::cell::RefCell::new(Vec::new());
        let bus = Bus { seen: &seen, present: &[0x08, 0x48, 0x77, 0x78], broken: None };
        let mut s = SensorControl::new(Pin(&seen), bus);
        let found = s.scan().unwrap();
        // 0x78 is reserved: never probed.
        assert_eq!(found.iter().collect::<Vec<_>>(), [0x08, 0x48, 0x77]);
        assert_eq!((found.len(), found.is_empty()), (3, false));
        // Probes are address-only writes.
        assert!(seen.borrow().iter().all(|e| matches!(e, Seen::Write(_, b) if b.is_empty())));

        let bus = Bus { seen: &seen, present: &[0x48], broken: Some(0x30) };
        let mut s = SensorControl::new(Pin(&seen), bus);
        assert_eq!(s.scan(), Err(SensorError::Bus(ErrorKind::Bus)));
    }

    #[test]
    fn configure_writes_in_order_and_stops_at_a_failure() {
        let seen = core::cell::RefCell::new(Vec::new());
        let bus = Bus { seen: &seen, present: &[0x36], broken: None };
        let mut s = SensorControl::new(Pin(&seen), bus);
        s.configure(0x36, &[&[1, 2], &[3]]).unwrap();
        assert_eq!(*seen.borrow(), [Seen::Write(0x36, vec![1, 2]), Seen::Write(0x36, vec![3])]);
        assert_eq!(
            s.configure(0x37, &[&[1]]),
            Err(SensorError::Bus(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)))
        );
    }
}
