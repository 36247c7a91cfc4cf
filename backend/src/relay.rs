//! Cross-device ordering without shared semaphores (`shared` and `relay` links, links.rs): one
//! host thread per device waits on that device's progress timeline and signals the consumer
//! device's timeline. Not started when every link waits on the GPU (`gpu` links) and no fault
//! is injected.
//!
//! Lavapipe has no VK_KHR_external_semaphore_fd, nor do separate GPUs share timelines. The
//! render thread only enqueues jobs; it never waits for a producer.
//!
//! Deadlock freedom: jobs watching one device are enqueued in the order that device's segments
//! are submitted, so their watched values increase; a job can only block later jobs of the same
//! device, which need a larger value anyway.
//!
//! A thread blocks in one vkWaitSemaphores (no timeout) on "the producer's progress reaches the
//! job's value, or the thread's own wake timeline reaches 1": it wakes on the signal itself, and
//! shutting down host-signals the wake timeline instead of waiting out a polling slice.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use ash::vk;

use crate::device::Device;
use crate::error::{BackendError, Result};

/// "When the watched device's progress reaches `watch_value`, do `action`."
pub(crate) struct RelayJob {
    pub watch_value: u64,
    pub action: RelayAction,
}

/// What a relay job does once its value is reached.
pub(crate) enum RelayAction {
    /// Set `target`'s `semaphore` to `value`.
    Signal { target: Arc<Device>, semaphore: vk::Semaphore, value: u64 },
    /// Hand chunks that are now in host staging to another process (crate::remote).
    Send(Box<dyn FnOnce() -> Result<()> + Send>),
}

impl RelayJob {
    pub(crate) fn signal(watch_value: u64, target: Arc<Device>, semaphore: vk::Semaphore, value: u64) -> Self {
        Self { watch_value, action: RelayAction::Signal { target, semaphore, value } }
    }
}

struct Worker {
    device: Arc<Device>,
    sender: Option<Sender<RelayJob>>,
    thread: Option<JoinHandle<()>>,
    /// Host-signalled to 1 to end the thread's wait at shutdown.
    wake: vk::Semaphore,
}

/// The relay threads of an executor, one per device.
pub(crate) struct Relay {
    workers: Vec<Worker>,
    stop: Arc<AtomicBool>,
    failure: Arc<Mutex<Failure>>,
}

/// What the relay threads have hit.
#[derive(Default)]
enum Failure {
    #[default]
    None,
    /// The first error, not yet handed to the executor.
    Pending(BackendError),
    /// Handed over; later checks still fail.
    Reported,
}

/// How long a relay thread polls the producer's timeline before it blocks. A blocking
/// vkWaitSemaphores on NVIDIA wakes 50–250 µs after the signal (measured on H200), which is a
/// whole 8 MiB chunk of PCIe time; polling hands a chunk over in ~25 µs. The window covers a
/// frame in flight ahead of its producer; the thread yields between polls so it only uses an
/// otherwise idle core. Only done for real GPUs: on lavapipe the "GPU" is the CPU cores a
/// polling thread would steal.
const SPIN: std::time::Duration = std::time::Duration::from_millis(5);

impl Relay {
    /// Starts one relay thread per device; `progress[d]` is device d's progress timeline.
    pub(crate) fn new(devices: &[Arc<Device>], progress: &[vk::Semaphore]) -> Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let failure = Arc::new(Mutex::new(Failure::None));
        let mut relay = Self { workers: Vec::with_capacity(devices.len()), stop, failure };
        for (device, &timeline) in devices.iter().zip(progress) {
            let wake = device.create_timeline(0)?;
            let (sender, receiver) = channel();
            let (thread_device, stop, failure) = (device.clone(), relay.stop.clone(), relay.failure.clone());
            let thread = std::thread::Builder::new()
                .name(format!("parallax-relay-{}", device.info.index))
                .spawn(move || run_worker(&thread_device, [timeline, wake], &receiver, &stop, &failure));
            let thread = match thread {
                Ok(thread) => thread,
                Err(e) => {
                    unsafe { device.raw.destroy_semaphore(wake, None) };
                    return Err(BackendError::Relay(format!("starting relay thread {}: {e}", device.info.index)));
                }
            };
            relay.workers.push(Worker { device: device.clone(), sender: Some(sender), thread: Some(thread), wake });
        }
        Ok(relay)
    }

    /// Queues `job` on the thread watching device `watched`.
    pub(crate) fn push(&self, watched: usize, job: RelayJob) -> Result<()> {
        self.check()?;
        self.workers[watched]
            .sender
            .as_ref()
            .and_then(|s| s.send(job).ok())
            .ok_or_else(|| BackendError::Relay(format!("relay thread {watched} is gone")))
    }

    /// Fails if a relay thread hit an error: the first time with that error (a lost device
    /// stays [`BackendError::DeviceLost`]), later with a note that it was reported.
    pub(crate) fn check(&self) -> Result<()> {
        let mut failure = self.failure.lock().unwrap_or_else(|p| p.into_inner());
        match std::mem::replace(&mut *failure, Failure::Reported) {
            Failure::None => {
                *failure = Failure::None;
                Ok(())
            }
            Failure::Pending(error) => Err(error),
            Failure::Reported => Err(BackendError::Relay("a relay thread failed earlier (reported above)".into())),
        }
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        // Pending jobs are abandoned: the executor waits for its frames before dropping us,
        // so only jobs of frames that will never complete (after an error) remain.
        self.stop.store(true, Ordering::SeqCst);
        for worker in &mut self.workers {
            worker.sender.take();
            // A failed signal (a lost device) also ends the thread's wait, with an error.
            let _ = worker.device.signal_timeline(worker.wake, 1);
            if let Some(t) = worker.thread.take() {
                let _ = t.join();
            }
            unsafe { worker.device.raw.destroy_semaphore(worker.wake, None) };
        }
    }
}

