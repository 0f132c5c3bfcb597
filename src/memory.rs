//! The daemon's own memory use, from `/proc/self/status` (Linux): resident
//! now and at its peak, for the run report and `opennav status`.

use serde::Serialize;

/// Resident memory, MiB.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct MemoryUse {
    /// Resident now (`VmRSS`).
    pub rss_mb: f64,
    /// The most resident so far (`VmHWM`): the peak the chair's laptop
    /// must have room for.
    pub peak_rss_mb: f64,
}

/// `VmRSS` and `VmHWM` of a `/proc/PID/status` text; an error names the
/// field that is missing or malformed.
pub fn parse_proc_status(text: &str) -> Result<MemoryUse, String> {
    let field = |name: &str| -> Result<f64, String> {
        let line = text
            .lines()
            .find_map(|l| l.strip_prefix(name)?.strip_prefix(':'))
            .ok_or_else(|| format!("/proc status has no {name} line"))?;
        let kb = line
            .trim()
            .strip_suffix("kB")
            .map(str::trim)
            .and_then(|n| n.parse::<u64>().ok())
            .ok_or_else(|| format!("/proc status {name} is not \"N kB\": {:?}", line.trim()))?;
        Ok(kb as f64 / 1024.0)
    };
    Ok(MemoryUse {
        rss_mb: field("VmRSS")?,
        peak_rss_mb: field("VmHWM")?,
    })
}

/// This process's memory use; None where `/proc` is not there (logged).
pub fn own_memory() -> Option<MemoryUse> {
    let text = std::fs::read_to_string("/proc/self/status")
        .map_err(|e| tracing::debug!(error = %e, "/proc/self/status is unreadable"))
        .ok()?;
    parse_proc_status(&text)
        .map_err(|e| tracing::warn!(error = %e, "memory use not known"))
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_resident_and_peak() {
        let text = "Name:\topennav\nVmPeak:\t  812344 kB\nVmHWM:\t  153600 kB\nVmRSS:\t  102400 kB\nThreads:\t9\n";
        assert_eq!(
            parse_proc_status(text),
            Ok(MemoryUse {
                rss_mb: 100.0,
                peak_rss_mb: 150.0
            })
        );
    }

    #[test]
    fn a_missing_or_malformed_field_is_named() {
        let e = parse_proc_status("VmRSS:\t 10 kB\n").unwrap_err();
        assert!(e.contains("VmHWM"), "{e}");
        let e = parse_proc_status("VmRSS:\t ten kB\nVmHWM:\t 10 kB\n").unwrap_err();
        assert!(e.contains("VmRSS") && e.contains("ten"), "{e}");
    }

    #[test]
    fn this_process_has_a_resident_size() {
        let m = own_memory().expect("/proc/self/status on Linux");
        assert!(m.rss_mb > 1.0 && m.peak_rss_mb >= m.rss_mb, "{m:?}");
    }
}
