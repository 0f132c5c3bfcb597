//! The systemd units as the chair's laptop loads them: `systemd-analyze
//! verify` accepts them, `systemd-analyze security` scores each at or below
//! 2.5, the daemon's unit allows no IP and only the chair's devices, and the
//! daemon's inference works under the unit's W^X rule
//! (`MemoryDenyWriteExecute=yes`, reproduced with the same seccomp filter).

mod common;

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::Command;

const MAX_EXPOSURE: f64 = 2.5;

fn systemd_analyze() -> PathBuf {
    for dir in ["/usr/bin", "/bin"] {
        let p = Path::new(dir).join("systemd-analyze");
        if p.exists() {
            return p;
        }
    }
    panic!(
        "\n\n*** systemd-analyze NOT FOUND: install Debian's `systemd` package \
         (tests/run.sh does) ***\n\n"
    );
}

fn unit_text(name: &str) -> String {
    let path = common::repo().join("systemd").join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The unit with its executables pointed at this machine's: the built
/// `opennav` and `ip`, so `verify` checks everything else as installed.
fn installable(dir: &Path, name: &str) -> PathBuf {
    let ip = ["/usr/sbin/ip", "/sbin/ip", "/usr/bin/ip", "/bin/ip"]
        .into_iter()
        .find(|p| Path::new(p).exists())
        .unwrap_or_else(|| panic!("\n\n*** `ip` NOT FOUND: install iproute2 ***\n\n"));
    let text = unit_text(name)
        .replace("/opt/opennav/bin/opennav", env!("CARGO_BIN_EXE_opennav"))
        .replace("/usr/sbin/ip ", &format!("{ip} "));
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write unit");
    path
}

fn exposure(unit: &Path) -> f64 {
    let out = Command::new(systemd_analyze())
        .args(["security", "--offline=yes"])
        .arg(unit)
        .output()
        .expect("systemd-analyze runs");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let line = text
        .lines()
        .find(|l| l.contains("Overall exposure level"))
        .unwrap_or_else(|| panic!("no exposure line in:\n{text}"));
    let after = line.split(": ").nth(1).expect("score after ': '");
    after
        .split_whitespace()
        .next()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("exposure not a number: {line}"))
}

#[test]
fn units_verify() {
    let dir = tempfile::tempdir().expect("tmp");
    let units = [
        installable(dir.path(), "opennav.service"),
        installable(dir.path(), "opennav-can.service"),
    ];
    let out = Command::new(systemd_analyze())
        .arg("verify")
        .args(&units)
        .output()
        .expect("systemd-analyze runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "verify failed:\n{stderr}");
    // verify warns (exit 0) on unknown keys: none may be ignored
    assert!(
        !stderr.contains("Unknown key") && !stderr.contains("Unknown section"),
        "verify warnings:\n{stderr}"
    );
}

#[test]
fn units_exposure_at_most_2_5() {
    let dir = tempfile::tempdir().expect("tmp");
    for name in ["opennav.service", "opennav-can.service"] {
        let score = exposure(&installable(dir.path(), name));
        eprintln!("{name}: exposure {score}");
        assert!(
            score <= MAX_EXPOSURE,
            "{name}: exposure {score} > {MAX_EXPOSURE}"
        );
    }
}

fn keys<'a>(text: &'a str, key: &str) -> Vec<&'a str> {
    let prefix = format!("{key}=");
    text.lines()
        .filter_map(|l| l.trim().strip_prefix(prefix.as_str()))
        .collect()
}

#[test]
fn daemon_unit_allows_no_ip_and_only_the_chairs_devices() {
    let text = unit_text("opennav.service");
    let families = keys(&text, "RestrictAddressFamilies").join(" ");
    assert!(families.contains("AF_CAN"), "{families}");
    assert!(
        !families.contains("AF_INET"),
        "IP only in the network drop-in: {families}"
    );
    assert_eq!(keys(&text, "DevicePolicy"), ["closed"]);
    let allowed = keys(&text, "DeviceAllow");
    assert!(!allowed.is_empty());
    for d in &allowed {
        assert!(
            [
                "char-ttyACM rw",
                "char-ttyUSB rw",
                "char-usb_device rw",
                "char-alsa rw"
            ]
            .contains(d),
            "unexpected device {d}"
        );
    }
    assert_eq!(keys(&text, "CapabilityBoundingSet"), [""]);
    assert_eq!(keys(&text, "MemoryDenyWriteExecute"), ["yes"]);
    // no stdin words under systemd (its end would be a stop): the words
    // come on the control socket in the runtime directory
    assert!(keys(&text, "StandardInput").iter().all(|v| *v != "tty"));
    assert!(
        keys(&text, "ExecStart")
            .iter()
            .all(|v| v.contains("run --no-stdin")),
        "{text}"
    );
    assert_eq!(keys(&text, "RuntimeDirectory"), ["opennav"]);
    // the drop-in is the one place IP comes back
    let dropin = unit_text("opennav-network.conf");
    assert!(keys(&dropin, "RestrictAddressFamilies")
        .join(" ")
        .contains("AF_INET"));
}

