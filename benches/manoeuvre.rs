//! One manoeuvre search on the chair's map (`navigation::manoeuvre::plan`),
//! as the control step makes it when the way stays held: through a 0.85 m
//! doorway to a goal past it (found), and past a 0.72 m gap the guide's
//! disc passes and the chair's footprint does not, to a goal 2.2 m and 4 m
//! off (the whole window searched, or the search's bound on poses
//! reached; none found: the longest a search takes).
//! Run: `cargo bench --bench manoeuvre`.

use criterion::{criterion_group, criterion_main, Criterion};
use opennav::config::Settings;
use opennav::msg::Pose2;
use opennav::navigation::manoeuvre::{plan, ManoeuvreShape};
use opennav::navigation::map::{GridMap, MapSettings};
use opennav::safety::Supervisor;

/// The map of a wall at x = 1 m with a gap of `gap_m` about y = 0.
fn wall_with_gap(gap_m: f64) -> GridMap {
    let points: Vec<[f64; 2]> = (0..=400)
        .map(|k| -4.0 + k as f64 * 0.02)
        .filter(|y| y.abs() >= gap_m / 2.0)
        .map(|y| [1.0, y])
        .collect();
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    map.set_camera(&points, &[]);
    map.update_distances();
    map
}

fn bench(c: &mut Criterion) {
    let start = Pose2::default();
    // the chair's footprint as the supervisor keeps it at a crawl
    let supervisor = Supervisor::new(Settings::defaults().safety_limits());
    let shape = ManoeuvreShape::at_a_crawl(&supervisor);
    let cases = [
        ("manoeuvre_through_a_0_85_m_doorway", 0.85, [2.2, 0.0], true),
        ("manoeuvre_none_past_a_0_72_m_gap", 0.72, [2.2, 0.0], false),
        (
            "manoeuvre_none_past_a_0_72_m_gap_4_m_off",
            0.72,
            [3.5, 2.0],
            false,
        ),
    ];
    for (name, gap_m, goal, found) in cases {
        let map = wall_with_gap(gap_m);
        let search = || plan(&map, &[], &[], start, goal, 0.0, 0.25, 0.6, &shape);
        assert_eq!(search().is_some(), found, "{name}");
        c.bench_function(name, |b| b.iter(search));
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
