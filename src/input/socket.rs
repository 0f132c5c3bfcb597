//! The control socket: a Unix stream socket (`/run/opennav/control.sock`
//! under systemd, mode 0660, the service's group), one JSON object per
//! line in, one per line back:
//!
//! | request | effect | reply |
//! |---|---|---|
//! | `{"go": "chair"}` | go to a chair (as the word would) | `{"ok": true}` |
//! | `{"stop": true}` | stop, latched until `resume` — always accepted | `{"ok": true}` |
//! | `{"resume": true}` | go on after a stop ("go") | `{"ok": true}` |
//! | `{"yes": true}`, `{"no": true}` | answer the chair's question | `{"ok": true}` |
//! | `{"ack_fault": true}` | a person checked the chair: clear a latched fault | `{"ok": true}` |
//! | `{"status": true}` | — | `{"ok": true, "status": {…}}` |
//!
//! A line that is not one of these, or longer than [`MAX_LINE`] bytes, gets
//! `{"ok": false, "error": "…"}` and is dropped; the connection stays open.
//! A line containing a stop request is acted on even when the rest of it
//! is malformed. At most [`MAX_CLIENTS`] connections at once.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{json, Value};
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::{UnixListener, UnixStream};
use tokio::sync::{watch, Semaphore};
use tokio_util::sync::CancellationToken;

use super::{DaemonStatus, InputHub};
use crate::msg::UserInput;

/// Longest request line, bytes.
pub const MAX_LINE: usize = 4096;
/// Connections served at once.
pub const MAX_CLIENTS: usize = 16;
/// How long a connection waits for a slot before it is refused.
const SLOT_WAIT: std::time::Duration = std::time::Duration::from_millis(500);

/// One request.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    Input(UserInput),
    Status,
}

/// The request in a line, or why it is not one.
pub fn parse_request(line: &str) -> Result<Request, String> {
    let v: Value =
        serde_json::from_str(line.trim()).map_err(|e| format!("not a JSON object: {e}"))?;
    let obj = v
        .as_object()
        .ok_or_else(|| "not a JSON object".to_string())?;
    if obj.len() != 1 {
        return Err(format!(
            "one request per line, got {} keys (go, stop, resume, yes, no, ack_fault, status)",
            obj.len()
        ));
    }
    let (key, value) = obj.iter().next().ok_or("empty object")?;
    let flag = |what: UserInput| -> Result<Request, String> {
        match value {
            Value::Bool(true) => Ok(Request::Input(what)),
            other => Err(format!("\"{key}\" takes true, got {other}")),
        }
    };
    match key.as_str() {
        "go" => match value.as_str().map(str::trim) {
            Some(w) if !w.is_empty() && w.chars().count() <= 64 => {
                Ok(Request::Input(UserInput::Goto(w.to_lowercase())))
            }
            _ => Err(format!(
                "\"go\" takes a word (1 to 64 characters), got {value}"
            )),
        },
        "stop" => flag(UserInput::Stop),
        "resume" => flag(UserInput::Go),
        "yes" => flag(UserInput::Yes),
        "no" => flag(UserInput::No),
        "ack_fault" => flag(UserInput::AckFault),
        "look_around" => flag(UserInput::LookAround),
        "status" => match value {
            Value::Bool(true) => Ok(Request::Status),
            other => Err(format!("\"status\" takes true, got {other}")),
        },
        other => Err(format!(
            "unknown request \"{other}\" (go, stop, resume, yes, no, ack_fault, status)"
        )),
    }
}

/// Whether a line that could not be parsed still asks for a stop (a
/// truncated or garbled stop must not be lost).
fn mentions_stop(line: &[u8]) -> bool {
    line.windows(6).any(|w| w.eq_ignore_ascii_case(b"\"stop\""))
}

#[derive(Debug, thiserror::Error)]
pub enum SocketError {
    #[error("control socket {path}: {reason}")]
    Bind { path: String, reason: String },
}

/// The listening socket; the file is removed when dropped.
pub struct ControlSocket {
    listener: UnixListener,
    path: PathBuf,
}

