//! The control socket as a carer's app or `opennav go/stop/status` use it:
//! the simulated daemon at the wall clock's pace with its socket open;
//! the socket's mode; a word and a stop through the clients; malformed and
//! oversized lines answered and dropped with the connection still usable;
//! many clients at once; the socket gone when the daemon ends.

use std::io::{BufRead, BufReader, Write};
use std::os::unix::fs::PermissionsExt;
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

fn client(args: &[&str], socket: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(args)
        .arg("--socket")
        .arg(socket)
        .output()
        .expect("runs")
}

fn status(socket: &Path) -> Value {
    let out = client(&["status"], socket);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["ok"], true, "{v}");
    v["status"].clone()
}

/// Polls the status until `pred` holds (at most `within`).
fn wait_status(socket: &Path, within: Duration, pred: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    loop {
        let s = status(socket);
        if pred(&s) {
            return s;
        }
        assert!(start.elapsed() < within, "status never matched: {s}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// One line to the socket on an open connection, its reply.
fn exchange(conn: &mut (UnixStream, BufReader<UnixStream>), line: &[u8]) -> Value {
    conn.0.write_all(line).expect("write");
    let mut reply = String::new();
    conn.1.read_line(&mut reply).expect("reply");
    serde_json::from_str(&reply).unwrap_or_else(|e| panic!("{e}: {reply:?}"))
}

#[test]
fn clients_drive_the_daemon_through_its_socket() {
    let dir = tempfile::tempdir().expect("tmp");
    let socket = dir.path().join("control.sock");
    let mut daemon = Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args([
            "run",
            "--sim",
            "--clock",
            "realtime",
            "--no-stdin",
            "--max-duration",
            "60s",
            "--control-socket",
        ])
        .arg(&socket)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("runs");
    let start = Instant::now();
    while !socket.exists() {
        assert!(start.elapsed() < Duration::from_secs(20), "no socket");
        std::thread::sleep(Duration::from_millis(50));
    }
    // the service's group may use it, nobody else
    let mode = std::fs::metadata(&socket)
        .expect("meta")
        .permissions()
        .mode()
        & 0o777;
    assert_eq!(mode, 0o660, "{mode:o}");

    let s = status(&socket);
    assert!(s["state"].is_string() || s["state"].is_object(), "{s}");
    assert!(s["goal"].is_null(), "{s}");

    // a word: the goal is taken
    let out = client(&["go", "chair"], &socket);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = wait_status(&socket, Duration::from_secs(10), |s| s["goal"] == "chair");
    assert!(s["said"].to_string().contains("Looking for a chair"), "{s}");
    // a refused request exits 1 with the daemon's reason
    let out = client(&["go", " "], &socket);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("takes a word"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // a stop: latched, said
    let out = client(&["stop"], &socket);
    assert!(out.status.success());
    let s = wait_status(&socket, Duration::from_secs(5), |s| {
        s["state"] == serde_json::json!({"Stopped": "UserStop"})
    });
    assert!(s["said"].to_string().contains("Stopped."), "{s}");

    // malformed and oversized lines: an error each, the connection goes on
    let stream = UnixStream::connect(&socket).expect("connect");
    let mut conn = (stream.try_clone().expect("clone"), BufReader::new(stream));
    let r = exchange(&mut conn, b"go to the chair please\n");
    assert_eq!(r["ok"], false, "{r}");
    assert!(r["error"].as_str().expect("error").contains("JSON"), "{r}");
    let mut long = vec![b'x'; 6000];
    long.push(b'\n');
    let r = exchange(&mut conn, &long);
    assert_eq!(r["ok"], false, "{r}");
    assert!(
        r["error"].as_str().expect("error").contains("longer than"),
        "{r}"
    );
    let r = exchange(&mut conn, b"{\"status\": true}\n");
    assert_eq!(r["ok"], true, "{r}");
    drop(conn);

    // many clients at once
    let threads: Vec<_> = (0..10)
        .map(|_| {
            let socket = socket.clone();
            std::thread::spawn(move || {
                for _ in 0..5 {
                    let v = opennav::input::socket::request(
                        &socket,
                        &serde_json::json!({"status": true}),
                        Duration::from_secs(5),
                    )
                    .expect("reply");
                    assert_eq!(v["ok"], true, "{v}");
                }
            })
        })
        .collect();
    for t in threads {
        t.join().expect("client thread");
    }

    // sixteen clients hold every slot: a seventeenth is refused as busy,
    // unless it asks for a stop, which is always taken
    let out = client(&["resume"], &socket);
    assert!(out.status.success());
    wait_status(&socket, Duration::from_secs(5), |s| {
        s["state"] != serde_json::json!({"Stopped": "UserStop"})
    });
    let held: Vec<UnixStream> = (0..opennav::input::socket::MAX_CLIENTS)
        .map(|_| UnixStream::connect(&socket).expect("connect"))
        .collect();
    std::thread::sleep(Duration::from_millis(200));
    let one = |line: &[u8]| {
        let stream = UnixStream::connect(&socket).expect("connect");
        let mut conn = (stream.try_clone().expect("clone"), BufReader::new(stream));
        exchange(&mut conn, line)
    };
    let r = one(b"{\"status\": true}\n");
    assert_eq!(r["ok"], false, "{r}");
    assert!(r["error"].as_str().expect("error").contains("busy"), "{r}");
    let r = one(b"{\"stop\": true}\n");
    assert_eq!(r["ok"], true, "{r}");
    drop(held);
    wait_status(&socket, Duration::from_secs(5), |s| {
        s["state"] == serde_json::json!({"Stopped": "UserStop"})
    });

    // the daemon ends: its socket goes with it
    // SAFETY: kill(2) on our own child
    assert_eq!(
        unsafe { libc::kill(daemon.id() as libc::pid_t, libc::SIGTERM) },
        0
    );
    let status_code = daemon.wait().expect("exits");
    assert!(status_code.success());
    assert!(!socket.exists(), "the socket file outlived the daemon");
    let out = client(&["status"], &socket);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("control.sock") && err.contains("opennav run"),
        "{err}"
    );
}
