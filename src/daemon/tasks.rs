//! The daemon's tasks, watched ([`Tasks`]: any that ends before shutdown
//! is a fault, named with why), the text of a panic, and the fault
//! injection the health tests use.

use std::collections::HashMap;
use std::time::Duration;

use tokio::task::JoinSet;

use super::TaskResult;

/// The daemon's tasks, watched: any that ends before shutdown is a fault.
pub(super) struct Tasks {
    set: JoinSet<TaskResult>,
    names: HashMap<tokio::task::Id, String>,
    inject_panic: Option<(String, Duration)>,
}

impl Tasks {
    pub(super) fn new(inject_panic: Option<(String, Duration)>) -> Tasks {
        Tasks {
            set: JoinSet::new(),
            names: HashMap::new(),
            inject_panic,
        }
    }

    pub(super) fn spawn(
        &mut self,
        name: &str,
        fut: impl std::future::Future<Output = TaskResult> + Send + 'static,
    ) {
        let after = injected_panic_after(&self.inject_panic, name);
        let h = self.set.spawn(panic_after(after, fut));
        self.names.insert(h.id(), name.to_string());
    }

    /// The next task to end: its name and why.
    pub(super) async fn next_end(&mut self) -> Option<(String, TaskResult)> {
        let r = self.set.join_next_with_id().await?;
        Some(match r {
            Ok((id, r)) => (self.name(id), r),
            Err(e) => {
                let id = e.id();
                let why = if e.is_panic() {
                    format!("panicked: {}", panic_message(e.into_panic()))
                } else {
                    "cancelled".to_string()
                };
                (self.name(id), Err(why))
            }
        })
    }

    fn name(&self, id: tokio::task::Id) -> String {
        self.names
            .get(&id)
            .cloned()
            .unwrap_or_else(|| format!("task {id}"))
    }
}

/// When `name` is the task a fault-injection test names, its delay.
pub(super) fn injected_panic_after(
    inject: &Option<(String, Duration)>,
    name: &str,
) -> Option<Duration> {
    inject.as_ref().filter(|(t, _)| t == name).map(|(_, d)| *d)
}

/// Runs `fut`; with `after`, panics then unless it has ended (fault
/// injection).
pub(super) async fn panic_after<F: std::future::Future>(
    after: Option<Duration>,
    fut: F,
) -> F::Output {
    match after {
        Some(after) => tokio::select! {
            r = fut => r,
            _ = tokio::time::sleep(after) => panic!("injected panic (fault-injection test)"),
        },
        None => fut.await,
    }
}

/// The text of a panic's payload.
pub fn panic_message(payload: Box<dyn std::any::Any + Send>) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "(no message)".to_string()
    }
}
