//! The wire protocol between the device and the host.
