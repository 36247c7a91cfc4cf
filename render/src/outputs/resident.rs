//! The process's resident set over the measured frames, sampled on a thread of its own every
//! second (and once at each end), for render.json's `host_memory`: whether a long run's host
//! memory stays flat is read off a real run, where the driver's and the allocator's memory
//! count too, not off a test on a software driver.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Time between two samples.
const INTERVAL: Duration = Duration::from_secs(1);

/// What the samples say, in bytes; every figure is `None` where the resident set cannot be
/// read (no /proc).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct ResidentSummary {
    pub interval_s: f64,
    pub samples: usize,
    pub first_bytes: Option<u64>,
    pub last_bytes: Option<u64>,
    pub min_bytes: Option<u64>,
    pub max_bytes: Option<u64>,
}

/// Running figures, updated by the sampling thread.
#[derive(Default)]
struct Samples {
    count: usize,
    first: Option<u64>,
    last: Option<u64>,
    min: Option<u64>,
    max: Option<u64>,
}

impl Samples {
    fn add(&mut self, bytes: u64) {
        self.count += 1;
        self.first.get_or_insert(bytes);
        self.last = Some(bytes);
        self.min = Some(self.min.map_or(bytes, |m| m.min(bytes)));
        self.max = Some(self.max.map_or(bytes, |m| m.max(bytes)));
    }
}

/// Samples the resident set until [`ResidentSampler::stop`].
pub struct ResidentSampler {
    samples: Arc<Mutex<Samples>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl ResidentSampler {
    /// Takes the first sample now and the next ones every [`INTERVAL`].
    pub fn start() -> Self {
        let samples = Arc::new(Mutex::new(Samples::default()));
        let stop = Arc::new(AtomicBool::new(false));
        sample_into(&samples);
        let (thread_samples, thread_stop) = (samples.clone(), stop.clone());
        // A sampler that cannot start leaves the two end samples: the run goes on.
        let thread = std::thread::Builder::new()
            .name("resident-set".into())
            .spawn(move || {
                let mut next = Instant::now() + INTERVAL;
                while !thread_stop.load(Ordering::Relaxed) {
                    // Short sleeps, so that stop() returns at once instead of after a second.
                    std::thread::sleep(Duration::from_millis(20));
                    if Instant::now() >= next {
                        sample_into(&thread_samples);
                        next += INTERVAL;
                    }
                }
            })
            .ok();
        Self { samples, stop, thread }
    }

    /// Takes the last sample and says what all of them were.
    pub fn stop(mut self) -> ResidentSummary {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
        sample_into(&self.samples);
        let s = self.samples.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        ResidentSummary {
            interval_s: INTERVAL.as_secs_f64(),
            samples: s.count,
            first_bytes: s.first,
            last_bytes: s.last,
            min_bytes: s.min,
            max_bytes: s.max,
        }
    }
}

impl Drop for ResidentSampler {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

fn sample_into(samples: &Mutex<Samples>) {
    if let Some(bytes) = resident_bytes() {
        samples.lock().unwrap_or_else(|poisoned| poisoned.into_inner()).add(bytes);
    }
}

/// This process's resident set: /proc/self/statm's second field, in pages.
fn resident_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions; a negative answer (no page size) gives None.
    let page = u64::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).ok()?;
    Some(pages * page)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_samples_keep_first_last_min_and_max() {
        let mut s = Samples::default();
        for bytes in [5, 3, 9, 4] {
            s.add(bytes);
        }
        assert_eq!((s.count, s.first, s.last, s.min, s.max), (4, Some(5), Some(4), Some(3), Some(9)));
    }

    #[test]
    fn a_sampler_stopped_at_once_has_its_two_end_samples() {
        let summary = ResidentSampler::start().stop();
        assert_eq!(summary.samples, 2);
        assert!(summary.min_bytes.is_some_and(|b| b > 0), "{summary:?}");
        assert!(summary.min_bytes <= summary.max_bytes);
    }
}