impl ControlSocket {
    /// Binds `path` with mode 0660, replacing a stale socket file (none
    /// listening); another listener there is an error.
    pub fn bind(path: &Path) -> Result<ControlSocket, SocketError> {
        let err = |reason: String| SocketError::Bind {
            path: path.display().to_string(),
            reason,
        };
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| err(e.to_string()))?;
        }
        if path.exists() {
            if std::os::unix::net::UnixStream::connect(path).is_ok() {
                return Err(err("another program is listening there".into()));
            }
            std::fs::remove_file(path).map_err(|e| err(format!("stale file: {e}")))?;
        }
        let listener = UnixListener::bind(path).map_err(|e| err(e.to_string()))?;
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o660))
            .map_err(|e| err(format!("mode 0660: {e}")))?;
        Ok(ControlSocket {
            listener,
            path: path.to_path_buf(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Serves clients until `cancel`.
    pub async fn serve(
        self,
        hub: InputHub,
        status: watch::Receiver<DaemonStatus>,
        cancel: CancellationToken,
    ) {
        let slots = Arc::new(Semaphore::new(MAX_CLIENTS));
        loop {
            let stream = tokio::select! {
                _ = cancel.cancelled() => return,
                r = self.listener.accept() => match r {
                    Ok((s, _)) => s,
                    Err(e) => {
                        tracing::warn!(error = %e, "control socket: accept failed");
                        continue;
                    }
                },
            };
            let (hub, status, cancel, slots) =
                (hub.clone(), status.clone(), cancel.clone(), slots.clone());
            tokio::spawn(async move {
                // a slot freed a moment ago may not be returned yet (its
                // client's end not read): wait a little before refusing
                let permit = tokio::time::timeout(SLOT_WAIT, slots.acquire_owned()).await;
                let Ok(Ok(permit)) = permit else {
                    busy(stream, &hub).await;
                    return;
                };
                tokio::select! {
                    _ = cancel.cancelled() => {}
                    r = client(stream, hub, status) => {
                        if let Err(e) = r {
                            tracing::debug!(error = %e, "control socket client");
                        }
                    }
                }
                drop(permit);
            });
        }
    }
}

/// A connection beyond [`MAX_CLIENTS`]: its first line is still read, and
/// a stop in it is taken; anything else is refused as busy.
async fn busy(stream: UnixStream, hub: &InputHub) {
    let (read, mut write) = stream.into_split();
    let mut line = Vec::new();
    let read = tokio::time::timeout(
        SLOT_WAIT,
        BufReader::new(read)
            .take(MAX_LINE as u64)
            .read_until(b'\n', &mut line),
    )
    .await;
    let reply = if read.is_ok() && mentions_stop(&line) {
        // a stop is always accepted
        hub.stop();
        format!("{}\n", json!({"ok": true}))
    } else {
        reply_error(&format!("busy: at most {MAX_CLIENTS} connections"))
    };
    if let Err(e) = write.write_all(reply.as_bytes()).await {
        tracing::debug!(error = %e, "control socket: a busy reply was not delivered");
    }
}

impl Drop for ControlSocket {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

fn reply_error(e: &str) -> String {
    format!("{}\n", json!({"ok": false, "error": e}))
}

/// What one line gets back.
pub fn answer(line: &[u8], hub: &InputHub, status: &DaemonStatus) -> String {
    let text = match std::str::from_utf8(line) {
        Ok(t) => t,
        Err(_) => {
            if mentions_stop(line) {
                hub.stop();
            }
            return reply_error("not UTF-8");
        }
    };
    match parse_request(text) {
        Ok(Request::Status) => format!("{}\n", json!({"ok": true, "status": status})),
        Ok(Request::Input(i)) => match hub.send(i) {
            Ok(()) => format!("{}\n", json!({"ok": true})),
            Err(e) => reply_error(&e.to_string()),
        },
        Err(e) => {
            if mentions_stop(line) {
                // garbled, but it asked for a stop: stopped
                hub.stop();
                return reply_error(&format!("{e} (stopped anyway: the line asks for a stop)"));
            }
            reply_error(&e)
        }
    }
}

async fn client(
    stream: UnixStream,
    hub: InputHub,
    status: watch::Receiver<DaemonStatus>,
) -> std::io::Result<()> {
    let (read, mut write) = stream.into_split();
    let mut read = BufReader::new(read);
    let mut line = Vec::new();
    loop {
        line.clear();
        // at most MAX_LINE + 1 bytes of a line are held
        let n = (&mut read)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut line)
            .await?;
        if n == 0 {
            return Ok(());
        }
        let reply = if line.len() > MAX_LINE && line.last() != Some(&b'\n') {
            // skip the rest of the oversized line
            let stop = mentions_stop(&line);
            let mut rest = Vec::new();
            loop {
                rest.clear();
                let k = (&mut read)
                    .take(MAX_LINE as u64)
                    .read_until(b'\n', &mut rest)
                    .await?;
                if k == 0 || rest.last() == Some(&b'\n') {
                    break;
                }
            }
            if stop {
                hub.stop();
            }
            reply_error(&format!("line longer than {MAX_LINE} bytes: dropped"))
        } else {
            let body = line.strip_suffix(b"\n").unwrap_or(&line);
            if body.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            let snapshot = status.borrow().clone();
            answer(body, &hub, &snapshot)
        };
        write.write_all(reply.as_bytes()).await?;
    }
}

/// The configured socket path: `input.control_socket`, else
/// `$RUNTIME_DIRECTORY/control.sock` (systemd), else
/// `$XDG_RUNTIME_DIR/opennav/control.sock`, else
/// `/tmp/opennav-<uid>/control.sock`.
pub fn default_path(configured: &str) -> PathBuf {
    if !configured.is_empty() {
        return PathBuf::from(configured);
    }
    if let Some(d) = std::env::var_os("RUNTIME_DIRECTORY") {
        // systemd may list several, colon-separated: the first
        let first = d
            .to_string_lossy()
            .split(':')
            .next()
            .unwrap_or("")
            .to_string();
        if !first.is_empty() {
            return PathBuf::from(first).join("control.sock");
        }
    }
    if let Some(d) = std::env::var_os("XDG_RUNTIME_DIR") {
        return PathBuf::from(d).join("opennav").join("control.sock");
    }
    // SAFETY: getuid cannot fail
    let uid = unsafe { libc::getuid() };
    PathBuf::from(format!("/tmp/opennav-{uid}")).join("control.sock")
}

/// A client's one request and its reply (the `opennav go/stop/status`
/// commands), blocking, with a timeout.
pub fn request(path: &Path, req: &Value, timeout: std::time::Duration) -> std::io::Result<Value> {
    use std::io::{BufRead, Read, Write};
    let mut s = std::os::unix::net::UnixStream::connect(path)?;
    s.set_read_timeout(Some(timeout))?;
    s.set_write_timeout(Some(timeout))?;
    s.write_all(format!("{req}\n").as_bytes())?;
    let mut line = String::new();
    std::io::BufReader::new(s.take(1 << 20)).read_line(&mut line)?;
    serde_json::from_str(&line).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("reply is not JSON: {e}: {line:?}"),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_parse_and_bad_ones_say_why() {
        assert_eq!(
            parse_request(r#"{"go": " Chair "}"#),
            Ok(Request::Input(UserInput::Goto("chair".into())))
        );
        assert_eq!(
            parse_request(r#"{"stop": true}"#),
            Ok(Request::Input(UserInput::Stop))
        );
        assert_eq!(
            parse_request(r#"{"resume": true}"#),
            Ok(Request::Input(UserInput::Go))
        );
        assert_eq!(
            parse_request(r#"{"ack_fault": true}"#),
            Ok(Request::Input(UserInput::AckFault))
        );
        assert_eq!(parse_request(r#"{"status": true}"#), Ok(Request::Status));
        for (bad, why) in [
            ("go chair", "not a JSON object"),
            ("[1]", "not a JSON object"),
            (r#"{"go": ""}"#, "takes a word"),
            (r#"{"go": 3}"#, "takes a word"),
            (r#"{"stop": false}"#, "takes true"),
            (r#"{"fly": true}"#, "unknown request"),
            (r#"{"go": "a", "stop": true}"#, "one request per line"),
        ] {
            let e = parse_request(bad).expect_err(bad);
            assert!(e.contains(why), "{bad}: {e}");
        }
    }

    #[tokio::test]
    async fn a_stop_is_taken_when_words_are_full_and_when_garbled() {
        let (hub, mut rx) = super::super::hub();
        let status = DaemonStatus::default();
        for _ in 0..super::super::WORDS_QUEUED {
            assert!(answer(br#"{"go": "chair"}"#, &hub, &status).contains("true"));
        }
        let busy = answer(br#"{"go": "desk"}"#, &hub, &status);
        assert!(busy.contains("busy"), "{busy}");
        assert!(answer(br#"{"stop": true}"#, &hub, &status).contains("\"ok\":true"));
        assert_eq!(*rx.stops.borrow_and_update(), 1);
        let garbled = answer(br#"{"stop": tru"#, &hub, &status);
        assert!(garbled.contains("stopped anyway"), "{garbled}");
        let binary = answer(b"\xff\xfe{\"stop\"", &hub, &status);
        assert!(binary.contains("not UTF-8"), "{binary}");
        assert_eq!(*rx.stops.borrow_and_update(), 3);
        assert_eq!(rx.words.try_recv(), Ok(UserInput::Goto("chair".into())));
    }
}
