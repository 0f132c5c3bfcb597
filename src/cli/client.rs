//! `opennav go WORD`, `stop`, `resume`, `yes`, `no`, `status`: clients of
//! the running daemon's control socket. Each prints the daemon's one-line
//! JSON reply; a refused request exits 1 with its reason, no daemon exits
//! 1 naming the socket.

use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use serde_json::{json, Value};

use opennav::config::Settings;

use super::{failed, Failure};

#[derive(Args, Debug, Clone)]
pub struct SocketArg {
    /// The daemon's control socket (default: input.control_socket, else
    /// $RUNTIME_DIRECTORY/control.sock, else $XDG_RUNTIME_DIR/opennav/control.sock).
    #[arg(long)]
    pub socket: Option<PathBuf>,
}

impl SocketArg {
    pub fn path(&self, settings: &Settings) -> PathBuf {
        self.socket
            .clone()
            .unwrap_or_else(|| opennav::input::socket::default_path(&settings.input.control_socket))
    }
}

/// Sends `req`, prints the reply; `ok: false` is a failure with its reason.
pub fn send(settings: &Settings, socket: &SocketArg, req: Value) -> Result<(), Failure> {
    let path = socket.path(settings);
    let reply =
        opennav::input::socket::request(&path, &req, Duration::from_secs(2)).map_err(|e| {
            failed(anyhow::anyhow!(
                "control socket {}: {e} (is `opennav run` running?)",
                path.display()
            ))
        })?;
    println!("{reply}");
    if reply["ok"] == json!(true) {
        Ok(())
    } else {
        Err(failed(anyhow::anyhow!(
            "the daemon refused: {}",
            reply["error"].as_str().unwrap_or("no reason given")
        )))
    }
}
