//! `opennav sim`: the closed loop over seeded apartments (one JSON line
//! per scene, then a summary), or synthetic data from the simulator.

use std::path::PathBuf;

use clap::{Args, Subcommand};

use opennav::perception::detector::parse_prompts;

use super::{bad_input, failed, Failure};

#[derive(Args, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct SimArgs {
    #[command(subcommand)]
    pub command: Option<SimCommand>,
    /// How many generated scenes to drive.
    #[arg(long)]
    pub scenes: Option<u64>,
    /// The run's seed (scene k's own seed derives from it and k).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only scene K (as numbered in a run of this seed).
    #[arg(long)]
    pub scene: Option<u64>,
    /// Scenes run at once (default: the core count); the lines do not
    /// depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Only the JSON lines on stdout (no progress on stderr).
    #[arg(long)]
    pub json: bool,
    /// Write each failed trip's recording (scene-K.mcap) and top-down
    /// picture (scene-K.png) here.
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// The simulated detector misses each object in view in a frame with
    /// this probability (the benchmark's default; `[sim]` in config is the
    /// plain simulator's).
    #[arg(long, default_value_t = 0.1)]
    pub misses: f64,
    /// A false box of the word in a frame with this probability.
    #[arg(long, default_value_t = 0.05)]
    pub false_positives: f64,
    /// Box edges move by up to this many pixels.
    #[arg(long, default_value_t = 4.0)]
    pub box_noise_px: f64,
    /// With --record: keep every trip's recording and picture, not only
    /// the failed ones'.
    #[arg(long, requires = "record")]
    pub record_all: bool,
    /// Drive nothing: print each scene as generated (its word, the
    /// chair's start, every box, doorway, step down and walking person,
    /// in the scene's frame), one JSON line a scene.
    #[arg(long, conflicts_with_all = ["record", "jobs"])]
    pub describe: bool,
}

#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Writes a synthetic scene in Replica's layout (rendered RGB-D views, traj.txt, ground-truth cloud).
    ReplicaScene {
        /// Dataset root to write.
        #[arg(long)]
        out: PathBuf,
        /// Scene names (comma-separated); each is the same living room.
        #[arg(long, default_value = "office0")]
        scenes: String,
        /// Views along the orbit.
        #[arg(long, default_value_t = 60)]
        views: usize,
        /// Divide the 640×360 frame size by this.
        #[arg(long, default_value_t = 1)]
        scale_down: usize,
    },
}

pub fn run(config: Option<&std::path::Path>, args: SimArgs) -> Result<(), Failure> {
    let Some(cmd) = args.command else {
        return trips(config, &args);
    };
    match cmd {
        SimCommand::ReplicaScene {
            out,
            scenes,
            views,
            scale_down,
        } => {
            if views == 0 {
                return Err(bad_input(anyhow::anyhow!("--views: at least 1")));
            }
            let cam = opennav::sim::replica::camera(scale_down);
            let room = opennav::sim::room::Room::living_room();
            for name in parse_prompts(&scenes) {
                opennav::sim::replica::write_scene(&out, &name, &room, &cam, views)
                    .map_err(failed)?;
                eprintln!(
                    "wrote {} ({views} views, {}x{})",
                    out.join(&name).display(),
                    cam.w,
                    cam.h
                );
            }
            Ok(())
        }
    }
}

