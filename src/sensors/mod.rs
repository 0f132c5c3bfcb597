//! Sensors: pure codecs for the devices' byte protocols (`scip`, the
//! encoder board's frames in `encoders`), the blocking drivers around them
//! (`hokuyo`, `encoders`), run on reader threads by `task` and exposed to
//! the daemon as `daemon::Source`s; device clocks mapped to the host's
//! (`clock`); the two lasers merged into obstacles in `base_link`
//! (`laser`); RGB-D camera sources (`camera`: replay, RealSense).

pub mod camera;
pub mod clock;
pub mod encoders;
pub mod hokuyo;
pub mod laser;
pub mod scip;
pub mod task;

/// Why a serial port did not open, for the person at the terminal: on a
/// permission error, the group that owns the device node (Debian's serial
/// ports: `dialout`) and how to join it.
pub fn serial_open_reason(port: &str, e: &serialport::Error) -> String {
    use std::os::unix::fs::MetadataExt;
    if e.kind() != serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied) {
        return e.to_string();
    }
    let group = std::fs::metadata(port)
        .ok()
        .and_then(|m| group_name(m.gid()))
        .unwrap_or_else(|| "dialout".to_string());
    format!(
        "{e}: permission denied; the user running opennav must be in the group \
         `{group}` that owns {port} (sudo usermod -aG {group} $USER, then log in again; \
         the service's user gets it from systemd/opennav.service)"
    )
}

/// The name of group `gid` from /etc/group.
fn group_name(gid: u32) -> Option<String> {
    let groups = std::fs::read_to_string("/etc/group").ok()?;
    groups.lines().find_map(|l| {
        let mut f = l.split(':');
        let name = f.next()?;
        let id = f.nth(1)?.parse::<u32>().ok()?;
        (id == gid).then(|| name.to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_permission_error_names_the_group_to_join() {
        use std::os::unix::fs::MetadataExt;
        let dir = tempfile::tempdir().expect("dir");
        let node = dir.path().join("ttyACM9");
        std::fs::write(&node, b"").expect("file");
        let port = node.to_string_lossy().to_string();
        let gid = std::fs::metadata(&node).expect("meta").gid();
        let denied = serialport::Error::new(
            serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied),
            "Permission denied",
        );
        let msg = serial_open_reason(&port, &denied);
        let group = group_name(gid).unwrap_or_else(|| "dialout".into());
        assert!(msg.contains(&format!("`{group}`")), "{msg}");
        assert!(msg.contains(&port) && msg.contains("usermod"), "{msg}");
        // a port that is not there: no node, so the usual group
        let msg = serial_open_reason("/dev/opennav-none", &denied);
        assert!(msg.contains("`dialout`"), "{msg}");
        // any other error is passed on as it is
        let gone = serialport::Error::new(serialport::ErrorKind::NoDevice, "No such device");
        assert_eq!(serial_open_reason(&port, &gone), "No such device");
    }
}
