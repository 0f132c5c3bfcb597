//! The simulated living-room trips on the virtual clock: wall time against
//! the simulated time (the speed-up over real time). One current-thread
//! runtime: everything, perception included, runs on one core.
//!
//!   cargo bench --bench sim_trip [-- RUNS]

use std::sync::Arc;
use std::time::{Duration, Instant};

use opennav::config::Settings;
use opennav::daemon::{Outcome, RunOptions, RunReport};
use opennav::msg::{Clock, TokioClock, UserInput};
use opennav::sim::world::SimWorld;
use tokio_util::sync::CancellationToken;

fn trip(settings: &Settings, word: &str) -> (RunReport, Duration) {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("runtime");
    let t0 = Instant::now();
    let r = rt.block_on(async {
        let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
        let world = SimWorld::living_room(settings.drive_params());
        let (devices, _sim) =
            opennav::sim::devices::devices(settings, world, clock.clone()).expect("devices");
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        tx.send(UserInput::Goto(word.into())).await.expect("word");
        // "yes" when the chair asks whether it is clear behind (its rear
        // is unseen at start-up: a search turn needs it)
        let yes = tx.clone();
        tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(2500)).await;
            yes.send(UserInput::Yes).await.ok();
        });
        let opts = RunOptions {
            exit_on_arrival: true,
            max_duration: Some(Duration::from_secs(120)),
            ..Default::default()
        };
        let r = opennav::daemon::run(devices, settings, opts, rx, clock, CancellationToken::new())
            .await
            .expect("runs");
        drop(tx);
        r
    });
    (r, t0.elapsed())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let runs: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(7);
    let settings = Settings::load(None).expect("defaults");
    println!("simulated trip on the virtual clock, {runs} runs each (median)");
    println!(
        "{:<10} {:>9} {:>12} {:>10} {:>10}",
        "word", "outcome", "simulated s", "wall s", "speed-up"
    );
    for word in ["chair", "cabinet", "piano"] {
        let mut wall = Vec::new();
        let mut sim = Vec::new();
        let mut outcome = Outcome::Timeout;
        for _ in 0..runs {
            let (r, w) = trip(&settings, word);
            wall.push(w.as_secs_f64());
            sim.push(r.duration_s);
            outcome = r.outcome;
        }
        let (w, s) = (median(&mut wall), median(&mut sim));
        println!(
            "{word:<10} {:>9} {s:>12.2} {w:>10.3} {:>9.1}x",
            format!("{outcome:?}"),
            s / w
        );
    }
}
