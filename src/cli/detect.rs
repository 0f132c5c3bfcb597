//! `opennav detect`: prompted objects in one RGB(-D) image — 2D boxes, and
//! 3D objects in `base_link` with depth and calibration.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use opennav::config::Settings;
use opennav::msg::RgbdCalibration;
use opennav::msg::{DepthImage, RgbImage};
use opennav::output::{overlay, slug, write_ply, DetectReport};
use opennav::perception::detector::parse_prompts;
use opennav::perception::pipeline::Pipeline;
use opennav::setup::{open_configured_detector, open_configured_segmenter, PerceptionChoice};

use super::{bad_input, failed, Failure, Format};

#[derive(Args, Debug)]
pub struct DetectArgs {
    /// Colour image (PNG or JPEG).
    #[arg(long)]
    pub rgb: PathBuf,
    /// Depth image, 16-bit PNG (scale from the calibration).
    #[arg(long, requires = "calibration")]
    pub depth: Option<PathBuf>,
    /// Calibration JSON (opennav-calibration/1).
    #[arg(long, requires = "depth")]
    pub calibration: Option<PathBuf>,
    /// What to find, comma-separated: "chair, person".
    #[arg(long)]
    pub prompt: String,
    /// Detector model file (backend recognised from its inputs/outputs).
    #[arg(long)]
    pub detector: Option<PathBuf>,
    /// Segmenter: depth, sam, auto, or a directory with the SAM encoder and decoder.
    #[arg(long)]
    pub segmenter: Option<String>,
    /// Models directory (overrides models.dir).
    #[arg(long)]
    pub models: Option<PathBuf>,
    /// Minimum detection score (overrides perception.score_threshold).
    #[arg(long)]
    pub score_threshold: Option<f32>,
    /// Write an overlay PNG and a PLY per object here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "json")]
    pub format: Format,
}

pub fn run(mut settings: Settings, args: DetectArgs) -> Result<(), Failure> {
    let DetectArgs {
        rgb,
        depth,
        calibration,
        prompt,
        detector,
        segmenter,
        models,
        score_threshold,
        out,
        format,
    } = args;

    if let Some(t) = score_threshold {
        settings.perception.score_threshold = t;
        settings
            .validate()
            .map_err(|e| bad_input(anyhow::anyhow!("--score-threshold: {e}")))?;
    }
    let prompts = parse_prompts(&prompt);
    if prompts.is_empty() {
        return Err(bad_input(anyhow::anyhow!(
            "--prompt: empty; name at least one object, e.g. --prompt \"chair\""
        )));
    }
    let color = RgbImage::load(&rgb).map_err(bad_input)?;
    let rgbd = match (&depth, &calibration) {
        (Some(d), Some(c)) => {
            let cal = RgbdCalibration::load(c).map_err(bad_input)?;
            let depth = DepthImage::load_png(d, cal.depth_scale_m as f32).map_err(bad_input)?;
            Some((cal, depth))
        }
        _ => None,
    };
    let choice = PerceptionChoice {
        detector,
        segmenter,
        models_dir: models,
    };
    let det = open_configured_detector(&settings, &choice).map_err(bad_input)?;
    let seg = if rgbd.is_some() {
        open_configured_segmenter(&settings, &choice).map_err(bad_input)?
    } else {
        Box::new(opennav::perception::segmenter::DepthBoxSegmenter::default())
    };
    let calib = match &rgbd {
        Some((c, _)) => c.clone(),
        None => RgbdCalibration::registered(
            opennav::msg::Intrinsics {
                width: color.width(),
                height: color.height(),
                fx: color.width() as f64,
                fy: color.width() as f64,
                cx: color.width() as f64 / 2.0,
                cy: color.height() as f64 / 2.0,
            },
            nalgebra::Isometry3::identity(),
        ),
    };
    let mut pipeline = Pipeline::new(det, seg, calib, settings.geometry_settings());
    let report = pipeline.set_prompts(&prompts).map_err(bad_input)?;
    for p in &report.unmatched {
        tracing::warn!(prompt = %p, "the detector has no class for this prompt");
    }
    let view = pipeline
        .process(&color, rgbd.as_ref().map(|(_, d)| d))
        .map_err(|e| match e {
            opennav::perception::pipeline::PipelineError::Input(_) => bad_input(e),
            other => failed(other),
        })?;
    if let Some(dir) = out {
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("--out {}", dir.display()))
            .map_err(bad_input)?;
        let img = overlay(&color, &view.detections, &view.masks);
        img.save_png(&dir.join("overlay.png")).map_err(failed)?;
        for (i, o) in view.objects.iter().enumerate() {
            let p = dir.join(format!("object_{i:02}_{}.ply", slug(&o.label)));
            write_ply(&p, o)
                .with_context(|| p.display().to_string())
                .map_err(failed)?;
        }
    }
    let report = DetectReport::from(&view);
    match format {
        Format::Json => {
            let s = serde_json::to_string_pretty(&report).map_err(failed)?;
            println!("{s}");
        }
        Format::Text => {
            for p in &report.prompts.unmatched {
                println!("prompt \"{p}\": the detector has no class for it");
            }
            for d in &report.detections {
                println!(
                    "2D {:<12} {:.2}  [{:.0}, {:.0}, {:.0}, {:.0}]",
                    d.label, d.score, d.box_xyxy[0], d.box_xyxy[1], d.box_xyxy[2], d.box_xyxy[3]
                );
            }
            for o in &report.objects {
                println!(
                    "3D {:<12} {:.2}  centre ({:.2}, {:.2}, {:.2}) m  size ({:.2}, {:.2}, {:.2}) m  {} points  [{}]",
                    o.label,
                    o.score,
                    o.center_m[0],
                    o.center_m[1],
                    o.center_m[2],
                    o.size_m[0],
                    o.size_m[1],
                    o.size_m[2],
                    o.points,
                    o.frame
                );
            }
            for d in &report.dropped {
                println!("dropped {} {:.2}: {}", d.label, d.score, d.reason);
            }
            let t = report.timing_ms;
            println!(
                "timing: registration {:.1} ms, detector {:.1} ms, segmenter {:.1} ms, geometry {:.1} ms, total {:.1} ms",
                t.registration, t.detector, t.segmenter, t.geometry, t.total
            );
        }
    }
    Ok(())
}
