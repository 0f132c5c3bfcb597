//! systemd's notify protocol (READY, WATCHDOG, STATUS, STOPPING): a
//! datagram to `$NOTIFY_SOCKET`, nothing outside systemd.

/// Sends one notify message; outside systemd (no `NOTIFY_SOCKET`) nothing.
/// A failed send is logged (systemd then restarts us on its watchdog).
pub fn sd_notify(msg: &str) {
    let Ok(path) = std::env::var("NOTIFY_SOCKET") else {
        return;
    };
    let sent =
        std::os::unix::net::UnixDatagram::unbound().and_then(|s| s.send_to(msg.as_bytes(), &path));
    if let Err(e) = sent {
        tracing::warn!(socket = %path, error = %e, message = msg, "systemd notify failed");
    }
}
