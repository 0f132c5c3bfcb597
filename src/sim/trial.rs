//! One trip on a generated scene: the whole daemon (`daemon::run`, the
//! simulated devices, the real R-Net writer on the simulated chair's bus)
//! on the caller's paused runtime, the prompted word said at the start and
//! "yes" when the chair asks whether it is clear behind; the result as the
//! benchmark reports it.

use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use tokio_util::sync::CancellationToken;

use crate::config::Settings;
use crate::daemon::{Outcome, RunOptions};
use crate::msg::{Clock, TokioClock, UserInput};

use super::devices::devices;
use super::path::shortest_path_m;
use super::scene::Scene;
use super::world::SimWorld;

/// One scene's line.
#[derive(Debug, Clone, Serialize)]
pub struct TrialResult {
    pub scene: u64,
    pub seed: u64,
    pub prompt: String,
    /// At rest, the chair's front within the standoff's tolerance of the
    /// prompted object.
    pub reached: bool,
    pub collision: bool,
    pub fell: bool,
    pub min_clearance_m: f64,
    pub path_m: f64,
    /// None: no place beside the object can be reached.
    pub shortest_path_m: Option<f64>,
    pub time_s: f64,
    pub outcome: Outcome,
    /// The chair's last sentence.
    pub last_said: Option<String>,
}

/// How long a trip may take, s.
pub const TRIAL_LIMIT: Duration = Duration::from_secs(120);

/// Runs scene `index` (generated from `scene.seed`) on the current
/// (paused, current-thread) runtime.
pub async fn run(settings: &Settings, index: u64, scene: &Scene) -> Result<TrialResult, String> {
    let world = SimWorld::in_room(scene.room.clone(), scene.start, settings.drive_params());
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let (devs, sim) = devices(settings, world, clock.clone()).map_err(|e| e.to_string())?;
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let word = scene.prompt.clone();
    tokio::spawn(async move {
        // the word, and "yes" to the question about the space behind
        for (after, input) in [
            (Duration::ZERO, UserInput::Goto(word)),
            (Duration::from_millis(2500), UserInput::Yes),
        ] {
            tokio::time::sleep(after).await;
            if tx.send(input).await.is_err() {
                return;
            }
        }
        std::future::pending::<()>().await;
    });
    let opts = RunOptions {
        exit_on_arrival: true,
        max_duration: Some(TRIAL_LIMIT),
        ..Default::default()
    };
    let r = crate::daemon::run(devs, settings, opts, rx, clock, CancellationToken::new())
        .await
        .map_err(|e| e.to_string())?;
    let s = sim
        .summary(Some(&scene.prompt))
        .ok_or_else(|| "the simulated world was poisoned".to_string())?;
    let g = settings.goal_settings();
    let w = &s.world;
    // base_link to the box is the standoff plus the front offset
    let reached = r.outcome == Outcome::Arrived
        && w.v_mps.abs() < 0.05
        && s.distance_to_goal_object_m.is_some_and(|d| {
            (d - (g.standoff_m + g.front_offset_m)).abs() <= g.reached_within_m + 0.25
        });
    Ok(TrialResult {
        scene: index,
        seed: scene.seed,
        prompt: scene.prompt.clone(),
        reached,
        collision: w.collision_steps > 0,
        fell: w.fell_steps > 0,
        min_clearance_m: w.min_clearance_m,
        path_m: w.distance_travelled_m,
        shortest_path_m: shortest_path_m(
            &scene.room,
            [scene.start.x_m, scene.start.y_m],
            &scene.prompt,
            g.standoff_m + g.front_offset_m,
            g.reached_within_m + 0.25,
            0.4,
        ),
        time_s: r.duration_s,
        outcome: r.outcome,
        last_said: r.said.last().cloned(),
    })
}
