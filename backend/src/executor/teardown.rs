//! Ending an executor: waiting for its frames, and after a failure unblocking the device waits
//! nobody will signal, so the queues drain before memory and semaphores go.

use ash::vk;

use crate::device::Device;
use crate::links::LinkKind;
use crate::segments::ready_value;

use super::Executor;

impl Executor {
    /// After a failure (a relay thread died, a frame timed out), submissions may wait on values
    /// nobody will signal, and waiting for the devices to go idle would hang. Signals every
    /// cross-device semaphore to the last value any submitted frame waits for, so the queues
    /// drain (with meaningless contents) and teardown can proceed. That includes the frame
    /// `next_frame`, whose submission the failure may have cut short: its first segments can
    /// be on the queues already.
    fn unblock_device_waits(&mut self) {
        self.relay = None;
        self.remote = None;
        let local = self.next_frame.saturating_sub(self.plan_epoch);
        // A `gpu` link's consumer waits on the producer's own progress, which only its GPU may
        // raise (a host signal below a later GPU signal would break the timeline). It needs no
        // help: every segment is submitted after the segments it waits for
        // (`submission_order`), so once the relayed waits are released everything submitted
        // can run to its end.
        // A remote link's ready timeline is on this process's end where it is the consumer.
        let here = self.devices.len();
        for link in self.links.iter().filter(|l| l.kind.relayed() || (l.kind == LinkKind::Remote && l.to < here)) {
            let value = ready_value(local, link.per_frame, link.per_frame.saturating_sub(1));
            raise_timeline(&self.devices[link.to], link.ready, value);
        }
        if let Some(gate) = &self.gate {
            raise_timeline(&self.devices[gate.producer], gate.semaphore, local + 1);
        }
        self.in_flight.clear();
    }
}

impl Drop for Executor {
    fn drop(&mut self) {
        // Frames in flight must end before their memory and semaphores go; relay threads
        // before the semaphores they wait on.
        if self.finish().is_err() || self.cut_short {
            self.unblock_device_waits();
        }
        for device in &self.devices {
            let _ = device.wait_idle();
        }
        self.relay = None;
        self.remote = None;
        self.staging = None;
        self.states.clear();
        self.globals.clear();
        self.textures.clear();
        self.frame_data_buffers.clear();
    }
}

/// Host-signals `semaphore` to `value` unless it is already there (a timeline never goes back).
/// Errors are ignored: this only runs while tearing down after a failure.
fn raise_timeline(device: &Device, semaphore: vk::Semaphore, value: u64) {
    if device.timeline_value(semaphore).is_ok_and(|current| current < value) {
        let _ = device.signal_timeline(semaphore, value);
    }
}
