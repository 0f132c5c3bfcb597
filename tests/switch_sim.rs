//! The person's switch on the simulated chair: the switch task (the
//! scanning core on the daemon's clock, the input hub, the daemon's status)
//! exactly as `opennav run` wires it, with the switch's edges coming from
//! a virtual switch in place of the evdev reader's channel (the reader
//! itself is tested on a kernel input device in `tests/switch_hil.rs`).
//! A press mid-trip brings the chair to rest; one-switch scanning chooses
//! the second object the chair sees after two dwell times.

mod common;

use std::sync::Arc;
use std::time::Duration;

use opennav::config::Settings;
use opennav::daemon::{Outcome, RunOptions, RunReport};
use opennav::input::scan::Switch;
use opennav::input::switch::SwitchEdge;
use opennav::input::DaemonStatus;
use opennav::msg::{Clock, TokioClock, UserInput};
use opennav::sim::devices::SimSummary;
use opennav::sim::world::SimWorld;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

/// What the test does while the chair runs: words to the hub and switch
/// edges, each at its time from the start, and a look at the status.
enum Act {
    Word(UserInput),
    Edge(SwitchEdge),
    /// Records what the chair sees now (the menu's candidates).
    NoteSeen,
}

struct Trip {
    report: RunReport,
    sim: SimSummary,
    seen: Vec<Vec<String>>,
}

/// How long the switch is held for a press, s.
const PRESS_S: f64 = 0.15;

/// The living room, the chair facing `heading_rad` from its usual start;
/// `acts` and a press of the select switch at each of `presses_s`.
async fn trip(
    heading_rad: Option<f64>,
    mut acts: Vec<(Duration, Act)>,
    presses_s: &[f64],
    max: Duration,
) -> Trip {
    for &at in presses_s {
        acts.push((secs(at), Act::Edge(SwitchEdge::Down(Switch::Select))));
        acts.push((
            secs(at + PRESS_S),
            Act::Edge(SwitchEdge::Up(Switch::Select)),
        ));
    }
    acts.sort_by_key(|(at, _)| *at);
    let settings = Settings::load(None).expect("defaults");
    let mut world = SimWorld::living_room(settings.drive_params());
    if let Some(h) = heading_rad {
        world.start.theta_rad = h;
        world.truth.theta_rad = h;
    }
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let (devices, sim) =
        opennav::sim::devices::devices(&settings, world, clock.clone()).expect("devices");
    let (hub, receivers) = opennav::input::hub();
    let (status_tx, status_rx) = watch::channel(DaemonStatus::default());
    let (edges_tx, edges_rx) = mpsc::unbounded_channel();
    let (say_tx, mut say_rx) = mpsc::unbounded_channel::<String>();
    let cancel = CancellationToken::new();
    tokio::spawn(opennav::input::switch::run(
        settings.input.switch.scan_settings(),
        edges_rx,
        hub.clone(),
        status_rx.clone(),
        say_tx,
        clock.clone(),
        cancel.clone(),
    ));
    // the menu's sentences (the chair's own go through the report)
    let menu_said = tokio::spawn(async move {
        let mut all = Vec::new();
        while let Some(s) = say_rx.recv().await {
            all.push(s);
        }
        all
    });
    let script_hub = hub.clone();
    let (seen_tx, seen_rx) = tokio::sync::oneshot::channel();
    tokio::spawn(async move {
        let mut seen = Vec::new();
        let mut at = Duration::ZERO;
        for (when, act) in acts {
            tokio::time::sleep(when.saturating_sub(at)).await;
            at = when;
            match act {
                Act::Word(w) => script_hub.send(w).expect("word taken"),
                Act::Edge(e) => edges_tx.send(e).expect("switch task alive"),
                Act::NoteSeen => seen.push(status_rx.borrow().seen.clone()),
            }
        }
        seen_tx.send(seen).ok();
        // the switch stays plugged in
        std::future::pending::<()>().await;
        drop(edges_tx);
    });
    drop(hub);
    let opts = RunOptions {
        max_duration: Some(max),
        stops: Some(receivers.stops),
        status: Some(status_tx),
        ..Default::default()
    };
    let report = opennav::daemon::run(
        devices,
        &settings,
        opts,
        receivers.words,
        clock,
        CancellationToken::new(),
    )
    .await
    .expect("runs");
    cancel.cancel();
    let seen = seen_rx.await.unwrap_or_default();
    let label = report.goal.label().map(str::to_string);
    let sim = sim.summary(label.as_deref()).expect("summary");
    let mut report = report;
    report.said.extend(menu_said.await.expect("menu sentences"));
    Trip { report, sim, seen }
}

fn secs(s: f64) -> Duration {
    Duration::from_secs_f64(s)
}

