//! The switch reader against a real kernel input device: a virtual switch
//! interface made with uinput (two keys, plus one that is not the
//! switch's), read through its /dev/input/event node by
//! `opennav::input::switch::spawn_reader` — presses, releases, auto-repeat
//! ignored, another key ignored, the device unplugged (a `Lost` edge), a
//! missing device an error naming it. Needs /dev/uinput (root, or the test
//! VM: `tests/vcan/run-vm.sh`, run by `tests/switch_hil.rs`). Prints one
//! `SWITCH-HIL-RESULT {json}` line; exits 0 when every check held.

use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use evdev::uinput::VirtualDevice;
use evdev::{AttributeSet, EventType, InputEvent, KeyCode};
use opennav::input::scan::Switch;
use opennav::input::switch::{spawn_reader, SwitchEdge, SwitchSettings};
use serde_json::json;

fn key(code: KeyCode, value: i32) -> InputEvent {
    InputEvent::new(EventType::KEY.0, code.0, value)
}

fn settings(device: &str) -> SwitchSettings {
    SwitchSettings {
        device: device.into(),
        key: "KEY_ENTER".into(),
        step_key: "KEY_SPACE".into(),
        dwell_s: 2.0,
        long_press_s: 2.0,
        favourites: Vec::new(),
    }
}

fn run() -> Result<Vec<String>, String> {
    let mut failures = Vec::new();
    let mut keys = AttributeSet::<KeyCode>::new();
    for k in [KeyCode::KEY_ENTER, KeyCode::KEY_SPACE, KeyCode::KEY_A] {
        keys.insert(k);
    }
    let mut dev = VirtualDevice::builder()
        .map_err(|e| format!("/dev/uinput: {e}"))?
        .name("opennav test switch interface")
        .with_keys(&keys)
        .map_err(|e| format!("keys: {e}"))?
        .build()
        .map_err(|e| format!("uinput device: {e}"))?;
    // its event node (devtmpfs makes it)
    let mut node = None;
    for _ in 0..50 {
        if let Some(Ok(p)) = dev
            .enumerate_dev_nodes_blocking()
            .map_err(|e| format!("nodes: {e}"))?
            .next()
        {
            if p.exists() {
                node = Some(p);
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let node = node.ok_or("the virtual device has no /dev/input node")?;
    let node = node.display().to_string();
    let stop = Arc::new(AtomicBool::new(false));
    let mut edges = spawn_reader(&settings(&node), stop.clone()).map_err(|e| e.to_string())?;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| e.to_string())?;
    let mut next = |what: &str| -> Option<SwitchEdge> {
        rt.block_on(async {
            tokio::time::timeout(Duration::from_secs(2), edges.recv())
                .await
                .ok()
                .flatten()
        })
        .or_else(|| {
            eprintln!("no edge: {what}");
            None
        })
    };
    // a key that is not the switch's, the select switch with auto-repeat,
    // the step switch
    let batches = [
        vec![key(KeyCode::KEY_A, 1)],
        vec![key(KeyCode::KEY_A, 0)],
        vec![key(KeyCode::KEY_ENTER, 1)],
        vec![key(KeyCode::KEY_ENTER, 2)],
        vec![key(KeyCode::KEY_ENTER, 0)],
        vec![key(KeyCode::KEY_SPACE, 1)],
        vec![key(KeyCode::KEY_SPACE, 0)],
    ];
    for b in &batches {
        dev.emit(b).map_err(|e| format!("emit: {e}"))?;
    }
    let want = [
        SwitchEdge::Down(Switch::Select),
        SwitchEdge::Up(Switch::Select),
        SwitchEdge::Down(Switch::Step),
        SwitchEdge::Up(Switch::Step),
    ];
    for w in &want {
        match next(&format!("{w:?}")) {
            Some(got) if &got == w => {}
            other => failures.push(format!("wanted {w:?}, got {other:?}")),
        }
    }
    // unplugged: the reader says so
    drop(dev);
    match next("Lost") {
        Some(SwitchEdge::Lost(_)) => {}
        other => failures.push(format!("unplugged: wanted Lost, got {other:?}")),
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    // a configured switch that is not there is an error naming it
    match spawn_reader(&settings("/dev/input/opennav-no-such-switch"), stop) {
        Err(e) if e.to_string().contains("opennav-no-such-switch") => {}
        Err(e) => failures.push(format!("missing device: unclear error {e}")),
        Ok(_) => failures.push("a missing device was opened".into()),
    }
    Ok(failures)
}

fn main() -> ExitCode {
    let (ok, failures) = match run() {
        Ok(f) => (f.is_empty(), f),
        Err(e) => (false, vec![e]),
    };
    println!(
        "SWITCH-HIL-RESULT {}",
        json!({"ok": ok, "failures": failures})
    );
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
