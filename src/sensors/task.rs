//! Runs a blocking device reader on its own OS thread and publishes its
//! latest value on a `tokio::sync::watch` channel (latest value wins:
//! nothing queues). The thread stops when the token is cancelled or the
//! reader ends; errors go to the log and to the error counter, and the
//! reader decides whether to go on.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use tokio::sync::watch;
use tokio_util::sync::CancellationToken;

/// What a reader returns each call.
pub enum Step<T> {
    /// A new value to publish.
    Value(T),
    /// Nothing this time (a recoverable error, already logged).
    Retry,
    /// The source has ended (end of a recording).
    End,
}

/// A running reader thread.
pub struct SourceTask<T> {
    pub latest: watch::Receiver<Option<T>>,
    pub errors: Arc<AtomicU64>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl<T> SourceTask<T> {
    /// Waits for the thread to finish (after cancellation or the end).
    pub fn join(mut self) {
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }

    pub fn error_count(&self) -> u64 {
        self.errors.load(Ordering::SeqCst)
    }
}

/// Starts `read` on a thread named `name`, publishing into a watch channel.
pub fn spawn_source<T, F>(
    name: &str,
    cancel: CancellationToken,
    mut read: F,
) -> std::io::Result<SourceTask<T>>
where
    T: Send + Sync + 'static,
    F: FnMut() -> Step<T> + Send + 'static,
{
    let (tx, rx) = watch::channel(None);
    let errors = Arc::new(AtomicU64::new(0));
    let errs = errors.clone();
    let handle = std::thread::Builder::new()
        .name(name.to_string())
        .spawn(move || {
            while !cancel.is_cancelled() {
                match read() {
                    Step::Value(v) => {
                        // no receiver left: nobody listens any more
                        if tx.send(Some(v)).is_err() {
                            return;
                        }
                    }
                    Step::Retry => {
                        errs.fetch_add(1, Ordering::SeqCst);
                    }
                    Step::End => return,
                }
            }
        })?;
    Ok(SourceTask {
        latest: rx,
        errors,
        handle: Some(handle),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn publishes_the_latest_and_stops_on_cancel() {
        let cancel = CancellationToken::new();
        let mut n = 0u32;
        let task = spawn_source("fake", cancel.clone(), move || {
            n += 1;
            match n {
                3 => Step::Retry,
                1..=5 => Step::Value(n),
                _ => Step::End,
            }
        })
        .unwrap();
        let mut rx = task.latest.clone();
        // the reader ends after 5: the channel closes and holds the last value
        while rx.changed().await.is_ok() {}
        assert_eq!(*rx.borrow(), Some(5));
        assert_eq!(task.error_count(), 1);
        task.join();

        let cancel = CancellationToken::new();
        let task = spawn_source("endless", cancel.clone(), || {
            std::thread::sleep(std::time::Duration::from_millis(1));
            Step::Value(1u8)
        })
        .unwrap();
        cancel.cancel();
        task.join();
    }
}
