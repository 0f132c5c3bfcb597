//! `opennav eval`: the evaluation protocols (instance AP, the paper's Replica run).

use std::path::PathBuf;

use anyhow::Context;
use clap::{Subcommand, ValueEnum};

use opennav::config::Settings;
use opennav::perception::detector::parse_prompts;
use opennav::setup::{open_configured_detector, open_configured_segmenter, PerceptionChoice};

use super::{bad_input, failed, Failure};

#[derive(Subcommand, Debug)]
pub enum EvalCommand {
    /// Open3DIS's 3D instance AP on one case file (scenes + RLE predictions), JSON out.
    Instances {
        /// Case JSON: {"scenes":[{"id","sem","inst"}],"predictions":[{"scene","label_id","score","mask_rle"}]}.
        case: PathBuf,
        /// `detector`: the predictions' scores; `one`: 1.0 for all (Open3DIS's Replica runs).
        #[arg(long, value_enum, default_value = "detector")]
        score_mode: ScoreModeArg,
    },
    /// The paper's Replica protocol on a dataset in Replica's layout (see docs/evaluation.md).
    Replica {
        /// Dataset root (cam_params.json, <scene>/traj.txt, <scene>/results/, ground_truth/).
        #[arg(long)]
        root: PathBuf,
        /// Scenes, comma-separated (default: every folder with a traj.txt).
        #[arg(long)]
        scenes: Option<String>,
        /// Views per scene, evenly spaced (default: all).
        #[arg(long)]
        views: Option<usize>,
        /// Detector model file (default: the configured one).
        #[arg(long)]
        detector: Option<PathBuf>,
        /// Use the simulator's ground-truth detector (synthetic scenes only).
        #[arg(long, conflicts_with = "detector")]
        sim_gt: bool,
        /// With --sim-gt: miss every other object.
        #[arg(long, requires = "sim_gt")]
        degraded: bool,
        /// Segmenter: depth, sam, auto, or a directory with the SAM encoder and decoder.
        #[arg(long)]
        segmenter: Option<String>,
        /// Models directory (overrides models.dir).
        #[arg(long)]
        models: Option<PathBuf>,
        /// Cross-view merge rule.
        #[arg(long, value_enum, default_value = "paper")]
        merge: MergeArg,
        /// `one`: every score 1.0 (Open3DIS's Replica runs); `detector`: the scores.
        #[arg(long, value_enum, default_value = "one")]
        score_mode: ScoreModeArg,
        /// Minimum detection score (overrides perception.score_threshold).
        #[arg(long)]
        score_threshold: Option<f32>,
        /// Where to write the JSON report.
        #[arg(long, default_value = "eval_replica.json")]
        out: PathBuf,
    },
}

