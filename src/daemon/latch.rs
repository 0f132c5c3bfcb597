//! Faults that survive a restart: after a CAN bus fault, a motor-link fault
//! or an overspeed, the daemon writes the fault to its state directory;
//! every start reads it and stays stopped until a person acknowledges it
//! (`opennav ack-fault`). A record that cannot be read counts as a fault:
//! it is never silently cleared.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::msg::FaultReason;

/// The file in the state directory.
pub const FILE: &str = "latched-fault.json";

/// Faults a restart does not clear.
pub fn persists(kind: FaultReason) -> bool {
    matches!(
        kind,
        FaultReason::CanBus
            | FaultReason::MotorLink
            | FaultReason::Overspeed
            | FaultReason::OtherWriter
    )
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatchedFault {
    pub fault: FaultReason,
    /// What happened, as said at the time.
    pub reason: String,
    /// Seconds since the Unix epoch.
    pub since_unix_s: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum LatchError {
    #[error("fault record {path}: {reason}")]
    Io { path: PathBuf, reason: String },
}

fn path(dir: &Path) -> PathBuf {
    dir.join(FILE)
}

/// The latched fault, if any. A record that exists but cannot be read is
/// a latched fault of unknown kind (reported as a motor-link fault).
pub fn load(dir: &Path) -> Option<LatchedFault> {
    let p = path(dir);
    let text = match std::fs::read_to_string(&p) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
        Err(e) => {
            return Some(LatchedFault {
                fault: FaultReason::MotorLink,
                reason: format!("the fault record {} cannot be read: {e}", p.display()),
                since_unix_s: 0,
            })
        }
    };
    Some(
        serde_json::from_str(&text).unwrap_or_else(|e| LatchedFault {
            fault: FaultReason::MotorLink,
            reason: format!("the fault record {} is damaged: {e}", p.display()),
            since_unix_s: 0,
        }),
    )
}

/// Writes the record (atomically: a temporary file renamed over it).
pub fn store(dir: &Path, fault: &LatchedFault) -> Result<(), LatchError> {
    let io = |e: std::io::Error| LatchError::Io {
        path: path(dir),
        reason: e.to_string(),
    };
    std::fs::create_dir_all(dir).map_err(io)?;
    let tmp = dir.join(format!("{FILE}.tmp"));
    let text = serde_json::to_string_pretty(fault).map_err(|e| LatchError::Io {
        path: path(dir),
        reason: e.to_string(),
    })?;
    std::fs::write(&tmp, text).map_err(io)?;
    std::fs::rename(&tmp, path(dir)).map_err(io)
}

/// A person acknowledged it: the record is removed; what it held is
/// returned (None: nothing was latched).
pub fn acknowledge(dir: &Path) -> Result<Option<LatchedFault>, LatchError> {
    let held = load(dir);
    match std::fs::remove_file(path(dir)) {
        Ok(()) => Ok(held),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(LatchError::Io {
            path: path(dir),
            reason: e.to_string(),
        }),
    }
}

pub fn now_unix_s() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fault_is_kept_until_acknowledged_and_a_damaged_record_counts_as_one() {
        let dir = tempfile::tempdir().expect("tmp");
        assert_eq!(load(dir.path()), None);
        let f = LatchedFault {
            fault: FaultReason::CanBus,
            reason: "bus-off".into(),
            since_unix_s: 1_700_000_000,
        };
        store(dir.path(), &f).expect("stored");
        assert_eq!(load(dir.path()), Some(f.clone()));
        assert_eq!(acknowledge(dir.path()).expect("ack"), Some(f));
        assert_eq!(load(dir.path()), None);
        assert_eq!(acknowledge(dir.path()).expect("ack"), None);
        std::fs::write(dir.path().join(FILE), "{not json").expect("write");
        let damaged = load(dir.path()).expect("latched");
        assert!(damaged.reason.contains("damaged"), "{damaged:?}");
        assert!(persists(FaultReason::Overspeed) && !persists(FaultReason::Task));
    }
}
