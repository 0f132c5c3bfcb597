//! Time: monotonic stamps, stamped values and the clock handle every task reads.

use std::time::Duration;

/// A monotonic time stamp: time since an arbitrary epoch of the host's
/// monotonic clock (or of a recording). Stamps mark *acquisition*, not
/// processing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Stamp(pub Duration);

impl serde::Serialize for Stamp {
    /// Seconds, as a float.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(self.as_secs_f64())
    }
}

impl Stamp {
    pub const ZERO: Stamp = Stamp(Duration::ZERO);

    /// Saturating: negative and NaN give zero, beyond `Duration`'s range
    /// its maximum (outside data is checked for range before it gets here).
    pub fn from_secs_f64(secs: f64) -> Stamp {
        Stamp(Duration::try_from_secs_f64(secs.max(0.0)).unwrap_or(Duration::MAX))
    }

    pub fn as_secs_f64(self) -> f64 {
        self.0.as_secs_f64()
    }

    /// Age of this stamp at `now` (zero when `now` is earlier).
    pub fn age_at(self, now: Stamp) -> Duration {
        now.0.saturating_sub(self.0)
    }
}

/// Where drivers read the time: the host's monotonic clock in production,
/// a controlled one in tests.
pub trait Clock: Send + Sync {
    fn now(&self) -> Stamp;
}

/// The host's monotonic clock, counted from when this value was made.
#[derive(Debug, Clone, Copy)]
pub struct MonotonicClock {
    origin: std::time::Instant,
}

impl MonotonicClock {
    pub fn new() -> Self {
        MonotonicClock {
            origin: std::time::Instant::now(),
        }
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for MonotonicClock {
    fn now(&self) -> Stamp {
        Stamp(self.origin.elapsed())
    }
}

/// A value with the monotonic stamp of its acquisition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stamped<T> {
    pub stamp: Stamp,
    pub value: T,
}

impl<T> Stamped<T> {
    pub fn new(stamp: Stamp, value: T) -> Self {
        Stamped { stamp, value }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_out_of_range_saturate_instead_of_panicking() {
        assert_eq!(Stamp::from_secs_f64(1e300).0, Duration::MAX);
        assert_eq!(Stamp::from_secs_f64(f64::NAN), Stamp::ZERO);
        assert_eq!(Stamp::from_secs_f64(-1.0), Stamp::ZERO);
    }

    #[test]
    fn age_saturates_at_zero() {
        let a = Stamp::from_secs_f64(2.0);
        let b = Stamp::from_secs_f64(2.5);
        assert_eq!(a.age_at(b), Duration::from_millis(500));
        assert_eq!(b.age_at(a), Duration::ZERO);
    }
}

/// tokio's clock, counted from when this value was made: the real monotonic
/// clock normally, and the test's controlled clock under
/// `tokio::time::pause()`. Drivers that time with tokio timers read this so
/// that stamps and timers agree.
#[derive(Debug, Clone, Copy)]
pub struct TokioClock {
    origin: tokio::time::Instant,
}

impl TokioClock {
    pub fn new() -> Self {
        TokioClock {
            origin: tokio::time::Instant::now(),
        }
    }
}

impl Default for TokioClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for TokioClock {
    fn now(&self) -> Stamp {
        Stamp(self.origin.elapsed())
    }
}
