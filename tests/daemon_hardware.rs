//! The daemon on the chair's device interfaces, each played by its
//! emulator on a pty: two Hokuyo URG-04LX (SCIP 2.0, real indoor scans),
//! the encoder board (its wire format), and the Rebus motor chipset. A word
//! with no camera makes the chair turn to search — which only reaches the
//! motors when both lasers and the odometry are fresh — and the stop word
//! centres it; quitting releases the link.

mod common;

use std::io::Write;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use opennav::sensors::encoders::{encode_message, CountsFrame, Message};
use opennav::sensors::scip::SensorParams;
use opennav::sim::hokuyo::{load_sena_csv, resample_to_urg, HokuyoEmulator};
use opennav::sim::rebus::RebusChipset;
use serde_json::Value;

/// An encoder board standing still: counts frames at 100 Hz on a pty.
fn encoder_board(link: std::path::PathBuf, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let (mut master, slave) = serialport::TTYPort::pair().expect("pty");
        let name = serialport::SerialPort::name(&slave).expect("name");
        std::os::unix::fs::symlink(&name, &link).expect("link");
        let mut seq: u16 = 0;
        while !stop.load(Ordering::SeqCst) {
            let f = encode_message(&Message::Counts(CountsFrame {
                seq,
                mcu_time_us: seq as u32 * 10_000,
                left: 0,
                right: 0,
                left_illegal: 0,
                right_illegal: 0,
                overrun: false,
            }));
            let _ = master.write_all(&f);
            seq = seq.wrapping_add(1);
            std::thread::sleep(Duration::from_millis(10));
        }
        drop(slave);
    })
}

fn wait_for(p: &std::path::Path) {
    let t = Instant::now();
    while !p.exists() && t.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn runs_on_emulated_devices_turns_to_search_and_stops_on_the_word() {
    let dir = tempfile::tempdir().expect("tmp");
    let scans: Vec<Vec<u32>> = load_sena_csv(&common::asset(
        common::shared().join("data/laser/sena_2006_laser_scans.csv"),
    ))
    .expect("scans")
    .iter()
    .take(20)
    .map(|s| resample_to_urg(s, &SensorParams::URG_04LX))
    .collect();
    let left = HokuyoEmulator::spawn(
        &dir.path().join("hokuyo_left"),
        scans.clone(),
        Duration::from_millis(100),
        0,
    )
    .expect("left laser");
    let right = HokuyoEmulator::spawn(
        &dir.path().join("hokuyo_right"),
        scans,
        Duration::from_millis(100),
        5000,
    )
    .expect("right laser");
    let stop = Arc::new(AtomicBool::new(false));
    let board = encoder_board(dir.path().join("encoders"), stop.clone());
    let chip = RebusChipset::spawn(&dir.path().join("rebus")).expect("chipset");
    wait_for(&dir.path().join("encoders"));

    let p = |n: &str| dir.path().join(n).display().to_string();
    let mut child = Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["run", "--no-camera"])
        .env("OPENNAV_LASERS__LEFT__PORT", p("hokuyo_left"))
        .env("OPENNAV_LASERS__RIGHT__PORT", p("hokuyo_right"))
        .env("OPENNAV_ENCODERS__PORT", p("encoders"))
        .env("OPENNAV_ACTUATION__BACKEND", "rebus")
        .env("OPENNAV_ACTUATION__REBUS__PORT", p("rebus"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let mut stdin = child.stdin.take().expect("stdin");
    std::thread::sleep(Duration::from_secs(2));
    writeln!(stdin, "chair").expect("word");
    std::thread::sleep(Duration::from_secs(2));
    let turning = chip
        .log()
        .velocity
        .iter()
        .filter(|v| (v.vx, v.vy) == (-20, 0))
        .count();
    writeln!(stdin, "stop").expect("stop");
    std::thread::sleep(Duration::from_millis(300));
    let stopped_at = Instant::now();
    std::thread::sleep(Duration::from_millis(500));
    writeln!(stdin, "quit").expect("quit");
    let out = child.wait_with_output().expect("exits");
    stop.store(true, Ordering::SeqCst);
    let _ = board.join();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let r: Value = serde_json::from_str(
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .last()
            .expect("report"),
    )
    .expect("JSON");
    // the search turn (ω 0.3 rad/s → X −20 at 1.5 rad/s full scale) reached
    // the motors: lasers and odometry were fresh
    assert!(turning > 20, "{turning} turning packets; {stderr}");
    let log = chip.log();
    assert_eq!(log.startups, 1);
    let after: Vec<_> = log.velocity.iter().filter(|v| v.at > stopped_at).collect();
    assert!(!after.is_empty());
    assert!(after.iter().all(|v| (v.vx, v.vy) == (0, 0)), "{after:?}");
    assert_eq!(r["outcome"], "quit", "{r}");
    assert_eq!(r["supervisor"]["Stopped"], "UserStop", "{r}");
    assert_eq!(r["actuator"]["backend"], "rebus");
    assert_eq!(r["actuator"]["state"], "released", "{r}");
    assert!(left.scans_sent() > 10 && right.scans_sent() > 10);
}
