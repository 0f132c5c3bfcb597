//! One trip on a generated scene: the whole daemon (`daemon::run`, the
//! simulated devices, the real R-Net writer on the simulated chair's bus)
//! on the caller's paused runtime, the prompted word said at the start; a
//! simulated person answers the chair's questions truthfully (is it clear
//! behind? — from the world, not from what the chair knows); the result as
//! the benchmark reports it, and for a failed trip its recording and a
//! top-down picture.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde::Serialize;
use tokio_util::sync::CancellationToken;

use crate::config::Settings;
use crate::daemon::{Outcome, RunOptions};
use crate::msg::{Clock, TokioClock, UserInput};

use super::devices::devices;
use super::drive::{drivable, Drivable};
use super::path::shortest_path_m;
use super::scene::Scene;
use super::world::Footprint;
use super::world::SimWorld;

/// One scene's line.
#[derive(Debug, Clone, Serialize)]
pub struct TrialResult {
    pub scene: u64,
    pub seed: u64,
    pub prompt: String,
    /// What the scene holds: rooms, a step down, a person walking, the
    /// word only in a sunken room (unreachable by construction).
    pub rooms: usize,
    pub step_down: bool,
    pub person: bool,
    pub sunken_room: bool,
    /// At rest, the chair's front within the standoff's tolerance of the
    /// prompted object.
    pub reached: bool,
    pub collision: bool,
    pub fell: bool,
    pub min_clearance_m: f64,
    /// At the end: the distance from base_link to the nearest object of
    /// the word less the standoff and the front's offset (positive: short
    /// of where it should stop), m.
    pub standoff_error_m: Option<f64>,
    /// What the chair first touched, when and how it moved then (a
    /// collision's explanation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<String>,
    pub path_m: f64,
    /// The shortest drive to a place the `reached` test accepts (the
    /// standoff ± the arrival's tolerance and 0.25 m) for a disc of the
    /// chair's half-width, the widest disc inside its footprint: no drive
    /// of the chair is shorter. None: not even that disc reaches a place
    /// beside the object.
    pub shortest_path_m: Option<f64>,
    /// The shortest drive to a place the chair's own arrival accepts (the
    /// standoff ± `goal.reached_within_m`): the path ratio's yardstick,
    /// since the chair drives to the standoff, not to the edge of the
    /// benchmark's tolerance. None where `shortest_path_m` is None (or no
    /// such place can be reached).
    pub shortest_path_to_standoff_m: Option<f64>,
    /// The chair itself — its footprint, turning on the spot and driving
    /// straight — can reach a place the `reached` test accepts
    /// (`sim::drive`). A scene where it cannot counts as a success when the
    /// chair says so and stops.
    pub reachable: bool,
    pub time_s: f64,
    pub outcome: Outcome,
    /// Times the chair stopped for safety on the way (the supervisor's
    /// stops, the planner's) — not counting the stop on arrival.
    pub stops: u64,
    /// Times the chair asked the person whether it is clear (behind it,
    /// all around it) before a turn on the spot or a back-up.
    pub questions: u64,
    /// Doorway passages begun and given up, back-offs.
    pub navigation: crate::daemon::control::NavigationStats,
    /// The chair's last sentence.
    pub last_said: Option<String>,
    /// The supervisor's state at the end (why a stuck chair stood).
    pub supervisor: crate::msg::SupervisorState,
    /// Reached, or (no place beside the object can be reached) the chair
    /// said so and stopped; and no collision, no fall.
    pub success: bool,
    /// The failed trip's recording and picture.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
}

/// How long a trip may take beyond the search's limit
/// (`goal.search_at_most_s`): the way to what it found.
pub const TRIAL_AFTER_SEARCH: Duration = Duration::from_secs(30);

/// A person's time to answer a question, s.
const ANSWER_AFTER: Duration = Duration::from_millis(1500);
/// The chair's corners reach this far from base_link when it turns on the
/// spot (0.55 m ahead, 0.45 m behind, 0.35 m to each side), plus a margin:
/// nothing behind within this, the person says it is clear (all around,
/// the circle the chair's word for the floor holds in), m.
const CLEAR_BEHIND_M: f64 = crate::safety::rear::AROUND_VOUCHED_M;

