//! Commands on their way to the motors: the planner's velocity request,
//! and the supervisor's checked output with its state.

use serde::Serialize;

use super::Stamp;

/// A velocity command in `base_link`: m/s forward, rad/s counter-clockwise.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct VelocityCmd {
    pub v_mps: f64,
    pub omega_radps: f64,
}

/// Why the chair is stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum StopReason {
    LaserStale,
    OdometryStale,
    CommandStale,
    /// The depth camera's obstacles are older than their deadline.
    CameraStale,
    /// Something inside the stop corridor.
    Obstacle,
    /// A drop-off (a step down) inside the stop corridor.
    DropOff,
    /// Too many laser steps through the corridor (or the turn circle)
    /// came back without a range that means "free": the way is not seen.
    LaserBlind,
    /// A turn on the spot would sweep the chair's rear through space no
    /// sensor has seen and nobody vouched for.
    RearUnseen,
    /// A turn on the spot would sweep the chair over floor the camera
    /// never saw (a step down may lie there) and nobody vouched for.
    FloorUnseen,
    /// A stop from any input (socket, switch, voice).
    UserStop,
    /// The user deflected the real joystick.
    UserTakeover,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum FaultReason {
    /// Bus-off, error-passive or controller problems on CAN.
    CanBus,
    /// The motor interface's link (Rebus: packets not acknowledged).
    MotorLink,
    /// A task or thread of the daemon died.
    Task,
    /// The motor interface came up but never took over the chair's
    /// joystick (R-Net JSMerror: the joystick module kept talking).
    Takeover,
    /// The chair moved faster than the caps (plus a margin) for longer
    /// than the overspeed window: something other than us drives it.
    Overspeed,
    /// Another program sends joystick frames on our id (more frames per
    /// window than the joystick module and we account for).
    OtherWriter,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum SupervisorState {
    /// No goal: nothing to do.
    Idle,
    Navigating,
    /// A goal is held (e.g. lost from view): standing still.
    Holding,
    Stopped(StopReason),
    /// Latched until cleared by a person.
    Fault(FaultReason),
}

/// What the supervisor hands the actuator.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SafeCmd {
    pub cmd: VelocityCmd,
    pub state: SupervisorState,
    pub stamp: Stamp,
    /// The camera stamp of the newest view the step that made this command
    /// had seen (its objects in the tracker): the writer measures from it
    /// to the first frame carrying the command (frame-to-command latency).
    pub view: Option<Stamp>,
}
