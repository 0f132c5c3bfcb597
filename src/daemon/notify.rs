//! systemd's notify protocol (READY, WATCHDOG, STATUS, STOPPING) through
//! the `sd-notify` crate: a datagram to `$NOTIFY_SOCKET`, nothing outside
//! systemd. And the one line `systemctl status` shows while the daemon
//! runs ([`status_line`]).

pub use sd_notify::NotifyState;

use crate::msg::SupervisorState;

/// Sends one notification; outside systemd (no `NOTIFY_SOCKET`) nothing.
/// A failed send is logged (systemd then restarts us on its watchdog).
pub fn sd_notify(state: NotifyState) {
    if let Err(e) = sd_notify::notify(std::slice::from_ref(&state)) {
        tracing::warn!(error = %e, message = %state, "systemd notify failed");
    }
}

/// What the daemon is doing, for `STATUS=`: the supervisor's state with
/// the goal's word, and the last stop's reason while it is not stopped.
pub fn status_line(
    state: &SupervisorState,
    goal: Option<&str>,
    phase: Option<&str>,
    last_stop: Option<&str>,
) -> String {
    let now = match (state, goal) {
        (SupervisorState::Idle, _) => "idle, waiting for a word".to_string(),
        (SupervisorState::Navigating, Some(g)) => match phase {
            Some(p) => format!("going to the {g} ({p})"),
            None => format!("going to the {g}"),
        },
        (SupervisorState::Navigating, None) => "moving".to_string(),
        (SupervisorState::Holding, Some(g)) => format!("holding: the {g} is out of view"),
        (SupervisorState::Holding, None) => "holding".to_string(),
        (SupervisorState::Stopped(r), _) => return format!("stopped: {r:?}"),
        (SupervisorState::Fault(r), _) => {
            return format!("FAULT {r:?}: check the chair, then run opennav ack-fault")
        }
    };
    match last_stop {
        Some(r) => format!("{now}; last stop: {r}"),
        None => now,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{FaultReason, StopReason};

    #[test]
    fn the_status_line_says_the_state_the_goal_and_the_last_stop() {
        assert_eq!(
            status_line(&SupervisorState::Idle, None, None, None),
            "idle, waiting for a word"
        );
        assert_eq!(
            status_line(
                &SupervisorState::Navigating,
                Some("chair"),
                Some("tracking"),
                Some("Obstacle")
            ),
            "going to the chair (tracking); last stop: Obstacle"
        );
        assert_eq!(
            status_line(
                &SupervisorState::Stopped(StopReason::Obstacle),
                Some("chair"),
                None,
                Some("Obstacle")
            ),
            "stopped: Obstacle"
        );
        let f = status_line(&SupervisorState::Fault(FaultReason::Task), None, None, None);
        assert!(
            f.starts_with("FAULT Task") && f.contains("ack-fault"),
            "{f}"
        );
    }
}
