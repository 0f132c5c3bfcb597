//! Pseudo-terminals for device emulators: the emulator keeps the master,
//! the driver under test opens the slave through a stable link (as udev
//! gives the real device).

use std::path::Path;
use std::time::Duration;

use serialport::{SerialPort, TTYPort};

/// A plugged-in emulated device: the master end, and the slave kept open
/// so the pty lives while the driver reconnects.
pub struct PtyDevice {
    pub master: TTYPort,
    pub slave: TTYPort,
}

/// A new pty whose slave is linked at `link` (replacing a stale link); the
/// master reads with `read_timeout`.
pub fn plug(link: &Path, read_timeout: Duration) -> std::io::Result<PtyDevice> {
    let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::other)?;
    master
        .set_timeout(read_timeout)
        .map_err(std::io::Error::other)?;
    let name = slave
        .name()
        .ok_or_else(|| std::io::Error::other("pty without a name"))?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(&name, link)?;
    Ok(PtyDevice { master, slave })
}