#[derive(Debug, Clone, Copy, ValueEnum, PartialEq)]
pub enum MergeArg {
    /// The paper's: same label, 3D IoU > 0.8.
    Paper,
    /// Also when one box lies mostly (> 80 %) inside the other.
    Containment,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ScoreModeArg {
    Detector,
    One,
}

pub fn eval_instances(case: &std::path::Path, mode: ScoreModeArg) -> Result<(), Failure> {
    use opennav::eval::instances::{evaluate, EvalCase, ScoreMode};
    let text = std::fs::read_to_string(case)
        .with_context(|| case.display().to_string())
        .map_err(bad_input)?;
    let case_data: EvalCase = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a valid case", case.display()))
        .map_err(bad_input)?;
    let mode = match mode {
        ScoreModeArg::Detector => ScoreMode::Detector,
        ScoreModeArg::One => ScoreMode::One,
    };
    let r = evaluate(&case_data, mode)
        .with_context(|| case.display().to_string())
        .map_err(bad_input)?;
    let classes: serde_json::Map<String, serde_json::Value> = r
        .classes
        .iter()
        .map(|(n, c)| Ok((n.clone(), serde_json::to_value(c)?)))
        .collect::<Result<_, serde_json::Error>>()
        .map_err(failed)?;
    let out = serde_json::json!({
        "mAP": r.map, "mAP50": r.map50, "mAP25": r.map25,
        "score_mode": r.score_mode,
        "classes": classes,
    });
    println!("{}", serde_json::to_string_pretty(&out).map_err(failed)?);
    Ok(())
}

pub struct EvalReplicaArgs {
    root: PathBuf,
    scenes: Option<String>,
    views: Option<usize>,
    choice: PerceptionChoice,
    sim_gt: bool,
    degraded: bool,
    merge: MergeArg,
    score_mode: ScoreModeArg,
    out: PathBuf,
}

pub fn eval_replica(settings: &Settings, a: EvalReplicaArgs) -> Result<(), Failure> {
    use opennav::eval::instances::{ScoreMode, REPLICA_CLASSES};
    use opennav::eval::replica::{
        list_scenes, read_cam_params, run, ModelViewDetector, RunSettings, ViewDetector,
    };
    use opennav::perception::boxes::MergeRule;
    use std::io::IsTerminal;

    let root_arg = || format!("--root {}", a.root.display());
    let scenes = match &a.scenes {
        Some(s) => parse_prompts(s),
        None => list_scenes(&a.root)
            .context(root_arg())
            .map_err(bad_input)?,
    };
    if scenes.is_empty() {
        return Err(bad_input(anyhow::anyhow!(
            "{}: no scenes (folders with a traj.txt)",
            root_arg()
        )));
    }
    let mut detector: Box<dyn ViewDetector> = if a.sim_gt {
        let cam = read_cam_params(&a.root)
            .context(root_arg())
            .map_err(bad_input)?;
        let mut d =
            opennav::sim::replica::SimGtDetector::new(opennav::sim::room::Room::living_room(), cam);
        if a.degraded {
            d.degrade = Some(opennav::sim::replica::Degrade {
                miss_every_other: true,
                box_fraction: 1.0,
            });
        }
        Box::new(d)
    } else {
        let mut det = open_configured_detector(settings, &a.choice).map_err(bad_input)?;
        let prompts: Vec<String> = REPLICA_CLASSES
            .iter()
            .map(|c| c.replace('-', " "))
            .collect();
        let report = det.set_prompts(&prompts).map_err(bad_input)?;
        if !report.unmatched.is_empty() {
            eprintln!(
                "the detector has no class for: {}",
                report.unmatched.join(", ")
            );
        }
        Box::new(ModelViewDetector(det))
    };
    let mut segmenter = open_configured_segmenter(settings, &a.choice).map_err(bad_input)?;
    let run_settings = RunSettings {
        views: a.views,
        merge: match a.merge {
            MergeArg::Paper => MergeRule::paper(settings.perception.merge_iou),
            MergeArg::Containment => MergeRule {
                iou: settings.perception.merge_iou,
                containment: Some(0.8),
            },
        },
        geometry: settings.geometry_settings(),
        mask_voxel_m: 0.03,
        score_mode: match a.score_mode {
            ScoreModeArg::Detector => ScoreMode::Detector,
            ScoreModeArg::One => ScoreMode::One,
        },
    };
    let tty = std::io::stderr().is_terminal();
    let mut progress = |scene: &str, i: usize, n: usize| {
        if tty {
            eprint!("\r{scene}: {i}/{n} views");
            if i == n {
                eprintln!();
            }
        } else if i == n || i.is_multiple_of((n / 10).max(1)) {
            eprintln!("{scene}: {i}/{n} views");
        }
    };
    let report = run(
        &a.root,
        &scenes,
        detector.as_mut(),
        segmenter.as_mut(),
        &run_settings,
        &mut progress,
    )
    .map_err(|e| match e {
        opennav::eval::replica::ReplicaError::File { .. }
        | opennav::eval::replica::ReplicaError::Image(_) => bad_input(e),
        other => failed(other),
    })?;
    let json = report.to_json(&run_settings);
    let text = serde_json::to_string_pretty(&json).map_err(failed)?;
    std::fs::write(&a.out, text)
        .with_context(|| format!("--out {}", a.out.display()))
        .map_err(bad_input)?;
    print!("{}", report.table());
    for s in &report.scenes {
        println!(
            "{}: {} views, {:.3} s per view (median {:.3}), {:.2} s per scene, {} fused objects",
            s.scene,
            s.views,
            s.secs_per_view_mean,
            s.secs_per_view_median,
            s.secs_per_scene,
            s.fused_objects
        );
    }
    println!(
        "detector: {}; masks: {}; report: {}",
        report.detector,
        opennav::eval::replica::MASK_RULE,
        a.out.display()
    );
    Ok(())
}

pub fn run(mut settings: Settings, cmd: EvalCommand) -> Result<(), Failure> {
    match cmd {
        EvalCommand::Instances { case, score_mode } => eval_instances(&case, score_mode),
        EvalCommand::Replica {
            root,
            scenes,
            views,
            detector,
            sim_gt,
            degraded,
            segmenter,
            models,
            merge,
            score_mode,
            score_threshold,
            out,
        } => {
            if let Some(t) = score_threshold {
                settings.perception.score_threshold = t;
                settings
                    .validate()
                    .map_err(|e| bad_input(anyhow::anyhow!("--score-threshold: {e}")))?;
            }
            eval_replica(
                &settings,
                EvalReplicaArgs {
                    root,
                    scenes,
                    views,
                    choice: PerceptionChoice {
                        detector,
                        segmenter,
                        models_dir: models,
                    },
                    sim_gt,
                    degraded,
                    merge,
                    score_mode,
                    out,
                },
            )
        }
    }
}
