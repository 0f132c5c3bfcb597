//! The person's switch: a USB switch interface presents as a key (or a
//! button) on an evdev device. A reader thread takes the configured keys'
//! presses and releases (the device grabbed, so the switch types nothing
//! elsewhere); the switch task runs the [scanning core](super::scan) on
//! the daemon's clock and hands its choices to the input hub and its
//! sentences to the speech path. A switch that goes away stops the chair
//! (it may be the person's only stop), is said, and is reopened every
//! second.

use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use evdev::{EventSummary, KeyCode};
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use super::scan::{ChairNow, ScanAction, ScanSettings, Scanner, Switch};
use super::{DaemonStatus, InputHub};
use crate::msg::{Clock, UserInput};

/// Config `[input.switch]`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchSettings {
    /// The evdev device (a udev by-id link); empty: no switch.
    pub device: String,
    /// The select key as evdev names it (KEY_ENTER, BTN_0, …).
    pub key: String,
    /// Two-switch scanning: the step key; empty: one switch, dwell scanning.
    pub step_key: String,
    /// Each candidate is said for this long (seconds, 0.5–10).
    pub dwell_s: f64,
    /// Held this long: stop and acknowledge a fault (seconds, 0.5–10).
    pub long_press_s: f64,
    /// Offered when nothing is seen.
    pub favourites: Vec<String>,
}

impl SwitchSettings {
    pub fn configured(&self) -> bool {
        !self.device.trim().is_empty()
    }

    pub fn scan_settings(&self) -> ScanSettings {
        ScanSettings {
            dwell: Duration::from_secs_f64(self.dwell_s),
            long_press: Duration::from_secs_f64(self.long_press_s),
            favourites: self.favourites.clone(),
            two_switch: !self.step_key.trim().is_empty(),
        }
    }

    /// The select and (two-switch) step keys.
    pub fn keys(&self) -> Result<(KeyCode, Option<KeyCode>), SwitchError> {
        let parse = |key: &str, name: &str| {
            KeyCode::from_str(name.trim()).map_err(|_| SwitchError::Key {
                key: key.into(),
                name: name.into(),
            })
        };
        let select = parse("input.switch.key", &self.key)?;
        let step = if self.step_key.trim().is_empty() {
            None
        } else {
            Some(parse("input.switch.step_key", &self.step_key)?)
        };
        Ok((select, step))
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SwitchError {
    #[error("configuration key `{key}` = {name:?}: not an evdev key name (e.g. KEY_ENTER, BTN_0)")]
    Key { key: String, name: String },
    #[error("switch {device}: {reason}")]
    Device { device: String, reason: String },
}

/// What the reader saw.
#[derive(Debug, Clone, PartialEq)]
pub enum SwitchEdge {
    Down(Switch),
    Up(Switch),
    /// The device went away (unplugged, a read error): why.
    Lost(String),
    /// It is back.
    Back,
}

fn open(device: &str) -> Result<evdev::Device, SwitchError> {
    let mut d = evdev::Device::open(device).map_err(|e| SwitchError::Device {
        device: device.into(),
        reason: e.to_string(),
    })?;
    // ours alone: the switch must not type into anything else
    if let Err(e) = d.grab() {
        tracing::warn!(device, error = %e, "switch: cannot grab it exclusively");
    }
    Ok(d)
}

/// Opens the device (an error if it is not there: a configured switch is
/// required) and reads it on a thread until `stop`.
pub fn spawn_reader(
    settings: &SwitchSettings,
    stop: Arc<std::sync::atomic::AtomicBool>,
) -> Result<mpsc::UnboundedReceiver<SwitchEdge>, SwitchError> {
    let (select, step) = settings.keys()?;
    let device = settings.device.clone();
    let mut dev = open(&device)?;
    let (tx, rx) = mpsc::unbounded_channel();
    std::thread::Builder::new()
        .name("switch".into())
        .spawn(move || {
            use std::sync::atomic::Ordering;
            loop {
                if stop.load(Ordering::Relaxed) {
                    return;
                }
                let fetched = dev.fetch_events().map(|ev| ev.collect::<Vec<_>>());
                let events = match fetched {
                    Ok(ev) => ev,
                    Err(e) => {
                        if tx.send(SwitchEdge::Lost(e.to_string())).is_err() {
                            return;
                        }
                        // reopen every second until it is back
                        loop {
                            std::thread::sleep(Duration::from_secs(1));
                            if stop.load(Ordering::Relaxed) {
                                return;
                            }
                            if let Ok(d) = open(&device) {
                                dev = d;
                                if tx.send(SwitchEdge::Back).is_err() {
                                    return;
                                }
                                break;
                            }
                        }
                        continue;
                    }
                };
                for ev in events {
                    if let EventSummary::Key(_, code, value) = ev.destructure() {
                        let which = if code == select {
                            Switch::Select
                        } else if Some(code) == step {
                            Switch::Step
                        } else {
                            continue;
                        };
                        let edge = match value {
                            1 => SwitchEdge::Down(which),
                            0 => SwitchEdge::Up(which),
                            // auto-repeat: the hold is timed by the scanner
                            _ => continue,
                        };
                        if tx.send(edge).is_err() {
                            return;
                        }
                    }
                }
            }
        })
        .map_err(|e| SwitchError::Device {
            device: settings.device.clone(),
            reason: format!("thread: {e}"),
        })?;
    Ok(rx)
}

/// The chair as the menu needs it, from the daemon's status.
pub fn chair_now(s: &DaemonStatus) -> ChairNow {
    ChairNow {
        moving: s.moving,
        asking: s.asking,
        seen: s.seen.clone(),
    }
}

/// The switch task: edges through the scanner, ticked every 100 ms, until
/// `cancel` or the reader ends.
pub async fn run(
    scan: ScanSettings,
    mut edges: mpsc::UnboundedReceiver<SwitchEdge>,
    hub: InputHub,
    status: watch::Receiver<DaemonStatus>,
    say: mpsc::UnboundedSender<String>,
    clock: Arc<dyn Clock>,
    cancel: CancellationToken,
) {
    let mut scanner = Scanner::new(scan);
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        let actions = tokio::select! {
            _ = cancel.cancelled() => return,
            e = edges.recv() => {
                let now = clock.now();
                let chair = chair_now(&status.borrow());
                match e {
                    Some(SwitchEdge::Down(w)) => scanner.press(now, w, &chair),
                    Some(SwitchEdge::Up(w)) => scanner.release(now, w, &chair),
                    Some(SwitchEdge::Lost(why)) => {
                        tracing::error!(reason = %why, "switch lost: stopping the chair");
                        vec![
                            ScanAction::Input(UserInput::Stop),
                            ScanAction::Say("The switch is disconnected. Stopped.".into()),
                        ]
                    }
                    Some(SwitchEdge::Back) => vec![ScanAction::Say("The switch is back.".into())],
                    None => {
                        tracing::error!("the switch reader ended: stopping the chair");
                        hub.stop();
                        return;
                    }
                }
            }
            _ = tick.tick() => scanner.tick(clock.now()),
        };
        for a in actions {
            match a {
                ScanAction::Say(s) => {
                    // the listener gone (the process ending): nothing to say it to
                    say.send(s).ok();
                }
                ScanAction::Input(i) => {
                    if let Err(e) = hub.send(i.clone()) {
                        tracing::warn!(input = ?i, error = %e, "switch: input not taken");
                    }
                }
            }
        }
    }
}
