//! The simulator's sensors, which take about a quarter of a benchmark
//! trip's time (`perf record` on `opennav sim --scenes 24 --seed 1`):
//! - `render_scene_k`: one RGB-D frame (320×180, the simulated camera's
//!   size) of generated scene k (`opennav sim --seed 1`), from the chair's
//!   start pose;
//! - `laser_scan_scene_k`: one URG-04LX scan (682 rays) there, the left
//!   laser.
//!
//! Run: `cargo bench --bench sim_sensors`

use criterion::{criterion_group, criterion_main, Criterion};
use opennav::config::Settings;
use opennav::sim::scene::{generate, scene_seed};
use opennav::sim::world::SimWorld;

fn bench_sensors(c: &mut Criterion) {
    let settings = Settings::load(None).expect("the default settings");
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .expect("the default camera pose");
    let base_from_laser = settings.lasers.left.base_from_laser();
    let k = opennav::sim::replica::camera(2).intrinsics();
    for scene_k in [0u64, 3] {
        let scene = generate(scene_seed(1, scene_k));
        let world = SimWorld::in_room(scene.room.clone(), scene.start, settings.drive_params());
        c.bench_function(&format!("render_scene_{scene_k}"), |b| {
            b.iter(|| world.render(&k, &base_from_camera).expect("render"))
        });
        c.bench_function(&format!("laser_scan_scene_{scene_k}"), |b| {
            b.iter(|| world.laser_scan(&base_from_laser, 0))
        });
    }
}

criterion_group!(benches, bench_sensors);
criterion_main!(benches);