/// Backing up, the chair asks about half a metre behind its rear edge
/// (0.45 m behind base_link; the word holds for
/// [`crate::safety::rear::BACK_UP_VOUCHED_M`] of that, the rest is for
/// stopping): the person looks that far, along its width and 0.05 m a
/// side (the word holds turned 0.05 rad at most, or 2 cm aside), m.
const CLEAR_BACK_M: f64 = 0.50;
const CLEAR_BACK_HALF_WIDTH_M: f64 = 0.40;
/// The person's look is sampled this finely, m.
const LOOK_STEP_M: f64 = 0.01;

/// Where the chair asked the person to look.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Look {
    /// Behind, for a turn on the spot.
    Behind,
    /// All around, for a turn on the spot.
    Around,
    /// All around but straight ahead (the strip of the chair's width
    /// before it, which its camera saw), for a turn on the spot.
    AroundBeside,
    /// Behind, for backing up.
    Back,
}

/// What a truthful person sees around the chair (walls, boxes taller than
/// 5 cm, steps down): for a turn, nothing within [`CLEAR_BEHIND_M`] of
/// base_link on the rear half (`Behind`), or (`Around`) nothing there
/// and nothing low (under the lasers' plane, `laser_plane_m` up) or
/// stepping down on the front half (`AroundBeside`: off the strip
/// `half_width_m` either side of base_link straight ahead): what the
/// chair asks about is what it cannot see, and the lasers see the rest
/// ahead and beside it; backing up, nothing in the strip the rear backs
/// into ([`CLEAR_BACK_M`]).
fn clear_behind(
    w: &super::world::SimWorld,
    look: Look,
    laser_plane_m: f64,
    half_width_m: f64,
) -> bool {
    let t = w.truth;
    let (c, s) = (t.theta_rad.cos(), t.theta_rad.sin());
    let [sx, sy, _] = w.room.size_m;
    // each box, and whether it is low (under the lasers' plane)
    let mut boxes: Vec<([f64; 2], [f64; 2], bool)> = w
        .room
        .objects
        .iter()
        .filter(|o| o.max_m[2] > 0.05)
        .map(|o| {
            (
                [o.min_m[0], o.min_m[1]],
                [o.max_m[0], o.max_m[1]],
                o.max_m[2] < laser_plane_m,
            )
        })
        .collect();
    boxes.extend(w.room.pits.iter().map(|p| (p.min_m, p.max_m, true)));
    // the outer walls as thin boxes
    boxes.extend([
        ([-1.0, -1.0], [sx + 1.0, 0.0], false),
        ([-1.0, sy], [sx + 1.0, sy + 1.0], false),
        ([-1.0, -1.0], [0.0, sy + 1.0], false),
        ([sx, -1.0], [sx + 1.0, sy + 1.0], false),
    ]);
    // sample the strip behind, the rear half-disc or the whole disc every
    // centimetre or so (a coarser look let a box's corner between its
    // samples: a person looking sees it)
    let n = |len_m: f64| (len_m / LOOK_STEP_M).ceil().max(1.0) as usize;
    let samples: Vec<[f64; 2]> = if look == Look::Back {
        let (ni, nk) = (n(CLEAR_BACK_M), n(2.0 * CLEAR_BACK_HALF_WIDTH_M));
        (0..=ni)
            .flat_map(|i| {
                (0..=nk).map(move |k| {
                    [
                        -0.45 - CLEAR_BACK_M * i as f64 / ni as f64,
                        CLEAR_BACK_HALF_WIDTH_M * (2.0 * k as f64 / nk as f64 - 1.0),
                    ]
                })
            })
            .collect()
    } else {
        // the rear half, or the whole circle
        let (from, span) = match look {
            Look::Around | Look::AroundBeside => (0.0, std::f64::consts::TAU),
            _ => (std::f64::consts::FRAC_PI_2, std::f64::consts::PI),
        };
        let (bearings, radii) = (n(span * CLEAR_BEHIND_M), n(CLEAR_BEHIND_M));
        (0..=bearings)
            .flat_map(move |i| {
                let a = from + span * i as f64 / bearings as f64;
                (1..=radii).map(move |k| {
                    let r = CLEAR_BEHIND_M * k as f64 / radii as f64;
                    [r * a.cos(), r * a.sin()]
                })
            })
            .collect()
    };
    {
        for [bx, by] in samples {
            let (x, y) = (t.x_m + c * bx - s * by, t.y_m + s * bx + c * by);
            // ahead of base_link, looking all round: only what is low,
            // and only beside the chair when asked about that alone
            if look == Look::AroundBeside && bx > 0.0 && by.abs() <= half_width_m {
                continue;
            }
            let low_only = matches!(look, Look::Around | Look::AroundBeside) && bx > 0.0;
            if boxes.iter().any(|(lo, hi, low)| {
                (*low || !low_only) && x >= lo[0] && x <= hi[0] && y >= lo[1] && y <= hi[1]
            }) {
                return false;
            }
        }
    }
    true
}

