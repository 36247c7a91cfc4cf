//! Running statistics of frame reports: what a frame loop keeps instead of every frame's
//! [`FrameReport`], so that its memory stays flat however many frames run.
//!
//! * Per timed event label (pass or copy name, kind, device): count, total time and bytes. The
//!   labels are the plan's, so their number does not grow with the frames.
//! * Per device: the sum of busy fractions.
//! * Per frame scalars (GPU span, host submission and slot-wait times, host interval between
//!   frames, GPU gap between frames) as [`Summary`]s: exact mean, quantiles from a bounded sample.

use std::collections::HashMap;

use crate::timing::{EventKind, FrameReport};

/// Values a [`Summary`] keeps for its quantiles.
pub const SUMMARY_SAMPLE: usize = 4096;

/// Mean and quantiles of a stream of values in bounded memory. The mean, minimum and maximum
/// are exact. The first [`SUMMARY_SAMPLE`] values are kept in order, so up to that many the
/// quantiles are exact too; after that the sample is a uniform random sample of all values
/// (reservoir sampling, Vitter's algorithm R, with a fixed seed so that a run repeats), whose
/// p95 is within about ±0.7 percentile points of the true one (2σ of a binomial over 4096).
/// A sorted sample would give exact quantiles of every value, but it is what grew with the
/// frames; a streaming estimator (P²) would be smaller but is not exact for short runs, which
/// are what the benchmarks are.
#[derive(Clone, Debug)]
pub struct Summary {
    count: u64,
    sum: f64,
    min: f64,
    max: f64,
    sample: Vec<f64>,
    rng: u64,
}

impl Default for Summary {
    fn default() -> Self {
        Self {
            count: 0,
            sum: 0.0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            sample: Vec::new(),
            rng: 0x9E37_79B9_7F4A_7C15,
        }
    }
}

impl Summary {
    pub fn add(&mut self, value: f64) {
        self.count += 1;
        self.sum += value;
        self.min = self.min.min(value);
        self.max = self.max.max(value);
        if self.sample.len() < SUMMARY_SAMPLE {
            if self.sample.capacity() == 0 {
                self.sample.reserve_exact(SUMMARY_SAMPLE);
            }
            self.sample.push(value);
            return;
        }
        // Value number `count` replaces a kept one with probability SUMMARY_SAMPLE / count.
        let j = self.next_random() % self.count;
        if let Some(kept) = self.sample.get_mut(j as usize) {
            *kept = value;
        }
    }

