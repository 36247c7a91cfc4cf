//! Retiring frames: waiting for a frame's last segments, turning its timestamps into a report,
//! keeping its readback.

use std::time::Instant;

use ash::vk;

use crate::device::CalibrationMethod;
use crate::error::{BackendError, Result, VkContext};
use crate::readback::{FrameReadback, FrameTicket};
use crate::relay::Relay;
use crate::segments::progress_value;
use crate::timing::{FrameReport, TimedEvent};

use super::Executor;

/// How long the host waits while no device makes progress before declaring a frame lost: a
/// signal that never comes or a hung GPU. Measured from the last progress of any device (a
/// segment done), not from the frame's start, so a frame that is slow but moving never times
/// out.
const STALL_TIMEOUT_S: u64 = 60;
/// The same for devices that run on the host's CPU (lavapipe): a loaded machine can hold one
/// segment of theirs for longer than a GPU would ever take.
const STALL_TIMEOUT_CPU_DEVICE_S: u64 = 600;

impl Executor {
    /// Waits for the frame of `ticket` (and so for the frames submitted before it, which finish
    /// first) — not for later frames — and returns its exported resources.
    pub fn wait_readback(&mut self, ticket: FrameTicket) -> Result<FrameReadback> {
        while self.in_flight.front().is_some_and(|f| f.frame <= ticket.frame) {
            self.retire_oldest()?;
        }
        self.readback
            .as_mut()
            .and_then(|r| r.take(ticket.frame))
            .ok_or(BackendError::ReadbackUnavailable { frame: ticket.frame })
    }

    /// Waits for every frame in flight (their reports become available).
    pub fn finish(&mut self) -> Result<()> {
        while !self.in_flight.is_empty() {
            self.retire_oldest()?;
        }
        Ok(())
    }

    /// Waits for the oldest frame in flight and turns its timestamps into a report.
    pub(super) fn retire_oldest(&mut self) -> Result<()> {
        let Some(f) = self.in_flight.pop_front() else {
            return Ok(());
        };
        // A failed link let its frames through with what its staging held (remote.rs).
        let remote_check = || self.remote.as_ref().map_or(Ok(()), crate::remote::Remote::check);
        remote_check()?;
        let mut events = Vec::new();
        for (d, state) in self.states.iter().enumerate() {
            let segment_count = state.segments.len();
            if segment_count == 0 {
                continue;
            }
            self.wait_for_progress(d, progress_value(f.local, segment_count, segment_count - 1), f.frame)?;
            // Its staging slot is written again by a later frame: its chunks for other processes
            // must have left it (remote.rs).
            if let Some(remote) = &self.remote {
                while !remote.sent_frame(d, f.local) {
                    self.relay.as_ref().map_or(Ok(()), Relay::check)?;
                    std::thread::sleep(std::time::Duration::from_micros(100));
                }
            }
            let timers = state.timers.len();
            if timers == 0 {
                continue;
            }
            let mut ticks = vec![0u64; timers * 2];
            unsafe {
                state.device.raw.get_query_pool_results(
                    state.slots[f.slot].query_pool,
                    0,
                    &mut ticks,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .vk("vkGetQueryPoolResults")?;
            // Calibrated timestamps are cheap: re-sample so that clock drift never accumulates.
            if self.calibration[d].method == CalibrationMethod::CalibratedTimestamps {
                self.calibration[d] = state.device.clock_offset()?;
            }
            let calibration = self.calibration[d];
            for (t, label) in state.timers.iter().enumerate() {
                let to_host = |ticks: u64| state.device.timestamp_to_host_ns(ticks, label.queue, &calibration);
                events.push(TimedEvent {
                    name: label.name.clone(),
                    kind: label.kind,
                    device: d,
                    view: label.view,
                    index: label.index,
                    chunk: label.chunk,
                    copies: label.copies,
                    bytes: label.bytes,
                    gather: label.gather,
                    start_ns: to_host(ticks[2 * t]),
                    end_ns: to_host(ticks[2 * t + 1]),
                });
            }
        }
        remote_check()?;
        self.first_frame_done_ns.get_or_insert_with(crate::device::host_now_ns);
        let mut report = FrameReport::new(
            f.frame,
            f.submit_start_ns,
            f.submit_cpu_ns,
            f.passes,
            f.segments,
            self.devices.len(),
            events,
        );
        report.slot_wait_ns = f.slot_wait_ns;
        self.reports.push(report);
        if let (true, Some(readback)) = (f.read_back, &mut self.readback) {
            readback.retire(f.frame, f.slot);
        }
        Ok(())
    }

    /// Waits until device `d`'s progress timeline reaches `value`, in short steps so that a
    /// failed relay thread is reported instead of hanging; an error once no device has made
    /// progress for the stall timeout.
    pub(super) fn wait_for_progress(&self, d: usize, value: u64, frame: u64) -> Result<()> {
        let state = &self.states[d];
        let seconds = if self.states.iter().any(|s| s.device.info.runs_on_host_cpu) {
            STALL_TIMEOUT_CPU_DEVICE_S
        } else {
            STALL_TIMEOUT_S
        };
        let stall = std::time::Duration::from_secs(seconds);
        let mut progress = self.total_progress()?;
        let mut moved_at = Instant::now();
        while !state.device.wait_timeline(state.progress, value, 100_000_000)? {
            self.relay.as_ref().map_or(Ok(()), Relay::check)?;
            self.remote.as_ref().map_or(Ok(()), crate::remote::Remote::check)?;
            let now = self.total_progress()?;
            if now != progress {
                (progress, moved_at) = (now, Instant::now());
            } else if moved_at.elapsed() > stall {
                return Err(BackendError::FrameTimeout { frame, device: d, seconds });
            }
        }
        Ok(())
    }

    /// The sum of every device's progress timeline: it grows whenever any segment is done.
    fn total_progress(&self) -> Result<u64> {
        self.states.iter().try_fold(0u64, |sum, s| Ok(sum.wrapping_add(s.device.timeline_value(s.progress)?)))
    }
}
