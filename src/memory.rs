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

/// Keeps freed heap memory in the process instead of handing it back to
/// the kernel (glibc's `M_TRIM_THRESHOLD` at 256 MiB, and blocks up to
/// 64 MiB from the heap rather than each its own mapping): each view's
/// point arrays (~170 kB an object) are then pages already mapped, not
/// fresh ones the kernel must fault in and zero — 8–10 % of steps 3–6
/// (`geometry_10_masks`). The resident peak is what it was; memory freed
/// stays resident up to it. True when the allocator took both settings;
/// false elsewhere than glibc (nothing to do there).
pub fn keep_freed_heap() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only sets the allocator's parameters, valid at
        // any time; both values are within what glibc accepts
        unsafe {
            libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20) == 1
                && libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// glibc takes both settings (a value outside its limits, as a 64 MiB
    /// mapping threshold, would be refused and leave it as it was).
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn glibc_keeps_freed_heap() {
        assert!(keep_freed_heap());
        // and the heap serves a view's point array again after it is freed
        let a: Vec<u8> = vec![1; 170_000];
        drop(a);
        let b: Vec<u8> = vec![2; 170_000];
        assert_eq!(b.len(), 170_000);
    }

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
