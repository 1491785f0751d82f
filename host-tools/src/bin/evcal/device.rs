//! `evcal device`: a virtual device on a TCP port, to try `replay` without hardware.

use anyhow::{Context, Result};
use clap::Args;
use evcal_core::wire::default_config;
use evcal_host::{input::link::virtual_device::serve_tcp, input::recording::parse_sensor};
use std::net::TcpListener;

#[derive(Args)]
pub struct DeviceArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1:7878")]
    pub listen: String,
    /// The sensor the device starts with (a replay's configuration replaces it).
    #[arg(long, default_value = "davis346")]
    pub sensor: String,
}

pub fn run(a: DeviceArgs) -> Result<()> {
    let sensor = parse_sensor(&a.sensor).map_err(anyhow::Error::msg)?;
    let listener = TcpListener::bind(&a.listen).with_context(|| format!("cannot listen on {}", a.listen))?;
    eprintln!("evcal: virtual device listening on tcp:{} (Ctrl-C to stop)", listener.local_addr()?);
    serve_tcp(&listener, default_config(sensor), |s| {
        eprintln!("evcal: host connected from {}", s.peer_addr().map(|a| a.to_string()).unwrap_or_default());
    })
    .context("accepting a connection")
}
