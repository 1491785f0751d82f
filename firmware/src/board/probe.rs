//! How a real board ends and reports, with no console of its own: it halts where a debugger
//! (probe-rs) sees it, and reports over RTT with the `defmt` feature.

/// Halts: a debugger (probe-rs) sees the breakpoint. `ok` is for the debugger's log.
pub fn exit(ok: bool) -> ! {
    #[cfg(feature = "defmt")]
    defmt::info!("evcal firmware stops (ok: {})", ok);
    let _ = ok;
    loop {
        cortex_m::asm::bkpt();
    }
}

/// Reports a fatal error: over RTT with the `defmt` feature, else nowhere (a real board has
/// no console of its own; the host sees the link go quiet).
pub fn report(args: core::fmt::Arguments) {
    #[cfg(feature = "defmt")]
    defmt::error!("{}", defmt::Display2Format(&args));
    let _ = args;
}
