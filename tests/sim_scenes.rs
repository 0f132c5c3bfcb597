//! The closed loop over generated apartments: a small fixed set of
//! scenes (`sim::scene`, seed 1) through the whole daemon
//! (`sim::trial::run`), each on its own paused runtime.

use opennav::config::Settings;
use opennav::sim::scene::{generate, scene_seed};
use opennav::sim::trial::{self, TrialResult};

fn trial(settings: &Settings, k: u64) -> TrialResult {
    let scene = generate(scene_seed(1, k));
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("runtime")
        .block_on(trial::run(settings, k, &scene))
        .expect("the trip runs")
}

#[test]
fn twelve_generated_scenes_are_driven_without_touching_anything() {
    let settings = Settings::load(None).expect("defaults");
    let results: Vec<TrialResult> = (0..12).map(|k| trial(&settings, k)).collect();
    for r in &results {
        eprintln!("{}", serde_json::to_string(r).expect("json"));
    }
    for r in &results {
        assert!(!r.collision, "{r:?}");
        assert!(!r.fell, "{r:?}");
    }
    // a trip that ends anywhere but at the object says why
    for r in results.iter().filter(|r| !r.reached) {
        assert!(r.last_said.is_some(), "{r:?}");
    }
}