/// Serves the jobs watching `device`: `[progress, wake]` are its progress timeline and the
/// thread's wake timeline.
fn run_worker(
    device: &Device,
    [timeline, wake]: [vk::Semaphore; 2],
    jobs: &Receiver<RelayJob>,
    stop: &AtomicBool,
    failure: &Mutex<Failure>,
) {
    // A lost device is reported as such; other errors with what the thread was doing.
    let fail = |doing: String, error: BackendError| {
        let mut failure = failure.lock().unwrap_or_else(|p| p.into_inner());
        if matches!(*failure, Failure::None) {
            *failure = Failure::Pending(match error {
                lost @ BackendError::DeviceLost { .. } => lost,
                error => BackendError::Relay(format!("{doing}: {error}")),
            });
        }
    };
    let spin = device.info.device_type != "CPU";
    while let Ok(job) = jobs.recv() {
        if spin {
            let start = std::time::Instant::now();
            while start.elapsed() < SPIN {
                match device.timeline_value(timeline) {
                    Ok(v) if v >= job.watch_value => break,
                    Ok(_) => std::thread::yield_now(),
                    Err(e) => {
                        fail(format!("reading device {} progress", device.info.index), e);
                        return;
                    }
                }
            }
        }
        if let Err(e) = device.wait_any_timeline(&[timeline, wake], &[job.watch_value, 1]) {
            fail(format!("waiting on device {} for value {}", device.info.index, job.watch_value), e);
            return;
        }
        if stop.load(Ordering::SeqCst) {
            return;
        }
        let done = match job.action {
            RelayAction::Signal { target, semaphore, value } => target
                .signal_timeline(semaphore, value)
                .map_err(|e| (format!("signalling device {} to value {value}", target.info.index), e)),
            RelayAction::Send(send) => send().map_err(|e| (format!("sending from device {}", device.info.index), e)),
        };
        if let Err((doing, e)) = done {
            fail(doing, e);
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::context::{Context, ContextDesc, DeviceSelection};
    use crate::instance::Validation;

    /// Generous bound on how long a relay may take to forward or to stop: only a hang guard.
    const HANG_GUARD: std::time::Duration = std::time::Duration::from_secs(120);

    #[test]
    fn a_job_is_forwarded_on_the_producers_signal_and_one_never_reached_is_abandoned_at_drop() {
        let context =
            Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(2), validation: Validation::Core })
                .unwrap();
        let [producer, consumer] = [context.devices[0].clone(), context.devices[1].clone()];
        let progress = [producer.create_timeline(0).unwrap(), consumer.create_timeline(0).unwrap()];
        let ready = consumer.create_timeline(0).unwrap();
        let relay = Relay::new(&context.devices, &progress).unwrap();
        let job = |value| RelayJob::signal(value, consumer.clone(), ready, value);
        relay.push(0, job(1)).unwrap();
        relay.push(0, job(2)).unwrap();
        producer.signal_timeline(progress[0], 1).unwrap();
        assert!(consumer.wait_timeline(ready, 1, HANG_GUARD.as_nanos() as u64).unwrap(), "job 1 forwarded");
        // Job 2's value never comes: dropping the relay wakes its thread anyway.
        let (done, dropped) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            drop(relay);
            let _ = done.send(());
        });
        dropped.recv_timeout(HANG_GUARD).expect("the relay stops while a job waits");
        assert_eq!(consumer.timeline_value(ready).unwrap(), 1, "the unreached job is abandoned, not signalled");
        unsafe {
            producer.raw.destroy_semaphore(progress[0], None);
            consumer.raw.destroy_semaphore(progress[1], None);
            consumer.raw.destroy_semaphore(ready, None);
        }
        context.check_validation().unwrap();
    }
}
