//! Helpers shared by the integration tests: where the fixtures are, and
//! loud failures when an asset that CI provides is absent.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The shared assets folder (`../shared` beside the checkout, or
/// `OPENNAV_SHARED`).
pub fn shared() -> PathBuf {
    std::env::var_os("OPENNAV_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("..").join("shared"))
}

/// A required asset: fails the test, loudly, naming how to get it.
pub fn asset(path: PathBuf) -> PathBuf {
    if !path.exists() {
        panic!(
            "\n\n*** MISSING TEST ASSET: {} ***\n\
             Generated fixtures come from tests/run.sh (tests/fixtures/generate.py);\n\
             models and data come from the shared folder (../shared or OPENNAV_SHARED).\n\n",
            path.display()
        );
    }
    path
}

pub fn generated(name: &str) -> PathBuf {
    asset(repo().join("tests/fixtures/generated").join(name))
}

pub fn yolo11n() -> PathBuf {
    asset(shared().join("models/yolo11n_coco.onnx"))
}

pub fn mrpt(name: &str) -> PathBuf {
    asset(repo().join("tests/fixtures/mrpt_openni2").join(name))
}

/// Initialises ONNX Runtime from ORT_DYLIB_PATH (set by .cargo/config.toml
/// to the library scripts/fetch-onnxruntime.sh fetched).
pub fn init_ort() {
    let lib = opennav::perception::runtime::resolve_library_path(None);
    let lib = if lib.is_relative() {
        repo().join(lib)
    } else {
        lib
    };
    asset(lib.clone());
    opennav::perception::runtime::init_runtime(&lib).expect("ONNX Runtime loads");
}

pub fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).expect("readable")).expect("json")
}

/// The daemon on the simulator through `daemon::run` on the caller's
/// (paused) runtime: `world` with `settings`; `words` said in order, each
/// after its delay from the one before (the channel then stays open, as a
/// user may still speak); `adapt` may change the devices first. The run's
/// report and the simulator's measurements for the goal's word.
pub async fn sim_run(
    settings: &opennav::config::Settings,
    world: opennav::sim::world::SimWorld,
    words: Vec<(std::time::Duration, opennav::msg::UserInput)>,
    opts: opennav::daemon::RunOptions,
    adapt: impl FnOnce(&mut opennav::daemon::Devices, &opennav::sim::devices::SimHandle),
) -> (
    opennav::daemon::RunReport,
    opennav::sim::devices::SimSummary,
) {
    use std::sync::Arc;
    let clock: Arc<dyn opennav::msg::Clock> = Arc::new(opennav::msg::TokioClock::new());
    let (mut devices, sim) =
        opennav::sim::devices::devices(settings, world, clock.clone()).expect("devices");
    adapt(&mut devices, &sim);
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    tokio::spawn(async move {
        for (at, w) in words {
            tokio::time::sleep(at).await;
            if tx.send(w).await.is_err() {
                return;
            }
        }
        std::future::pending::<()>().await;
    });
    let r = opennav::daemon::run(
        devices,
        settings,
        opts,
        rx,
        clock,
        tokio_util::sync::CancellationToken::new(),
    )
    .await
    .expect("runs");
    let label = r.goal.label().map(str::to_string);
    let s = sim.summary(label.as_deref()).expect("summary");
    (r, s)
}

/// `opennav ARGS…`, which must succeed: its stdout's JSON lines.
pub fn opennav_json_lines(args: &[&std::ffi::OsStr]) -> Vec<serde_json::Value> {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(args)
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect()
}

/// The JSON report `opennav run` prints last on stdout.
pub fn report(stdout: &[u8]) -> serde_json::Value {
    let text = String::from_utf8_lossy(stdout);
    let line = text
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or_else(|| panic!("no report in {text}"));
    serde_json::from_str(line).expect("report JSON")
}

/// `opennav ARGS…` run in `dir`, without the caller's RUST_LOG: its output.
pub fn opennav_in(dir: &Path, args: &[&std::ffi::OsStr]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(args)
        .current_dir(dir)
        .env_remove("RUST_LOG")
        .output()
        .expect("runs")
}

/// The stdout of a run that must have succeeded, as one JSON document.
pub fn success_json(out: &std::process::Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON document on stdout")
}
