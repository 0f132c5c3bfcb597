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
    encoder_board_after(link, stop, Duration::ZERO)
}

/// The board's port is there at once, its frames only after `silent`.
fn encoder_board_after(
    link: std::path::PathBuf,
    stop: Arc<AtomicBool>,
    silent: Duration,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let (mut master, slave) = serialport::TTYPort::pair().expect("pty");
        let name = serialport::SerialPort::name(&slave).expect("name");
        std::os::unix::fs::symlink(&name, &link).expect("link");
        std::thread::sleep(silent);
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

/// Both URG-04LX emulators streaming real indoor scans, on ptys in `dir`.
fn lasers(dir: &std::path::Path) -> (HokuyoEmulator, HokuyoEmulator) {
    let scans: Vec<Vec<u32>> = load_sena_csv(&common::asset(
        common::shared().join("data/laser/sena_2006_laser_scans.csv"),
    ))
    .expect("scans")
    .iter()
    .take(20)
    .map(|s| resample_to_urg(s, &SensorParams::URG_04LX))
    .collect();
    let left = HokuyoEmulator::spawn(
        &dir.join("hokuyo_left"),
        scans.clone(),
        Duration::from_millis(100),
        0,
    )
    .expect("left laser");
    let right = HokuyoEmulator::spawn(
        &dir.join("hokuyo_right"),
        scans,
        Duration::from_millis(100),
        5000,
    )
    .expect("right laser");
    (left, right)
}

/// `opennav` on the emulated devices in `dir` (the Rebus backend), with
/// its own lock and state directory.
fn opennav_on(dir: &std::path::Path) -> Command {
    let p = |n: &str| dir.join(n);
    let mut c = Command::new(env!("CARGO_BIN_EXE_opennav"));
    c.env("OPENNAV_LASERS__LEFT__PORT", p("hokuyo_left"))
        .env("OPENNAV_LASERS__RIGHT__PORT", p("hokuyo_right"))
        .env("OPENNAV_ENCODERS__PORT", p("encoders"))
        .env("OPENNAV_ACTUATION__BACKEND", "rebus")
        .env("OPENNAV_ACTUATION__REBUS__PORT", p("rebus"))
        .env("OPENNAV_RUNTIME__LOCK_FILE", p("opennav.lock"))
        .env("OPENNAV_RUNTIME__STATE_DIR", p("state"))
        .env("OPENNAV_INPUT__CONTROL_SOCKET", p("control.sock"))
        // spoken into files, not the sound card
        .env("OPENNAV_SPEECH__WAV_DIR", p("speech"));
    c
}

#[test]
fn runs_on_emulated_devices_turns_to_search_and_stops_on_the_word() {
    let dir = tempfile::tempdir().expect("tmp");
    let (left, right) = lasers(dir.path());
    let stop = Arc::new(AtomicBool::new(false));
    let board = encoder_board(dir.path().join("encoders"), stop.clone());
    let chip = RebusChipset::spawn(&dir.path().join("rebus")).expect("chipset");
    wait_for(&dir.path().join("encoders"));

    let mut child = opennav_on(dir.path())
        .args(["run", "--no-camera"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let mut stdin = child.stdin.take().expect("stdin");
    // what it says, as it says it (waited for, not slept for: a loaded
    // machine starts it later)
    let (said_tx, said_rx) = std::sync::mpsc::channel::<String>();
    let err_pipe = child.stderr.take().expect("stderr");
    let stderr_reader = std::thread::spawn(move || {
        use std::io::BufRead;
        let mut all = String::new();
        for line in std::io::BufReader::new(err_pipe)
            .lines()
            .map_while(Result::ok)
        {
            said_tx.send(line.clone()).ok();
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let wait_said = |what: &str| {
        let until = Instant::now() + Duration::from_secs(30);
        while Instant::now() < until {
            if let Ok(l) = said_rx.recv_timeout(Duration::from_millis(100)) {
                if l.contains(what) {
                    return;
                }
            }
        }
        panic!("never said {what:?}");
    };
    // ready once every device has delivered: then the word
    wait_said("No depth camera");
    writeln!(stdin, "chair").expect("word");
    // the rear was never seen: the chair asks before a turn on the spot
    wait_said("cannot see behind me");
    writeln!(stdin, "yes").expect("yes");
    let turning_packets = || {
        chip.log()
            .velocity
            .iter()
            .filter(|v| (v.vx, v.vy) == (-20, 0))
            .count()
    };
    let until = Instant::now() + Duration::from_secs(20);
    while turning_packets() <= 20 && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(50));
    }
    let turning = turning_packets();
    writeln!(stdin, "stop").expect("stop");
    std::thread::sleep(Duration::from_millis(300));
    let stopped_at = Instant::now();
    std::thread::sleep(Duration::from_millis(500));
    writeln!(stdin, "quit").expect("quit");
    let out = child.wait_with_output().expect("exits");
    stop.store(true, Ordering::SeqCst);
    let _ = board.join();
    let stderr = stderr_reader.join().expect("stderr");
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
    assert!(
        r["said"].as_array().is_some_and(|s| s.iter().any(|l| l
            .as_str()
            .is_some_and(|l| l.contains("cannot see behind me")))),
        "{r}"
    );
    assert_eq!(r["supervisor"]["Stopped"], "UserStop", "{r}");
    // every sentence spoken (espeak-ng into WAV files), in order
    let said: Vec<String> = r["said"]
        .as_array()
        .expect("said")
        .iter()
        .map(|l| l.as_str().expect("text").to_string())
        .collect();
    let speech = dir.path().join("speech");
    let mut spoken = Vec::new();
    for k in 1..=said.len() {
        let wav = speech.join(format!("{k:04}.wav"));
        let bytes = std::fs::read(&wav).unwrap_or_else(|e| panic!("{}: {e}", wav.display()));
        assert!(
            bytes.starts_with(b"RIFF") && bytes.len() > 4000,
            "{}",
            wav.display()
        );
        spoken.push(std::fs::read_to_string(wav.with_extension("txt")).expect("text"));
    }
    assert_eq!(spoken, said);
    assert_eq!(r["actuator"]["backend"], "rebus");
    assert_eq!(r["actuator"]["state"], "released", "{r}");
    assert!(left.scans_sent() > 10 && right.scans_sent() > 10);
}

/// READY=1 only once every device delivered: with the encoder board
/// silent for its first 3 s, systemd hears what the daemon waits for, and
/// READY after the board speaks; then the watchdog.
#[test]
fn ready_only_after_every_device_gave_a_first_reading() {
    let dir = tempfile::tempdir().expect("tmp");
    let (_left, _right) = lasers(dir.path());
    let stop = Arc::new(AtomicBool::new(false));
    let silent = Duration::from_secs(3);
    let started = Instant::now();
    let board = encoder_board_after(dir.path().join("encoders"), stop.clone(), silent);
    let _chip = RebusChipset::spawn(&dir.path().join("rebus")).expect("chipset");
    wait_for(&dir.path().join("encoders"));
    let notify = dir.path().join("notify");
    let sock = std::os::unix::net::UnixDatagram::bind(&notify).expect("bind");
    sock.set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    let child = opennav_on(dir.path())
        .args(["run", "--no-camera", "--no-stdin", "--max-duration", "5s"])
        .env("NOTIFY_SOCKET", &notify)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let mut msgs: Vec<(Duration, String)> = Vec::new();
    let mut buf = [0u8; 512];
    while let Ok(n) = sock.recv(&mut buf) {
        let m = String::from_utf8_lossy(&buf[..n]).trim_end().to_string();
        let done = m == "STOPPING=1";
        msgs.push((started.elapsed(), m));
        if done {
            break;
        }
    }
    let out = child.wait_with_output().expect("exits");
    stop.store(true, Ordering::SeqCst);
    board.join().expect("board");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ready = msgs
        .iter()
        .position(|(_, m)| m == "READY=1")
        .unwrap_or_else(|| panic!("no READY: {msgs:?}"));
    assert!(
        msgs[ready].0 >= silent,
        "READY at {:?}, before the board spoke: {msgs:?}",
        msgs[ready].0
    );
    // what it waited for, last the encoder board alone
    let waiting: Vec<&str> = msgs[..ready]
        .iter()
        .filter(|(_, m)| m.starts_with("STATUS=waiting"))
        .map(|(_, m)| m.as_str())
        .collect();
    assert_eq!(
        waiting.last().copied(),
        Some("STATUS=waiting for a first reading from: encoders"),
        "{msgs:?}"
    );
    assert_eq!(msgs.iter().filter(|(_, m)| m == "READY=1").count(), 1);
    assert!(
        msgs[ready..]
            .iter()
            .filter(|(_, m)| m == "WATCHDOG=1")
            .count()
            > 10,
        "{msgs:?}"
    );
}

/// `opennav check encoders` reads the board on the configured port (no
/// --port), and a port that is not there is one line naming it.
#[test]
fn check_encoders_reads_the_configured_port() {
    let dir = tempfile::tempdir().expect("tmp");
    let link = dir.path().join("encoders");
    let stop = Arc::new(AtomicBool::new(false));
    let board = encoder_board(link.clone(), stop.clone());
    wait_for(&link);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["check", "encoders", "--count", "5"])
        .env("OPENNAV_ENCODERS__PORT", &link)
        .output()
        .expect("runs");
    stop.store(true, Ordering::SeqCst);
    board.join().expect("board");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect();
    assert_eq!(lines.len(), 5);
    assert!(lines.iter().all(|l| l["left"] == 0 && l["right"] == 0));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["check", "encoders"])
        .env("OPENNAV_ENCODERS__PORT", "/dev/opennav-no-such-board")
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("/dev/opennav-no-such-board") && e.lines().count() == 1,
        "{e}"
    );
}