// --- W^X: the seccomp filter systemd installs for MemoryDenyWriteExecute
// (mmap with PROT_WRITE|PROT_EXEC, mprotect/pkey_mprotect with PROT_EXEC
// → EPERM), applied to a child before exec.

#[cfg(target_arch = "x86_64")]
const AUDIT_ARCH: u32 = 0xC000_003E;
#[cfg(target_arch = "aarch64")]
const AUDIT_ARCH: u32 = 0xC000_00B7;

fn stmt(code: u16, k: u32) -> libc::sock_filter {
    libc::sock_filter {
        code,
        jt: 0,
        jf: 0,
        k,
    }
}

fn jump(code: u16, k: u32, jt: u8, jf: u8) -> libc::sock_filter {
    libc::sock_filter { code, jt, jf, k }
}

fn wx_filter() -> Vec<libc::sock_filter> {
    const LD_W_ABS: u16 = 0x20; // BPF_LD | BPF_W | BPF_ABS
    const JEQ_K: u16 = 0x15; // BPF_JMP | BPF_JEQ | BPF_K
    const JSET_K: u16 = 0x45; // BPF_JMP | BPF_JSET | BPF_K
    const AND_K: u16 = 0x54; // BPF_ALU | BPF_AND | BPF_K
    const RET_K: u16 = 0x06; // BPF_RET | BPF_K
    const ALLOW: u32 = 0x7fff_0000;
    const EPERM: u32 = 0x0005_0000 | libc::EPERM as u32;
    const ARG2_LOW: u32 = 16 + 2 * 8; // seccomp_data.args[2], low half
    let (wr, ex) = (libc::PROT_WRITE as u32, libc::PROT_EXEC as u32);
    vec![
        stmt(LD_W_ABS, 4), // arch
        jump(JEQ_K, AUDIT_ARCH, 1, 0),
        stmt(RET_K, ALLOW),
        stmt(LD_W_ABS, 0), // nr
        jump(JEQ_K, libc::SYS_mmap as u32, 3, 0),
        jump(JEQ_K, libc::SYS_mprotect as u32, 5, 0),
        jump(JEQ_K, libc::SYS_pkey_mprotect as u32, 4, 0),
        stmt(RET_K, ALLOW),
        // mmap: both bits
        stmt(LD_W_ABS, ARG2_LOW),
        stmt(AND_K, wr | ex),
        jump(JEQ_K, wr | ex, 3, 2),
        // mprotect / pkey_mprotect: the exec bit
        stmt(LD_W_ABS, ARG2_LOW),
        jump(JSET_K, ex, 1, 0),
        stmt(RET_K, ALLOW),
        stmt(RET_K, EPERM),
    ]
}

fn under_wx(cmd: &mut Command) -> &mut Command {
    let filter = wx_filter();
    // SAFETY: between fork and exec only async-signal-safe calls (prctl)
    // on memory prepared before the fork.
    unsafe {
        cmd.pre_exec(move || {
            let prog = libc::sock_fprog {
                len: filter.len() as u16,
                filter: filter.as_ptr() as *mut libc::sock_filter,
            };
            if libc::prctl(libc::PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0
                || libc::prctl(
                    libc::PR_SET_SECCOMP,
                    libc::SECCOMP_MODE_FILTER,
                    &prog as *const libc::sock_fprog,
                ) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        })
    }
}

#[test]
fn wx_filter_bites_and_inference_runs_under_it() {
    // the filter is real: a writable+executable mapping is refused
    let python = common::repo().join(".venv/bin/python");
    let python = common::asset(python);
    let probe = under_wx(Command::new(&python).args([
        "-c",
        "import mmap\ntry:\n    mmap.mmap(-1, 4096, prot=7)\n    print('mapped')\nexcept OSError as e:\n    print('refused', e.errno)",
    ]))
    .output()
    .expect("python runs");
    let said = String::from_utf8_lossy(&probe.stdout);
    assert_eq!(said.trim(), format!("refused {}", libc::EPERM), "{said}");

    // and the daemon's models still run: ONNX Runtime generates no code
    let bus = common::asset(common::shared().join("data/images/bus.jpg"));
    let models = common::yolo11n();
    let out = under_wx(
        Command::new(env!("CARGO_BIN_EXE_opennav"))
            .args(["detect", "--rgb"])
            .arg(&bus)
            .args(["--prompt", "bus", "--models"])
            .arg(models.parent().expect("dir"))
            .env_remove("RUST_LOG"),
    )
    .output()
    .expect("opennav runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["detections"][0]["label"], "bus");
}
