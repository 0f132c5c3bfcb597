//! Tests of the control task (channels and timing, on tokio's paused clock).

use std::time::Duration;

use super::*;
use crate::actuation::ActuatorStatus;
use crate::config::Settings;
use crate::estimation::goal::GoalKeeper;
use crate::msg::TokioClock;
use crate::navigation::planner::Planner;
use crate::safety::Supervisor;

fn control() -> Control {
    let d = Settings::defaults();
    Control::new(
        Supervisor::new(d.safety_limits()),
        GoalKeeper::new(d.goal_settings()),
        Planner::new(d.mpc, d.field),
        None,
        false,
    )
}

/// A view new in the tracker is stepped on at once, not at the next
/// 20 Hz tick, and its camera stamp rides on the command it made (the
/// writer measures frame-to-command from it); the status carries the
/// writer's frame-to-command figures and the views' compute time.
#[tokio::test(start_paused = true)]
async fn a_new_view_is_stepped_on_at_once_and_its_stamp_rides_on_the_command() {
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let (_inputs_tx, inputs) = mpsc::channel(8);
    let (_faults_tx, faults) = mpsc::unbounded_channel();
    let (_events_tx, actuator_events) = mpsc::channel(8);
    let (_first_tx, first_readings) = mpsc::unbounded_channel();
    let (_obstacles_tx, obstacles) = watch::channel(None);
    let (_odometry_tx, odometry) = watch::channel(None);
    let (_camera_tx, camera) = watch::channel(None);
    let (tracks_tx, tracks) = watch::channel(Tracker::new(Settings::defaults().tracker));
    let (commands, mut commands_rx) = watch::channel(None);
    let (prompts, _prompts_rx) = watch::channel(Vec::new());
    let (status, status_rx) = watch::channel(crate::input::DaemonStatus::default());
    let frame_to_command = PeriodStats {
        count: 7,
        p50_us: 34_000.0,
        p99_us: 48_000.0,
        p01_us: 33_000.0,
        max_us: 50_000.0,
    };
    let (_actuator_tx, actuator_status) = watch::channel(ActuatorStatus {
        frame_to_command,
        ..Default::default()
    });
    let view_time = PeriodStats {
        count: 9,
        p50_us: 25_000.0,
        ..Default::default()
    };
    let (_view_time_tx, view_time_rx) = watch::channel(view_time);
    let cancel = CancellationToken::new();
    let task = tokio::spawn(run(
        control(),
        ControlTaskIo {
            inputs,
            faults,
            actuator_events,
            first_readings,
            waiting: BTreeSet::new(),
            obstacles,
            odometry,
            camera,
            tracks,
            commands,
            prompts,
            speech: None,
            state_dir: None,
            clock: clock.clone(),
            cancel: cancel.clone(),
            start: clock.now(),
            max_duration: None,
            stops: None,
            status: Some(status),
            live: None,
            record: None,
            actuator_status: Some(actuator_status),
            view_time: Some(view_time_rx),
        },
    ));
    // the ticks at 0, 50 and 100 ms have stepped, with no view
    tokio::time::sleep(Duration::from_millis(120)).await;
    let cmd = commands_rx.borrow_and_update().expect("a command by now");
    assert_eq!(cmd.view, None);
    let sent_at = clock.now();
    let view_at = Stamp(sent_at.0 - Duration::from_millis(30));
    let mut tracker = Tracker::new(Settings::defaults().tracker);
    tracker.update(view_at, &[], |_| false);
    tracks_tx.send_replace(tracker);
    // the next tick is at 150 ms: the command must come before it
    tokio::time::timeout(Duration::from_millis(5), commands_rx.changed())
        .await
        .expect("a step on the new view, before the next tick")
        .expect("the commands' channel open");
    assert_eq!(clock.now(), sent_at, "stepped without waiting");
    let cmd = commands_rx.borrow_and_update().expect("a command");
    assert_eq!(cmd.view, Some(view_at));
    let st = status_rx.borrow().clone();
    assert_eq!(st.frame_to_command, Some(frame_to_command));
    assert_eq!(st.view_time, Some(view_time));
    cancel.cancel();
    let end = task.await.expect("the control task ends");
    assert_eq!(end.outcome, Outcome::Signal);
    // the last word is zero
    let last = commands_rx.borrow().expect("a last command");
    assert_eq!(last.cmd, Default::default());
}
