//! Mapping a device's wrapping counter clock to the host's monotonic clock
//! (pure): unwrap the counter, estimate drift over a window, and take the
//! offset from the least-delayed sample.

use std::collections::VecDeque;

use crate::msg::Stamp;

#[derive(Debug, Clone)]
pub struct DeviceClock {
    /// Counter modulus (2^bits).
    modulus: u64,
    /// Seconds per count.
    tick_s: f64,
    last_raw: Option<u64>,
    wraps: u64,
    /// (unwrapped device seconds, host seconds)
    samples: VecDeque<(f64, f64)>,
    window: usize,
}

impl DeviceClock {
    /// A `bits`-bit counter ticking every `tick_s` seconds; drift is fitted
    /// over the last `window` samples.
    pub fn new(bits: u32, tick_s: f64, window: usize) -> Self {
        DeviceClock {
            modulus: 1u64 << bits.min(63),
            tick_s,
            last_raw: None,
            wraps: 0,
            samples: VecDeque::new(),
            window: window.max(2),
        }
    }

    /// Unwraps a raw counter value (a backwards step of more than half the
    /// range is a wrap); returns counts since the first sample's epoch.
    pub fn unwrap(&mut self, raw: u64) -> u64 {
        let raw = raw % self.modulus;
        if let Some(last) = self.last_raw {
            if raw < last && last - raw > self.modulus / 2 {
                self.wraps += 1;
            }
        }
        self.last_raw = Some(raw);
        self.wraps * self.modulus + raw
    }

    /// Host stamp of a reading with device time `raw`, received at `host`.
    pub fn map(&mut self, raw: u64, host: Stamp) -> Stamp {
        let dev_s = self.unwrap(raw) as f64 * self.tick_s;
        let host_s = host.as_secs_f64();
        self.samples.push_back((dev_s, host_s));
        while self.samples.len() > self.window {
            self.samples.pop_front();
        }
        let n = self.samples.len() as f64;
        let (mx, my) = self
            .samples
            .iter()
            .fold((0.0, 0.0), |a, s| (a.0 + s.0 / n, a.1 + s.1 / n));
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (x, y) in &self.samples {
            sxy += (x - mx) * (y - my);
            sxx += (x - mx) * (x - mx);
        }
        let rate = if sxx > 1e-6 && self.samples.len() >= 10 {
            (sxy / sxx).clamp(0.99, 1.01)
        } else {
            1.0
        };
        let offset = self
            .samples
            .iter()
            .map(|(x, y)| y - rate * x)
            .fold(f64::INFINITY, f64::min);
        Stamp::from_secs_f64((offset + rate * dev_s).min(host_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwraps_any_width() {
        let mut c = DeviceClock::new(24, 1e-3, 10);
        assert_eq!(c.unwrap(0xFF_FFF0), 0xFF_FFF0);
        assert_eq!(c.unwrap(0x10), (1 << 24) + 0x10);
        let mut c = DeviceClock::new(32, 1e-6, 10);
        assert_eq!(c.unwrap(u32::MAX as u64 - 5), u32::MAX as u64 - 5);
        assert_eq!(c.unwrap(3), (1u64 << 32) + 3);
    }

    #[test]
    fn maps_to_host_time_through_jitter_and_drift() {
        // device clock 0.1 % slow; reception delay 2..7 ms
        let mut c = DeviceClock::new(24, 1e-3, 100);
        let mut worst: f64 = 0.0;
        for k in 0..300u32 {
            let true_host = 100.0 + k as f64 * 0.1;
            let raw = ((k as f64 * 100.0 * 0.999) as u64 + 0xFF_F000) & 0xFF_FFFF;
            let delay = 0.002 + 0.005 * ((k * 7919 % 13) as f64 / 13.0);
            let s = c.map(raw, Stamp::from_secs_f64(true_host + delay));
            if k > 50 {
                worst = worst.max((s.as_secs_f64() - true_host).abs());
            }
        }
        assert!(worst < 0.003, "worst error {worst} s");
    }
}
