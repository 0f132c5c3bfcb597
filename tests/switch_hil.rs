//! The switch reader on a real kernel input device: `examples/switch_hil.rs`
//! makes a virtual switch interface with uinput and reads it through
//! evdev — directly when /dev/uinput is writable here, otherwise inside
//! the test VM (`tests/vcan/run-vm.sh`, Debian's kernel with the evdev and
//! uinput modules). Without either this test fails, saying so.

use std::path::PathBuf;
use std::process::Command;

use serde_json::Value;

fn host_has_uinput() -> bool {
    std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/uinput")
        .is_ok()
}

#[test]
fn the_switch_reader_sees_presses_releases_and_an_unplug() {
    let runner = PathBuf::from(env!("CARGO_BIN_EXE_opennav"))
        .parent()
        .expect("target dir")
        .join("examples")
        .join("switch_hil");
    assert!(
        runner.exists(),
        "{} missing: `cargo test` builds the examples (run `cargo build --examples`)",
        runner.display()
    );
    let out = if host_has_uinput() {
        eprintln!("switch HIL: this machine's /dev/uinput");
        Command::new(&runner).output()
    } else {
        eprintln!("switch HIL: no writable /dev/uinput here; booting the test VM");
        Command::new("bash")
            .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/vcan/run-vm.sh"))
            .arg(&runner)
            .output()
    }
    .expect("the switch HIL run starts");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .find_map(|l| l.trim_start().strip_prefix("SWITCH-HIL-RESULT "))
        .unwrap_or_else(|| {
            panic!(
                "no result (exit {:?})\n--- stdout ---\n{stdout}\n--- stderr ---\n{}",
                out.status.code(),
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let v: Value = serde_json::from_str(line).expect("result JSON");
    assert_eq!(v["ok"], true, "{}", v["failures"]);
}
