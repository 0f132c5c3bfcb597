//! The person's front end: every way a word, a stop or an answer reaches
//! the daemon — stdin (development), the control socket (a carer's app, a
//! ROS node, `opennav go/stop/status`) — through one [`InputHub`].
//!
//! Stops never queue behind words: each is a tick of a counter the control
//! task watches, so a stop is always accepted, however busy the word
//! channel is.

pub mod scan;
pub mod socket;
pub mod switch;

use serde::Serialize;
use tokio::sync::{mpsc, watch};

use crate::msg::{Pose2, SupervisorState, UserInput};

/// Where inputs go: words and answers on a bounded channel, stops as a
/// counter.
#[derive(Clone)]
pub struct InputHub {
    words: mpsc::Sender<UserInput>,
    stops: watch::Sender<u64>,
}

/// The daemon's side of the hub.
pub struct InputReceivers {
    pub words: mpsc::Receiver<UserInput>,
    pub stops: watch::Receiver<u64>,
}

/// Why an input was not taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InputError {
    #[error("busy: too many words waiting; say it again")]
    Busy,
    #[error("the daemon is shutting down")]
    Closed,
}

/// Words waiting at most (a stop never waits).
pub const WORDS_QUEUED: usize = 32;

pub fn hub() -> (InputHub, InputReceivers) {
    let (words_tx, words) = mpsc::channel(WORDS_QUEUED);
    let (stops_tx, stops) = watch::channel(0u64);
    (
        InputHub {
            words: words_tx,
            stops: stops_tx,
        },
        InputReceivers { words, stops },
    )
}

impl InputHub {
    /// A stop: one tick of the counter the control task watches (it
    /// cannot be full, and a closed control task has nothing to stop).
    pub fn stop(&self) {
        self.stops.send_modify(|n| *n += 1);
    }

    /// Hands an input on now; a stop always.
    pub fn send(&self, input: UserInput) -> Result<(), InputError> {
        if input == UserInput::Stop {
            self.stop();
            return Ok(());
        }
        self.words.try_send(input).map_err(|e| match e {
            mpsc::error::TrySendError::Full(_) => InputError::Busy,
            mpsc::error::TrySendError::Closed(_) => InputError::Closed,
        })
    }

    /// From a thread that may wait (stdin): blocks while the word channel
    /// is full, never for a stop.
    pub fn blocking_send(&self, input: UserInput) -> Result<(), InputError> {
        if input == UserInput::Stop {
            self.stop();
            return Ok(());
        }
        self.words
            .blocking_send(input)
            .map_err(|_| InputError::Closed)
    }
}

/// What the daemon is doing, for `{"status": true}` and `opennav status`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DaemonStatus {
    /// The supervisor's state (with its stop reason or fault).
    pub state: Option<SupervisorState>,
    /// The word being looked for or driven to.
    pub goal: Option<String>,
    /// The goal keeper's phase: searching, tracking, holding, reached.
    pub goal_phase: Option<String>,
    pub pose: Option<Pose2>,
    /// The latest fault, in words.
    pub fault: Option<String>,
    /// Devices that have not given a first reading yet.
    pub waiting_for: Vec<String>,
    /// The chair is asking a question ("yes" / "no" answer it).
    pub asking: bool,
    /// The chair moves (measured), or is commanded to.
    pub moving: bool,
    /// Labels of the confirmed objects it knows, nearest first.
    pub seen: Vec<String>,
    /// The last sentences the chair said, oldest first.
    pub said: Vec<String>,
    /// The daemon's resident memory (read once a second).
    pub memory: Option<crate::memory::MemoryUse>,
    /// Each view's compute time over the run (None: no camera).
    pub view_time: Option<crate::actuation::PeriodStats>,
    /// Camera stamp of each view → the first motor frame carrying the
    /// command made after it, over the run.
    pub frame_to_command: Option<crate::actuation::PeriodStats>,
}