/// Drives the scenes, `jobs` at a time, each on its own paused runtime;
/// prints their lines in scene order, then the summary.
fn trips(config: Option<&std::path::Path>, args: &SimArgs) -> Result<(), Failure> {
    use opennav::sim::scene::{generate, scene_seed};
    use opennav::sim::trial::{self, TrialResult};
    let indices: Vec<u64> = match (args.scene, args.scenes) {
        (Some(k), _) => vec![k],
        (None, Some(0)) => return Err(bad_input(anyhow::anyhow!("--scenes: at least 1"))),
        (None, Some(n)) => (0..n).collect(),
        (None, None) => {
            return Err(bad_input(anyhow::anyhow!(
                "say --scenes N (or --scene K), or a subcommand (replica-scene)"
            )))
        }
    };
    if args.describe {
        for &k in &indices {
            let scene = generate(scene_seed(args.seed, k));
            println!(
                "{}",
                serde_json::to_string(&scene.describe(k)).map_err(failed)?
            );
        }
        return Ok(());
    }
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let mut settings = opennav::config::Settings::load(config).map_err(bad_input)?;
    for (name, v) in [
        ("--misses", args.misses),
        ("--false-positives", args.false_positives),
    ] {
        if !(0.0..=1.0).contains(&v) {
            return Err(bad_input(anyhow::anyhow!(
                "{name} {v}: a probability, 0 to 1"
            )));
        }
    }
    if !(0.0..=100.0).contains(&args.box_noise_px) {
        return Err(bad_input(anyhow::anyhow!(
            "--box-noise-px {}: 0 to 100 pixels",
            args.box_noise_px
        )));
    }
    settings.sim.detector_miss_rate = args.misses;
    settings.sim.detector_false_positive_rate = args.false_positives;
    settings.sim.detector_box_noise_px = args.box_noise_px;
    let settings = settings;
    if let Some(dir) = &args.record {
        std::fs::create_dir_all(dir)
            .map_err(|e| bad_input(anyhow::anyhow!("--record {}: {e}", dir.display())))?;
    }
    let record = args.record.as_deref();
    let t0 = std::time::Instant::now();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let results: std::sync::Mutex<Vec<Option<Result<TrialResult, String>>>> =
        std::sync::Mutex::new(vec![None; indices.len()]);
    std::thread::scope(|scope| {
        for _ in 0..jobs.min(indices.len()) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&k) = indices.get(i) else { return };
                let scene = generate(scene_seed(args.seed, k));
                let r = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .start_paused(true)
                    .build()
                    .map_err(|e| e.to_string())
                    .and_then(|rt| {
                        // the scene's number on every log line of its trip
                        let _scene = tracing::info_span!("scene", k).entered();
                        rt.block_on(trial::run(&settings, k, &scene, record, args.record_all))
                    });
                if let Ok(mut all) = results.lock() {
                    all[i] = Some(r);
                }
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if !args.json {
                    progress(n, indices.len(), t0.elapsed().as_secs_f64());
                }
            });
        }
    });
    if !args.json {
        eprintln!();
    }
    let results = results
        .into_inner()
        .map_err(|_| failed(anyhow::anyhow!("a scene's thread panicked")))?;
    let mut ok = Vec::new();
    for (i, r) in results.into_iter().enumerate() {
        match r {
            Some(Ok(t)) => {
                println!("{}", serde_json::to_string(&t).map_err(failed)?);
                ok.push(t);
            }
            Some(Err(e)) => return Err(failed(anyhow::anyhow!("scene {}: {e}", indices[i]))),
            None => return Err(failed(anyhow::anyhow!("scene {} did not run", indices[i]))),
        }
    }
    let median = |mut v: Vec<f64>| -> Option<f64> {
        v.sort_by(f64::total_cmp);
        (!v.is_empty()).then(|| v[v.len() / 2])
    };
    // the path against the shortest drive to the chair's own stopping
    // place, and against the shortest drive to the edge of the `reached`
    // test's wider tolerance
    let ratios = |yardstick: fn(&TrialResult) -> Option<f64>| -> Vec<f64> {
        ok.iter()
            .filter(|t| t.reached)
            .filter_map(|t| yardstick(t).filter(|s| *s > 0.1).map(|s| t.path_m / s))
            .collect()
    };
    // how the trips that failed ended, reachable or not: where to look
    // first after a change
    let failed_by_outcome = |reachable: bool| {
        let mut counts = std::collections::BTreeMap::<String, usize>::new();
        for t in ok.iter().filter(|t| t.reachable == reachable && !t.success) {
            *counts.entry(outcome_name(&t.outcome)).or_default() += 1;
        }
        counts
    };
    let summary = serde_json::json!({"summary": {
        "scenes": ok.len(),
        "reached": ok.iter().filter(|t| t.reached).count(),
        "success": ok.iter().filter(|t| t.success).count(),
        "unreachable": ok.iter().filter(|t| !t.reachable).count(),
        "stops": ok.iter().map(|t| t.stops).sum::<u64>(),
        "questions": ok.iter().map(|t| t.questions).sum::<u64>(),
        "collisions": ok.iter().filter(|t| t.collision).count(),
        "fell": ok.iter().filter(|t| t.fell).count(),
        "min_clearance_m": ok.iter().map(|t| t.min_clearance_m).fold(f64::INFINITY, f64::min),
        "path_ratio_median": median(ratios(|t| t.shortest_path_to_standoff_m)),
        "path_ratio_median_reached_band": median(ratios(|t| t.shortest_path_m)),
        "time_s_median": median(ok.iter().map(|t| t.time_s).collect()),
        "failed_by_outcome": {
            "reachable": failed_by_outcome(true),
            "unreachable": failed_by_outcome(false),
        },
        "wall_s": t0.elapsed().as_secs_f64(),
    }});
    println!("{summary}");
    Ok(())
}

/// An outcome's name as each scene's line has it ("not_found",
/// "gave_up", …; a fault, whatever its task, "fault").
fn outcome_name(outcome: &opennav::daemon::control::Outcome) -> String {
    match serde_json::to_value(outcome) {
        Ok(serde_json::Value::String(name)) => name,
        Ok(serde_json::Value::Object(o)) if o.len() == 1 => {
            o.keys().next().cloned().unwrap_or_else(|| format!("{o:?}"))
        }
        Ok(other) => other.to_string(),
        Err(e) => format!("{outcome:?} (not written as JSON: {e})"),
    }
}

/// A progress bar on stderr: done of all, elapsed and the time left.
fn progress(done: usize, all: usize, elapsed_s: f64) {
    const WIDTH: usize = 30;
    let filled = done * WIDTH / all.max(1);
    let left_s = elapsed_s / done.max(1) as f64 * all.saturating_sub(done) as f64;
    eprint!(
        "\r[{}{}] {done}/{all} scenes, {elapsed_s:.0} s, ~{left_s:.0} s left ",
        "#".repeat(filled),
        " ".repeat(WIDTH - filled)
    );
}
