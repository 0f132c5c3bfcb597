//! The Replica protocol end to end on a synthetic scene in Replica's layout:
//! rendered RGB-D views, the simulator's ground-truth detector, the depth
//! segmenter, the cross-view merge, point masks and the Open3DIS metric.

mod common;

use opennav::eval::instances::ScoreMode;
use opennav::eval::replica::{list_scenes, run, ReplicaScene, RunSettings};
use opennav::perception::boxes::MergeRule;
use opennav::perception::segmenter::DepthBoxSegmenter;
use opennav::sim::replica::{camera, write_scene, Degrade, SimGtDetector};
use opennav::sim::room::Room;

fn score(
    dir: &std::path::Path,
    degrade: Option<Degrade>,
    merge: MergeRule,
) -> opennav::eval::replica::ReplicaReport {
    let cam = camera(2);
    let mut det = SimGtDetector::new(Room::living_room(), cam);
    det.degrade = degrade;
    let mut seg = DepthBoxSegmenter::default();
    let settings = RunSettings {
        score_mode: ScoreMode::Detector,
        merge,
        ..Default::default()
    };
    let scenes = list_scenes(dir).expect("scenes");
    run(
        dir,
        &scenes,
        &mut det,
        &mut seg,
        &settings,
        &mut |_, _, _| {},
    )
    .expect("run")
}

#[test]
fn synthetic_replica_scene_scores_end_to_end() {
    let dir = tempfile::tempdir().expect("tmp");
    let room = Room::living_room();
    let poses = write_scene(dir.path(), "office0", &room, &camera(2), 50).expect("written");
    assert_eq!(poses.len(), 50);
    // the layout is what the reader expects
    let scene = ReplicaScene::open(dir.path(), "office0").expect("opens");
    assert_eq!(scene.poses.len(), 50);
    let v = scene.load_view(7).expect("view");
    assert_eq!((v.color.width(), v.color.height()), (320, 180));
    assert!(v.depth.data().iter().filter(|&&z| z > 0.0).count() > 320 * 170);

    let degraded = Some(Degrade {
        miss_every_other: true,
        box_fraction: 1.0,
    });
    let paper = MergeRule::paper(0.8);
    let fused = MergeRule {
        iou: 0.8,
        containment: Some(0.8),
    };
    let good_paper = score(dir.path(), None, paper);
    eprintln!(
        "ground truth detector, paper merge:\n{}{:?}",
        good_paper.table(),
        good_paper.scenes
    );
    let good = score(dir.path(), None, fused);
    eprintln!(
        "ground truth detector, containment merge:\n{}{:?}",
        good.table(),
        good.scenes
    );
    let bad = score(dir.path(), degraded, fused);
    eprintln!("degraded detector:\n{}", bad.table());
    let bad_paper = score(dir.path(), degraded, paper);
    eprintln!("degraded detector, paper merge:\n{}", bad_paper.table());
    // the paper's merge leaves fragments of objects seen from truncated
    // views apart (duplicates are false positives); containment fuses them
    assert!(
        good_paper.result.map25 > 0.35,
        "paper merge mAP25 {}",
        good_paper.result.map25
    );
    assert!(good.result.map25 > 0.8, "mAP25 {}", good.result.map25);
    assert!(good.result.map50 > 0.6, "mAP50 {}", good.result.map50);
    assert!(good.result.map25 > good_paper.result.map25);
    assert!(good.scenes[0].fused_objects < good_paper.scenes[0].fused_objects);
    // a detector that misses half the objects scores clearly lower
    assert!(
        bad.result.map25 < good.result.map25 - 0.2,
        "{} vs {}",
        bad.result.map25,
        good.result.map25
    );
    assert!(bad.result.map < good.result.map);
    assert!(bad_paper.result.map < good_paper.result.map);
    // timing is reported per view and per scene
    let r = &good.scenes[0];
    assert_eq!(r.views, 50);
    assert!(r.secs_per_view_mean > 0.0 && r.secs_per_scene >= r.secs_per_view_mean * 50.0 * 0.99);
}

/// `opennav eval replica` runs any detector/segmenter pair: here the
/// paper's second stack on the stand-ins (Grounding DINO; EfficientSAM for
/// the masks), on a small synthetic scene; the report names the backend.
#[test]
fn eval_replica_runs_grounding_dino_with_a_sam_family_segmenter() {
    common::init_ort();
    let dir = tempfile::tempdir().expect("tmp");
    write_scene(dir.path(), "office0", &Room::living_room(), &camera(2), 3).expect("written");
    let out_dir = tempfile::tempdir().expect("tmp");
    let (model, segmenter) = (
        common::generated("grounding_dino.onnx"),
        common::generated("efficient_sam"),
    );
    let args: [&std::ffi::OsStr; 8] = [
        "eval".as_ref(),
        "replica".as_ref(),
        "--root".as_ref(),
        dir.path().as_ref(),
        "--detector".as_ref(),
        model.as_ref(),
        "--segmenter".as_ref(),
        segmenter.as_ref(),
    ];
    let out = common::opennav_in(out_dir.path(), &args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report = common::read_json(&out_dir.path().join("eval_replica.json"));
    assert_eq!(report["detector"], "grounding-dino", "{report}");
    assert!(report["mAP25"].is_number(), "{report}");
}