/// The simulated person: says the word, then listens to the chair and
/// answers its questions from what is really there.
async fn person(
    word: String,
    laser_plane_m: f64,
    half_width_m: f64,
    world: Arc<Mutex<super::world::SimWorld>>,
    tx: tokio::sync::mpsc::Sender<UserInput>,
    mut heard: tokio::sync::mpsc::UnboundedReceiver<String>,
) {
    {
        if tx.send(UserInput::Goto(word)).await.is_err() {
            return;
        }
        while let Some(sentence) = heard.recv().await {
            let look = if sentence.contains("Is it clear around me?") {
                Some(if sentence.contains("low beside or before me") {
                    Look::Around
                } else {
                    Look::AroundBeside
                })
            } else if sentence.contains("Is it clear behind?") {
                Some(if sentence.contains("back up") {
                    Look::Back
                } else {
                    Look::Behind
                })
            } else {
                None
            };
            let answer = if let Some(look) = look {
                tokio::time::sleep(ANSWER_AFTER).await;
                let clear = world
                    .lock()
                    .map(|w| clear_behind(&w, look, laser_plane_m, half_width_m))
                    .unwrap_or(false);
                Some(if clear { UserInput::Yes } else { UserInput::No })
            } else if sentence.starts_with("Staying here.") {
                // the person would not let it turn: the trip is over
                Some(UserInput::Quit)
            } else {
                None
            };
            if let Some(a) = answer {
                if tx.send(a).await.is_err() {
                    return;
                }
            }
        }
    }
}

