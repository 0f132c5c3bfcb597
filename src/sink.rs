//! A handle that hands items to a worker thread and never waits: what the
//! bounded queue cannot take is dropped, counted and logged (the live view
//! and the recorder are fed this way from the control path).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// The tasks' handle (cheap to clone).
pub struct DropSink<T> {
    tx: std::sync::mpsc::SyncSender<T>,
    dropped: Arc<AtomicU64>,
    /// Who falls behind, for the log.
    what: &'static str,
}

impl<T> Clone for DropSink<T> {
    fn clone(&self) -> Self {
        DropSink {
            tx: self.tx.clone(),
            dropped: self.dropped.clone(),
            what: self.what,
        }
    }
}

impl<T> DropSink<T> {
    /// A sink holding at most `capacity` items for the worker's receiver;
    /// the counter of dropped items is shared with the caller.
    pub fn channel(
        capacity: usize,
        what: &'static str,
    ) -> (DropSink<T>, std::sync::mpsc::Receiver<T>, Arc<AtomicU64>) {
        let (tx, rx) = std::sync::mpsc::sync_channel(capacity);
        let dropped = Arc::new(AtomicU64::new(0));
        (
            DropSink {
                tx,
                dropped: dropped.clone(),
                what,
            },
            rx,
            dropped,
        )
    }

    /// Hands an item over; never waits.
    pub fn put(&self, item: T) {
        if self.tx.try_send(item).is_err() {
            let n = self.dropped.fetch_add(1, Ordering::SeqCst) + 1;
            if n.is_power_of_two() {
                tracing::warn!(dropped = n, "{}: falls behind; items dropped", self.what);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_queue_drops_and_counts_without_waiting() {
        let (sink, rx, dropped) = DropSink::<u32>::channel(2, "test");
        for i in 0..5 {
            sink.put(i);
        }
        assert_eq!(dropped.load(Ordering::SeqCst), 3);
        assert_eq!(rx.try_iter().collect::<Vec<_>>(), vec![0, 1]);
    }
}