    /// xorshift64*: plenty for picking reservoir slots.
    fn next_random(&mut self) -> u64 {
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        self.rng.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    pub fn count(&self) -> u64 {
        self.count
    }

    /// 0 without values.
    pub fn mean(&self) -> f64 {
        if self.count == 0 { 0.0 } else { self.sum / self.count as f64 }
    }

    /// 0 without values.
    pub fn min(&self) -> f64 {
        if self.count == 0 { 0.0 } else { self.min }
    }

    /// 0 without values.
    pub fn max(&self) -> f64 {
        if self.count == 0 { 0.0 } else { self.max }
    }

    /// The `q` quantile (0..=1) of the sample, nearest rank (`sorted[round((n - 1) q)]`); 0
    /// without values.
    pub fn quantile(&self, q: f64) -> f64 {
        if self.sample.is_empty() {
            return 0.0;
        }
        let mut sorted = self.sample.clone();
        sorted.sort_by(f64::total_cmp);
        sorted[((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize]
    }

    /// The kept values: every value in order while there are at most [`SUMMARY_SAMPLE`], a
    /// uniform sample of them after that.
    pub fn sample(&self) -> &[f64] {
        &self.sample
    }

    /// Whether [`Self::sample`] holds every value (and the quantiles are exact).
    pub fn is_complete(&self) -> bool {
        self.count as usize == self.sample.len()
    }
}

/// Totals of one timed event label over the folded frames.
#[derive(Clone, Debug, PartialEq)]
pub struct EventTotals {
    pub name: String,
    pub kind: EventKind,
    pub device: usize,
    /// A copy of a finished view to device 0 ([`TimedEvent::gather`]).
    pub gather: bool,
    /// Events (one per frame, or several where a label repeats within a frame).
    pub count: u64,
    pub total_ns: u64,
    /// Copy chunks the events covered ([`TimedEvent::copies`]).
    pub copies: u64,
    pub bytes: u64,
}

/// Running statistics of the frames folded so far ([`Self::fold`]).
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    frames: u64,
    /// By event name: the totals of each (kind, device) with that name.
    events: HashMap<String, Vec<EventTotals>>,
    /// Per device: sum of busy fractions, frames that had the device.
    busy: Vec<(f64, u64)>,
    gpu_span_ms: Summary,
    submit_cpu_ms: Summary,
    slot_wait_ms: Summary,
    interval_ms: Summary,
    gpu_gap_ms: Summary,
    host_late_frames: u64,
    /// The previous frame: its number, submission start and last GPU event end (host ns).
    previous: Option<(u64, u64, u64)>,
}

impl FrameStats {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one retired frame. Frames are folded in the order they retire, which is the order
    /// they were submitted; the between-frame figures ([`Self::interval_ms`],
    /// [`Self::gpu_gap_ms`], [`Self::host_late_frames`]) only pair a frame with the one just
    /// before it.
    pub fn fold(&mut self, report: &FrameReport) {
        self.frames += 1;
        for event in &report.events {
            let totals = match self.events.get_mut(event.name.as_str()) {
                Some(totals) => totals,
                None => self.events.entry(event.name.clone()).or_default(),
            };
            let index = match totals.iter().position(|t| t.kind == event.kind && t.device == event.device) {
                Some(index) => index,
                None => {
                    totals.push(EventTotals {
                        name: event.name.clone(),
                        kind: event.kind,
                        device: event.device,
                        gather: event.gather,
                        count: 0,
                        total_ns: 0,
                        copies: 0,
                        bytes: 0,
                    });
                    totals.len() - 1
                }
            };
            let t = &mut totals[index];
            t.count += 1;
            t.total_ns += event.duration_ns();
            t.copies += u64::from(event.copies);
            t.bytes += event.bytes;
        }
        for d in &report.devices {
            if self.busy.len() <= d.device {
                self.busy.resize(d.device + 1, (0.0, 0));
            }
            self.busy[d.device].0 += d.busy_fraction;
            self.busy[d.device].1 += 1;
        }
        let ms = |ns: u64| ns as f64 / 1e6;
        self.gpu_span_ms.add(ms(report.gpu_span_ns));
        self.submit_cpu_ms.add(ms(report.submit_cpu_ns));
        self.slot_wait_ms.add(ms(report.slot_wait_ns));
        let first_start = report.events.iter().map(|e| e.start_ns).min();
        let last_end = report.events.iter().map(|e| e.end_ns).max();
        if let Some((frame, submit_start, gpu_end)) = self.previous
            && frame + 1 == report.frame
        {
            self.interval_ms.add(ms(report.submit_start_ns.saturating_sub(submit_start)));
            if let Some(first_start) = first_start {
                self.gpu_gap_ms.add(ms(first_start.saturating_sub(gpu_end)));
            }
            if report.submit_start_ns > gpu_end {
                self.host_late_frames += 1;
            }
        }
        self.previous = last_end.map(|end| (report.frame, report.submit_start_ns, end));
    }

    /// Frames folded.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Totals per event label, sorted by device, name and kind.
    pub fn event_totals(&self) -> Vec<&EventTotals> {
        let mut all: Vec<&EventTotals> = self.events.values().flatten().collect();
        all.sort_by(|a, b| (a.device, &a.name, a.kind as u8).cmp(&(b.device, &b.name, b.kind as u8)));
        all
    }

    /// Per device: its busy fraction averaged over the frames it took part in.
    pub fn busy_fraction(&self) -> Vec<f64> {
        self.busy.iter().map(|&(sum, n)| if n == 0 { 0.0 } else { sum / n as f64 }).collect()
    }

    /// GPU span of each frame: first event start to last event end over all devices.
    pub fn gpu_span_ms(&self) -> &Summary {
        &self.gpu_span_ms
    }

    /// Host CPU time of each frame's submission ([`FrameReport::submit_cpu_ns`]).
    pub fn submit_cpu_ms(&self) -> &Summary {
        &self.submit_cpu_ms
    }

    /// Host time each submission waited for its slot ([`FrameReport::slot_wait_ns`]).
    pub fn slot_wait_ms(&self) -> &Summary {
        &self.slot_wait_ms
    }

    /// Host time from one frame's submission to the next one's: the frame period the host
    /// sees.
    pub fn interval_ms(&self) -> &Summary {
        &self.interval_ms
    }

    /// From the last GPU event of a frame to the first of the next: GPU time between frames that
    /// no timestamp covers (idle, or untimed work such as the buffer resets at a frame's start).
    pub fn gpu_gap_ms(&self) -> &Summary {
        &self.gpu_gap_ms
    }

    /// Frames whose submission started after the previous frame's GPU work had ended: the GPU
    /// ran dry waiting for the host.
    pub fn host_late_frames(&self) -> u64 {
        self.host_late_frames
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timing::TimedEvent;

    fn report(frame: u64, submit_start_ns: u64, spans: &[(&str, usize, u64, u64)]) -> FrameReport {
        let events = spans
            .iter()
            .map(|&(name, device, start_ns, end_ns)| TimedEvent {
                name: name.to_string(),
                kind: EventKind::Pass,
                device,
                view: 0,
                index: 0,
                chunk: 0,
                copies: 0,
                bytes: 0,
                gather: false,
                start_ns,
                end_ns,
            })
            .collect();
        FrameReport::new(frame, submit_start_ns, 1_000, 1, 1, 2, events)
    }

    #[test]
    fn up_to_the_sample_size_quantiles_are_exact_and_the_mean_always_is() {
        let mut s = Summary::default();
        for v in [5.0, 1.0, 4.0, 2.0, 3.0] {
            s.add(v);
        }
        assert_eq!((s.mean(), s.min(), s.max()), (3.0, 1.0, 5.0));
        assert_eq!((s.quantile(0.5), s.quantile(0.95), s.quantile(0.0)), (3.0, 5.0, 1.0));
        assert_eq!(s.sample(), [5.0, 1.0, 4.0, 2.0, 3.0]);
        assert!(s.is_complete());
        assert_eq!(Summary::default().quantile(0.5), 0.0);
    }

    #[test]
    fn a_long_stream_keeps_a_bounded_sample_with_close_quantiles() {
        let mut s = Summary::default();
        let n = 200_000u64;
        // Values 0..n in a scrambled order, so the sample must be uniform over time.
        for i in 0..n {
            s.add(((i * 7919) % n) as f64);
        }
        assert_eq!(s.sample().len(), SUMMARY_SAMPLE);
        assert!(!s.is_complete());
        assert_eq!(s.mean(), (n - 1) as f64 / 2.0);
        for q in [0.5, 0.95] {
            let rank = s.quantile(q) / n as f64;
            assert!((rank - q).abs() < 0.025, "q {q}: sample rank {rank}");
        }
    }

    #[test]
    fn events_fold_by_label_and_frames_pair_with_the_one_before() {
        let mut stats = FrameStats::new();
        // Frame 0: GPU 100..300. Frame 1 submitted at 150 (before frame 0 ended), GPU 310..500.
        // Frame 2 submitted at 600, after frame 1 ended: the GPU waited for the host.
        stats.fold(&report(0, 50, &[("a", 0, 100, 200), ("b", 1, 150, 300)]));
        stats.fold(&report(1, 150, &[("a", 0, 310, 400), ("b", 1, 320, 500)]));
        stats.fold(&report(2, 600, &[("a", 0, 700, 800)]));
        assert_eq!(stats.frames(), 3);
        let totals: Vec<(&str, usize, u64, u64)> =
            stats.event_totals().iter().map(|t| (t.name.as_str(), t.device, t.count, t.total_ns)).collect();
        assert_eq!(totals, [("a", 0, 3, 290), ("b", 1, 2, 330)]);
        assert_eq!(stats.gpu_span_ms().sample(), [200e-6, 190e-6, 100e-6]);
        assert_eq!(stats.interval_ms().sample(), [100e-6, 450e-6]);
        assert_eq!(stats.gpu_gap_ms().sample(), [10e-6, 200e-6]);
        assert_eq!(stats.host_late_frames(), 1);
        // Device 1 has no event in frame 2 (busy 0 there).
        let busy = stats.busy_fraction();
        assert!((busy[0] - (100.0 / 200.0 + 90.0 / 190.0 + 1.0) / 3.0).abs() < 1e-12, "{busy:?}");
        assert!((busy[1] - (150.0 / 200.0 + 180.0 / 190.0) / 3.0).abs() < 1e-12, "{busy:?}");
    }

    #[test]
    fn a_frame_after_a_skipped_one_has_no_between_frame_figures() {
        let mut stats = FrameStats::new();
        stats.fold(&report(4, 0, &[("a", 0, 10, 20)]));
        stats.fold(&report(6, 100, &[("a", 0, 110, 120)]));
        assert_eq!(stats.interval_ms().count(), 0);
        assert_eq!(stats.gpu_gap_ms().count(), 0);
    }
}