/// Runs scene `index` (generated from `scene.seed`) on the current
/// (paused, current-thread) runtime; with `record`, a failed trip (every
/// trip, with `record_all`) leaves `scene-K.mcap` and `scene-K.png` there.
pub async fn run(
    settings: &Settings,
    index: u64,
    scene: &Scene,
    record: Option<&Path>,
    record_all: bool,
) -> Result<TrialResult, String> {
    // the detector's noise drawn from the scene's own seed
    let mut settings = settings.clone();
    settings.sim.seed = scene.seed;
    let settings = &settings;
    let mut world = SimWorld::in_room(scene.room.clone(), scene.start, settings.drive_params());
    world.walkers = scene
        .walkers
        .iter()
        .map(|w| super::world::Walking::new(w.clone()))
        .collect();
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let (devs, sim) = devices(settings, world, clock.clone()).map_err(|e| e.to_string())?;
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let (speech_tx, speech_rx) = tokio::sync::mpsc::unbounded_channel();
    // the lower scanner's plane: under it, only the camera sees a box
    let laser_plane_m =
        settings.lasers.left.translation_m[2].min(settings.lasers.right.translation_m[2]);
    tokio::spawn(person(
        scene.prompt.clone(),
        laser_plane_m,
        settings.safety.chair_width_m / 2.0,
        sim.world.clone(),
        tx,
        speech_rx,
    ));
    let mcap: Option<PathBuf> = record.map(|d| d.join(format!("scene-{index}.mcap")));
    let opts = RunOptions {
        exit_on_arrival: true,
        max_duration: Some(settings.goal_settings().search_at_most + TRIAL_AFTER_SEARCH),
        record: mcap.clone(),
        speech: Some(speech_tx),
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
    // base_link to the box is the standoff plus the front offset, on the
    // object's side of any wall
    let here = [w.truth.x_m, w.truth.y_m];
    let beside = scene.room.objects.iter().any(|o| {
        o.label.eq_ignore_ascii_case(&scene.prompt)
            && (super::scene::distance_to_box(here[0], here[1], o)
                - (g.standoff_m + g.front_offset_m))
                .abs()
                <= g.reached_within_m + 0.25
            && super::path::in_sight(&scene.room, here, o)
    });
    // how far the chair's front stopped from the nearest object of the
    // word, less the standoff (positive: short of it)
    let standoff_error_m = scene
        .room
        .objects
        .iter()
        .filter(|o| o.label.eq_ignore_ascii_case(&scene.prompt))
        .map(|o| super::scene::distance_to_box(here[0], here[1], o))
        .min_by(f64::total_cmp)
        .map(|d| d - (g.standoff_m + g.front_offset_m));
    let reached = r.outcome == Outcome::Arrived && w.v_mps.abs() < 0.05 && beside;
    let shortest = shortest_path_m(
        &scene.room,
        [scene.start.x_m, scene.start.y_m],
        &scene.prompt,
        g.standoff_m + g.front_offset_m,
        g.reached_within_m + 0.25,
        Footprint::CHAIR.half_width_m,
    );
    let shortest_to_standoff = shortest.and_then(|_| {
        shortest_path_m(
            &scene.room,
            [scene.start.x_m, scene.start.y_m],
            &scene.prompt,
            g.standoff_m + g.front_offset_m,
            g.reached_within_m,
            Footprint::CHAIR.half_width_m,
        )
    });
    // the chair's footprint with the margin its supervisor keeps at a
    // crawl (passing a doorway): a place only a narrower margin reaches is
    // one the chair should refuse
    let margin_m = settings
        .safety
        .corridor_margin_slow_m
        .min(settings.safety.corridor_margin_m);
    let kept_clear = Footprint {
        front_m: Footprint::CHAIR.front_m + margin_m,
        rear_m: Footprint::CHAIR.rear_m + margin_m,
        half_width_m: Footprint::CHAIR.half_width_m + margin_m,
    };
    let reachable = match drivable(
        &scene.room,
        scene.start,
        &scene.prompt,
        g.standoff_m + g.front_offset_m,
        g.reached_within_m + 0.25,
        kept_clear,
    ) {
        Drivable::Yes => true,
        Drivable::No => false,
        Drivable::Undecided => {
            // counted reachable: giving up there is then a failure
            tracing::warn!(
                scene = index,
                "the benchmark's search for a drive to the word ran past its bound; \
                     the scene is counted reachable"
            );
            true
        }
    };
    let collision = w.collision_steps > 0;
    let contact = w.first_contact.map(|c| {
        let what = match c.object.and_then(|i| scene.room.objects.get(i)) {
            Some(o) => format!("{} ({:.2} m high)", o.label, o.max_m[2]),
            None => "the outer wall".to_string(),
        };
        format!(
            "{what} at {:.1} s, moving {:.2} m/s, {:.2} rad/s",
            c.time_s, c.v_mps, c.omega_radps
        )
    });
    let fell = w.fell_steps > 0;
    let said_unreachable = !reachable
        && w.v_mps.abs() < 0.05
        && matches!(
            r.outcome,
            Outcome::NotFound | Outcome::Lost | Outcome::Quit | Outcome::GaveUp
        );
    let success = (reached || said_unreachable) && !collision && !fell;
    let mut files = Vec::new();
    if let (Some(dir), Some(mcap)) = (record, mcap) {
        if success && !record_all {
            std::fs::remove_file(&mcap).map_err(|e| format!("removing {}: {e}", mcap.display()))?;
        } else {
            files.push(mcap.display().to_string());
            let png = dir.join(format!("scene-{index}.png"));
            let caption = format!(
                "scene {index} \"{}\": {:?}{}{}",
                scene.prompt,
                r.outcome,
                if collision { ", collision" } else { "" },
                if fell { ", fell" } else { "" },
            );
            let picture = sim
                .world
                .lock()
                .map_err(|_| "the simulated world was poisoned".to_string())
                .and_then(|w| {
                    super::topdown::render(&w, &scene.prompt, &caption).map_err(|e| e.to_string())
                })?;
            picture
                .save_png(&png)
                .map_err(|e| format!("{}: {e}", png.display()))?;
            files.push(png.display().to_string());
        }
    }
    Ok(TrialResult {
        scene: index,
        seed: scene.seed,
        prompt: scene.prompt.clone(),
        rooms: scene.rooms_x_m.len(),
        step_down: !scene.room.pits.is_empty() && !scene.sunken_room,
        person: !scene.walkers.is_empty(),
        sunken_room: scene.sunken_room,
        reached,
        collision,
        fell,
        min_clearance_m: w.min_clearance_m,
        standoff_error_m,
        contact,
        path_m: w.distance_travelled_m,
        shortest_path_m: shortest,
        shortest_path_to_standoff_m: shortest_to_standoff,
        reachable,
        time_s: r.duration_s,
        outcome: r.outcome,
        stops: r.planner.stops + r.stops,
        questions: r.said.iter().filter(|s| s.contains("Is it clear")).count() as u64,
        navigation: r.navigation,
        last_said: r.said.last().cloned(),
        supervisor: r.supervisor,
        success,
        files,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Pose2;
    use crate::sim::room::{Room, SimObject};

    /// A 4 × 4 m room with one box of `height_m` whose near face is 0.5 m
    /// from the chair in the middle, ahead of it (`ahead`) or behind.
    fn world_with_box(height_m: f64, ahead: bool) -> super::super::world::SimWorld {
        let x = if ahead { [2.5, 2.8] } else { [1.2, 1.5] };
        world_with_box_at(x, [1.9, 2.1], height_m)
    }

    /// The same room, the box over `x` × `y` (the chair at (2, 2) facing +x).
    fn world_with_box_at(x: [f64; 2], y: [f64; 2], height_m: f64) -> super::super::world::SimWorld {
        let room = Room {
            size_m: [4.0, 4.0, 2.5],
            objects: vec![SimObject {
                label_id: 1,
                label: "box".into(),
                min_m: [x[0], y[0], 0.0],
                max_m: [x[1], y[1], height_m],
                color: [0, 0, 0],
            }],
            pits: Vec::new(),
        };
        let start = Pose2 {
            x_m: 2.0,
            y_m: 2.0,
            theta_rad: 0.0,
        };
        super::super::world::SimWorld::in_room(
            room,
            start,
            crate::config::Settings::defaults().drive_params(),
        )
    }

    /// Asked about all round, the person counts ahead of the chair only
    /// what the lasers (0.66 m up) cannot see, and behind it anything.
    #[test]
    fn all_round_the_person_counts_only_low_things_ahead_and_anything_behind() {
        let plane = 0.66;
        let clear = |h: f64, ahead: bool, look: Look| {
            clear_behind(&world_with_box(h, ahead), look, plane, 0.35)
        };
        // ahead: a low box is not clear, a tall cupboard the lasers see is
        assert!(!clear(0.3, true, Look::Around));
        assert!(clear(1.8, true, Look::Around));
        // behind: either is not clear
        assert!(!clear(0.3, false, Look::Around));
        assert!(!clear(1.8, false, Look::Around));
        // asked about behind only, nothing ahead counts
        assert!(clear(0.3, true, Look::Behind));
        assert!(!clear(1.8, false, Look::Behind));
    }

    /// Asked about behind and beside only (the camera saw the strip
    /// before the chair), the person leaves out a low box straight ahead
    /// but counts one low beside the front and anything behind.
    #[test]
    fn asked_about_beside_the_person_leaves_out_the_strip_ahead() {
        let plane = 0.66;
        let half = 0.35;
        let ahead = |h: f64, look: Look| clear_behind(&world_with_box(h, true), look, plane, half);
        assert!(ahead(0.3, Look::AroundBeside));
        assert!(!ahead(0.3, Look::Around));
        assert!(!clear_behind(
            &world_with_box(0.3, false),
            Look::AroundBeside,
            plane,
            half
        ));
        // low, 0.45–0.6 m to the left of base_link beside the front
        let beside = world_with_box_at([2.05, 2.3], [2.45, 2.6], 0.3);
        assert!(!clear_behind(&beside, Look::AroundBeside, plane, half));
        assert!(!clear_behind(&beside, Look::Around, plane, half));
        assert!(clear_behind(&beside, Look::Behind, plane, half));
    }
}
