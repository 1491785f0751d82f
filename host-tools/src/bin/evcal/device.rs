//! `evcal device`: a virtual device on a TCP port, to try `replay` without hardware.

use crate::ranges;
use anyhow::{Context, Result};
use clap::Args;
use evcal_core::detect::DetectConfig;
use evcal_host::{
    input::link::virtual_device::{serve_tcp, DeviceEvent, SessionEnd},
    input::recording::parse_sensor,
};
use std::{net::TcpListener, time::Duration};

#[derive(Args)]
pub struct DeviceArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:7878")]
    pub listen: String,
    /// The sensor the device starts with (a replay's configuration replaces it).
    #[arg(long, default_value = "davis346")]
    pub sensor: String,
    /// Seconds a host may send nothing (while the device has nothing to do) or leave unread
    /// what the device sends, before it is dropped and the device freed for the next; 0.1 to
    /// a year. A replay sends as fast as the device takes its frames: a host silent that long
    /// is gone or hung.
    #[arg(long, default_value = "30", value_name = "SECONDS", value_parser = ranges::idle,
          allow_negative_numbers = true)]
    pub idle_timeout: Duration,
}

pub fn run(a: DeviceArgs) -> Result<()> {
    let sensor = parse_sensor(&a.sensor).map_err(anyhow::Error::msg)?;
    let listener = TcpListener::bind(&a.listen).with_context(|| format!("cannot listen on {}", a.listen))?;
    eprintln!("evcal: virtual device listening on tcp:{} (Ctrl-C to stop)", listener.local_addr()?);
    let idle = a.idle_timeout;
    serve_tcp(&listener, DetectConfig::for_sensor(sensor), idle, move |e| match e {
        DeviceEvent::Connected(addr) => eprintln!("evcal: host connected from {addr}"),
        DeviceEvent::Busy { refused, serving } => {
            eprintln!("evcal: host {refused} turned away: busy with {serving} (one host at a time)")
        }
        DeviceEvent::Ended(addr, SessionEnd::Closed) => eprintln!("evcal: host {addr} disconnected"),
        DeviceEvent::Ended(addr, SessionEnd::Idle) => {
            eprintln!("evcal: host {addr} dropped: silent for {:.1} s (--idle-timeout)", idle.as_secs_f64())
        }
        DeviceEvent::Ended(addr, SessionEnd::Failed(why)) => eprintln!("evcal: host {addr} dropped: {why}"),
    })
    .context("accepting a connection")
}