#[tokio::test(start_paused = true)]
async fn a_switch_press_mid_trip_brings_the_chair_to_rest() {
    // "chair": the chair drives to it at once (the table is at the view's
    // edge at the start, a sliver with no place beside it yet: the chair
    // would first turn to look)
    let t = trip(
        None,
        vec![(secs(0.0), Act::Word(UserInput::Goto("chair".into())))],
        &[2.5],
        secs(8.0),
    )
    .await;
    let r = &t.report;
    assert_eq!(r.outcome, Outcome::Timeout, "{r:?}");
    assert_eq!(
        serde_json::to_value(r.supervisor).expect("state")["Stopped"],
        "UserStop",
        "{r:?}"
    );
    assert!(r.said.iter().any(|l| l.contains("Stopped")), "{:?}", r.said);
    // it was moving, and is at rest
    assert!(t.sim.world.distance_travelled_m > 0.05, "{:?}", t.sim);
    assert!(t.sim.world.v_mps.abs() < 0.02, "{:?}", t.sim);
    assert!(t.sim.world.omega_radps.abs() < 0.05, "{:?}", t.sim);
    assert_eq!(t.sim.world.collision_steps, 0);
    // the press did not open the menu
    assert!(!r.said.iter().any(|l| l.ends_with('?')), "{:?}", r.said);
}

#[tokio::test(start_paused = true)]
async fn one_switch_scanning_chooses_the_second_object_seen_after_two_dwell_times() {
    let dwell = Settings::load(None).expect("defaults").input.switch.dwell_s;
    // perception has looked for a few seconds; a press opens the menu,
    // the first candidate is said, after one dwell the second; a press
    // during the second's dwell chooses it
    let open = 3.0;
    let choose = open + dwell + dwell / 2.0;
    // facing the table and, further, the sofa
    let t = trip(
        Some(-2.8),
        vec![(secs(open - 0.1), Act::NoteSeen)],
        // open the menu; choose; "yes" to "Is it clear around me?"
        &[open, choose, choose + 2.5],
        secs(choose + 6.0),
    )
    .await;
    let r = &t.report;
    let seen = t.seen.first().expect("noted");
    assert!(seen.len() >= 2, "the chair saw {seen:?}");
    let (first, second) = (&seen[0], &seen[1]);
    assert!(
        r.said.contains(&format!("{first}?")) && r.said.contains(&format!("{second}?")),
        "{:?}",
        r.said
    );
    assert!(
        r.said.contains(&format!("Going to the {second}.")),
        "{:?}",
        r.said
    );
    assert_eq!(r.goal.label(), Some(second.as_str()), "{r:?}");
    assert!(
        r.said.iter().any(|l| l.contains("Say yes to let me turn")),
        "{:?}",
        r.said
    );
    assert!(
        t.sim.world.distance_travelled_m > 0.05,
        "{:?} {:?}",
        t.sim,
        r.said
    );
}

#[tokio::test(start_paused = true)]
async fn look_around_from_the_menu_turns_the_chair_once_and_says_what_is_around() {
    let dwell = Settings::load(None).expect("defaults").input.switch.dwell_s;
    // it sees three things from the start (the camera pitched down: the
    // table, a chair and the sofa): "table?", "chair?", "sofa?", then
    // "look around?"
    let open = 3.0;
    let choose = open + 3.0 * dwell + dwell / 2.0;
    let t = trip(
        None,
        vec![(secs(open - 0.1), Act::NoteSeen)],
        // open the menu; choose; "yes" to "Is it clear around me?"
        &[open, choose, choose + 2.5],
        secs(choose + 40.0),
    )
    .await;
    let r = &t.report;
    assert_eq!(t.seen.first().map(Vec::len), Some(3), "{:?}", t.seen);
    assert!(r.said.contains(&"look around?".to_string()), "{:?}", r.said);
    assert!(
        r.said.contains(&"Looking around.".to_string()),
        "{:?}",
        r.said
    );
    let told = r
        .said
        .iter()
        .find(|l| l.starts_with("I looked around. I see "))
        .unwrap_or_else(|| panic!("{:?}", r.said));
    // a whole turn shows more of the room than the start's view
    for thing in ["the chair", "the table", "the sofa"] {
        assert!(told.contains(thing), "{told}");
    }
    assert!(
        ["the cabinet", "the bed"].iter().any(|t| told.contains(t)),
        "nothing more than from the start: {told}"
    );
    // back at rest, with no goal, where it started
    assert_eq!(r.goal.label(), None, "{r:?}");
    assert!(t.sim.world.v_mps.abs() < 0.02 && t.sim.world.omega_radps.abs() < 0.05);
    let moved = (t.sim.world.truth.x_m - 3.4).hypot(t.sim.world.truth.y_m - 2.6);
    assert!(moved < 0.1, "{:?}", t.sim);
    assert_eq!(t.sim.world.collision_steps, 0);
}
