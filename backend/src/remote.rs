//! Links whose other end is a device of another process (`remote` links, links.rs): a render
//! split over processes (the ranks of an MPI run) whose schedule copies between devices of two
//! of them. The backend knows no transport: the executor is given a [`RemoteTransport`]
//! (`ExecOptions::remote`) and moves each chunk of such a copy through it.
//!
//! A plan names another process's device by a number past its own devices
//! ([`remote_device_id`]); a copy with one end there is a remote copy. Its messages are named
//! by a [`Wire`]: its two devices and its place among the remote copies between them in plan
//! order, which the plans of both processes keep, so both ends name it alike without talking.
//!
//! * The producer copies a chunk out into host staging of its own, as for a `relay` link; once
//!   its segment is done, its relay thread (relay.rs) copies the bytes out of staging and hands
//!   them to the transport, which sends them without blocking.
//! * The consumer has one receive thread per link into it: it takes the link's chunks of a
//!   frame in the order the consumer copies them in, waits for each from the transport, writes
//!   it into host staging and raises the link's ready timeline, which the copy-in waits on. A
//!   chunk's ready value is its place in the consumer's order, so a wait on it needs no chunk
//!   that the waiting segment (or one before it) does not copy in anyway: the numbering adds no
//!   dependency between the processes.
//!
//! The producer's slot of staging is written again only after its frame retired, and a frame
//! retires only once the relay thread has handed its chunks over (`Remote::sent_frame`); the
//! consumer's slot is written when the frame that uses it is submitted, after the slot's
//! previous frame retired.
//!
//! A receive that fails (the transport says why: another process failed or fell silent) lets
//! the frames already submitted through, so that nothing queued waits for ever, and the
//! executor fails at its next check (`Remote::check`: submitting, waiting, retiring).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use ash::vk;

use crate::device::Device;
use crate::error::{BackendError, Result};
use crate::links::{ChunkLink, LinkOrder};
use crate::plan::{DeviceId, ExecutionPlan};
use crate::segments::{Chunk, Item, Segment, ready_value};

/// Moves the chunks of remote copies between processes. Both calls return at once: the bytes
/// of a send are the transport's, and a receive's bytes come through the channel it returns, or
/// why they never will (the other process failed or fell silent: the message names it).
pub trait RemoteTransport: Send + Sync + std::fmt::Debug {
    /// Sends the next chunk of `wire` (from this process's device `wire.local`).
    fn send(&self, wire: Wire, bytes: Vec<u8>) -> std::result::Result<(), String>;
    /// Receives the next chunk of `wire` (into this process's device `wire.local`), `bytes` long.
    fn receive(&self, wire: Wire, bytes: usize) -> Receiver<std::result::Result<Vec<u8>, String>>;
}

/// What names the messages of one remote copy on both of its ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Wire {
    /// Its device on this process (the plan's index).
    pub local: usize,
    /// Its device on the other process, by the run's number ([`remote_device`]).
    pub remote: u32,
    /// Its place among the plan's remote copies from its producer to its consumer.
    pub copy: u32,
}

/// How a plan of `plan_devices` devices names device `device` of another process.
pub fn remote_device_id(plan_devices: usize, device: u32) -> DeviceId {
    DeviceId(plan_devices as u32 + device)
}

/// The device of another process that a plan of `plan_devices` devices names `id`, if any.
pub fn remote_device(plan_devices: usize, id: DeviceId) -> Option<u32> {
    id.0.checked_sub(plan_devices as u32)
}

/// The wire of every copy of `plan` (`None` for copies between its own devices).
pub(crate) fn wires(plan: &ExecutionPlan) -> Vec<Option<Wire>> {
    let n = plan.devices.len();
    let mut counts: BTreeMap<(u32, u32), u32> = BTreeMap::new();
    plan.copies
        .iter()
        .map(|c| {
            let (local, remote) = match (remote_device(n, c.from), remote_device(n, c.to)) {
                (None, Some(remote)) => (c.from.index(), remote),
                (Some(remote), None) => (c.to.index(), remote),
                _ => return None,
            };
            let count = counts.entry((c.from.0, c.to.0)).or_default();
            let wire = Wire { local, remote, copy: *count };
            *count += 1;
            Some(wire)
        })
        .collect()
}

/// Adds to `order` the links into this process's devices from other processes' devices, each
/// chunk numbered by the order its consumer copies it in (see the module documentation).
pub(crate) fn number_receives(plan: &ExecutionPlan, segments: &[Vec<Segment>], order: &mut LinkOrder) {
    let n = plan.devices.len();
    for (to, device) in segments.iter().enumerate() {
        for chunk in device.iter().flat_map(|s| &s.items).filter_map(|item| match item {
            Item::CopyIn(chunk) => Some(chunk),
            _ => None,
        }) {
            let from = plan.copy(chunk.copy).from.index();
            if from < n {
                continue;
            }
            let link = match order.links.iter().position(|&(f, t, _)| (f, t) == (from, to)) {
                Some(link) => link,
                None => {
                    order.links.push((from, to, 0));
                    order.links.len() - 1
                }
            };
            let position = order.links[link].2;
            order.chunks[chunk.copy.index()][chunk.index as usize] = ChunkLink { link, position, segment: 0 };
            order.links[link].2 += 1;
        }
    }
}

/// Bytes of host staging that one chunk occupies, handed to another thread.
#[derive(Clone, Copy)]
pub(crate) struct HostSpan {
    ptr: *mut u8,
    len: usize,
}

// The staging memory outlives the threads that use a span (the executor stops them first), and
// a span is only touched while no device copies through it (see the module documentation).
unsafe impl Send for HostSpan {}

impl HostSpan {
    /// `len` bytes at `offset` of the host allocation at `base`.
    pub(crate) fn new(base: *mut u8, offset: u64, len: u64) -> Self {
        Self { ptr: unsafe { base.add(offset as usize) }, len: len as usize }
    }

    fn read(&self) -> Vec<u8> {
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }.to_vec()
    }

    fn write(&self, bytes: &[u8]) {
        unsafe { std::slice::from_raw_parts_mut(self.ptr, self.len) }.copy_from_slice(bytes);
    }
}

/// A link into a device of this process from another process's device.
pub(crate) struct ReceiveLink {
    pub(crate) link: usize,
    /// Its chunks of a frame in the consumer's order, with their wires.
    pub(crate) chunks: Vec<(Chunk, Wire)>,
}

/// One chunk to receive: where it goes and the ready value that says it is there.
pub(crate) struct Arrival {
    pub(crate) wire: Wire,
    pub(crate) span: HostSpan,
    pub(crate) ready_value: u64,
}

struct Receiving {
    jobs: Option<Sender<Vec<Arrival>>>,
    thread: Option<JoinHandle<()>>,
}

/// The remote side of an executor's plan: its transport, its receive threads, and per device
/// the chunks its relay thread has handed to the transport.
pub(crate) struct Remote {
    pub(crate) transport: Arc<dyn RemoteTransport>,
    pub(crate) wires: Vec<Option<Wire>>,
    pub(crate) receives: Vec<ReceiveLink>,
    threads: Vec<Receiving>,
    stop: Arc<AtomicBool>,
    failure: Arc<Mutex<Option<String>>>,
    /// Per device of this process: chunks handed over so far, and per frame.
    pub(crate) sent: Vec<Arc<AtomicU64>>,
    pub(crate) sends_per_frame: Vec<u64>,
}

/// How often a receive thread looks whether it should stop while it waits for a chunk.
const STOP_POLL: Duration = Duration::from_millis(50);

impl Remote {
    /// Starts one receive thread per link of `receives`; `ends[i]` is its consumer device and
    /// ready timeline.
    pub(crate) fn new(
        transport: Arc<dyn RemoteTransport>,
        wires: Vec<Option<Wire>>,
        receives: Vec<ReceiveLink>,
        ends: Vec<(Arc<Device>, vk::Semaphore)>,
        sends_per_frame: Vec<u64>,
        slots: usize,
    ) -> Result<Self> {
        let mut remote = Self {
            transport,
            wires,
            receives,
            threads: Vec::new(),
            stop: Arc::new(AtomicBool::new(false)),
            failure: Arc::new(Mutex::new(None)),
            sent: sends_per_frame.iter().map(|_| Arc::new(AtomicU64::new(0))).collect(),
            sends_per_frame,
        };
        for ((device, ready), link) in ends.into_iter().zip(&remote.receives) {
            let per_frame = link.chunks.len() as u64;
            let (sender, jobs) = channel();
            let (transport, stop, failure) = (remote.transport.clone(), remote.stop.clone(), remote.failure.clone());
            let thread = std::thread::Builder::new()
                .name(format!("parallax-receive-{}", device.info.index))
                .spawn(move || {
                    let mut last = 0;
                    if let Err(e) = receive(&device, ready, &*transport, &jobs, &stop, &mut last) {
                        failure.lock().unwrap_or_else(|p| p.into_inner()).get_or_insert(e);
                        // Frames already submitted would wait for the link for ever, and a
                        // driver may wait for them too (lavapipe reads queries only once its
                        // queue is idle): they are let through, and the executor fails at its
                        // next check instead. At most `slots` frames follow the failed one.
                        let frame = last.saturating_sub(1) / per_frame.max(1);
                        let _ =
                            device.signal_timeline(ready, ready_value(frame + slots as u64 + 1, per_frame, per_frame));
                    }
                })
                .map_err(|e| BackendError::Remote(format!("starting a receive thread: {e}")))?;
            remote.threads.push(Receiving { jobs: Some(sender), thread: Some(thread) });
        }
        Ok(remote)
    }

    /// Queues the chunks of frame `local` for each receive link (`spans[i][k]`: where chunk k
    /// of link i goes; `per_frame[i]` its chunks a frame).
    pub(crate) fn queue_frame(&self, local: u64, spans: Vec<Vec<HostSpan>>) -> Result<()> {
        self.check()?;
        for ((link, spans), receiving) in self.receives.iter().zip(spans).zip(&self.threads) {
            let per_frame = link.chunks.len() as u64;
            let arrivals = link
                .chunks
                .iter()
                .zip(spans)
                .enumerate()
                .map(|(k, (&(_, wire), span))| Arrival {
                    wire,
                    span,
                    ready_value: ready_value(local, per_frame, k as u64),
                })
                .collect();
            receiving
                .jobs
                .as_ref()
                .and_then(|s| s.send(arrivals).ok())
                .ok_or_else(|| BackendError::Remote("a receive thread is gone".into()))?;
        }
        Ok(())
    }

    /// The job that hands chunk bytes at `span` over `wire` to the transport once device
    /// `device`'s segment is done (run by its relay thread).
    pub(crate) fn send_job(&self, device: usize, wire: Wire, span: HostSpan) -> Box<dyn FnOnce() -> Result<()> + Send> {
        let (transport, sent) = (self.transport.clone(), self.sent[device].clone());
        Box::new(move || {
            transport.send(wire, span.read()).map_err(BackendError::Remote)?;
            sent.fetch_add(1, Ordering::SeqCst);
            Ok(())
        })
    }

    /// Whether device `device`'s relay thread has handed over every chunk of frame `local`.
    pub(crate) fn sent_frame(&self, device: usize, local: u64) -> bool {
        self.sent[device].load(Ordering::SeqCst) >= (local + 1) * self.sends_per_frame[device]
    }

    /// Fails once a receive thread failed: with its message the first time, later too.
    pub(crate) fn check(&self) -> Result<()> {
        match &*self.failure.lock().unwrap_or_else(|p| p.into_inner()) {
            Some(e) => Err(BackendError::Remote(e.clone())),
            None => Ok(()),
        }
    }
}

impl Drop for Remote {
    fn drop(&mut self) {
        // Chunks not yet received are abandoned: the executor waits for its frames first, so
        // only those of frames that will never complete (after an error) remain.
        self.stop.store(true, Ordering::SeqCst);
        for receiving in &mut self.threads {
            receiving.jobs.take();
            if let Some(thread) = receiving.thread.take() {
                let _ = thread.join();
            }
        }
    }
}

/// Serves one receive link: each chunk from the transport into staging, then the ready value.
fn receive(
    device: &Device,
    ready: vk::Semaphore,
    transport: &dyn RemoteTransport,
    jobs: &Receiver<Vec<Arrival>>,
    stop: &AtomicBool,
    last: &mut u64,
) -> std::result::Result<(), String> {
    while let Ok(frame) = jobs.recv() {
        for arrival in frame {
            *last = arrival.ready_value;
            let incoming = transport.receive(arrival.wire, arrival.span.len);
            let bytes = loop {
                match incoming.recv_timeout(STOP_POLL) {
                    Ok(bytes) => break bytes?,
                    Err(RecvTimeoutError::Timeout) if !stop.load(Ordering::SeqCst) => {}
                    Err(RecvTimeoutError::Timeout) => return Ok(()),
                    Err(RecvTimeoutError::Disconnected) => return Err("the transport stopped".into()),
                }
            };
            if bytes.len() != arrival.span.len {
                return Err(format!(
                    "a chunk of {:?} arrived with {} bytes instead of {}: the processes run different plans",
                    arrival.wire,
                    bytes.len(),
                    arrival.span.len
                ));
            }
            arrival.span.write(&bytes);
            device
                .signal_timeline(ready, arrival.ready_value)
                .map_err(|e| format!("signalling device {} after a chunk arrived: {e}", device.info.index))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::collections::{HashMap, VecDeque};

    use super::*;
    use crate::bench::copy_plan;
    use crate::context::{Context, ContextDesc, DeviceSelection};
    use crate::exec_options::ExecOptions;
    use crate::executor::Executor;
    use crate::instance::Validation;
    use crate::kernel::KernelPlan;
    use crate::links::LinkKind;
    use crate::plan::{CopyId, CrossCopy, Op, Region};

    type Reply = Sender<std::result::Result<Vec<u8>, String>>;

    /// Per copy number: chunks sent and not yet received, and receives waiting for a chunk.
    #[derive(Debug, Default)]
    struct Queues {
        sent: HashMap<u32, VecDeque<Vec<u8>>>,
        waiting: HashMap<u32, VecDeque<Reply>>,
    }

    /// A transport within one process: a chunk sent on copy k is the next one received on
    /// copy k (both ends of a wire have the same place among their remote copies).
    #[derive(Debug, Default)]
    struct Loopback {
        queues: Mutex<Queues>,
    }

    impl RemoteTransport for Loopback {
        fn send(&self, wire: Wire, bytes: Vec<u8>) -> std::result::Result<(), String> {
            let Queues { sent, waiting } = &mut *self.queues.lock().unwrap();
            match waiting.get_mut(&wire.copy).and_then(VecDeque::pop_front) {
                Some(reply) => reply.send(Ok(bytes)).map_err(|e| e.to_string())?,
                None => sent.entry(wire.copy).or_default().push_back(bytes),
            }
            Ok(())
        }

        fn receive(&self, wire: Wire, _bytes: usize) -> Receiver<std::result::Result<Vec<u8>, String>> {
            let (reply, received) = channel();
            let Queues { sent, waiting } = &mut *self.queues.lock().unwrap();
            match sent.get_mut(&wire.copy).and_then(VecDeque::pop_front) {
                Some(bytes) => reply.send(Ok(bytes)).expect("the receiver is here"),
                None => waiting.entry(wire.copy).or_default().push_back(reply),
            }
            received
        }
    }

    /// What device 1 holds of the payload after `frames` frames of `plan`.
    fn received(context: &Context, plan: KernelPlan, options: ExecOptions, frames: usize) -> Vec<u8> {
        let dst = plan.copies.last().expect("a copy").dst_alloc;
        let mut executor = Executor::new(context, plan, options).unwrap();
        for _ in 0..frames {
            executor.run_frame().unwrap();
        }
        executor.read_resource(DeviceId(1), dst).unwrap()
    }

    /// The copy of the copy benchmark, device 0 → device 1, cut in two remote copies that a
    /// loopback transport joins (device 0 → device 7 of "another process" → device 1), in
    /// small chunks over three frames: device 1 receives what the plain copy gives it, bit for
    /// bit, and the links say `remote` with the copy's bytes.
    #[test]
    fn a_copy_through_a_transport_delivers_what_a_copy_between_devices_does() {
        let context =
            Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(2), validation: Validation::Core })
                .unwrap();
        let plain = copy_plan(64, 32).unwrap();
        let mut split = plain.clone();
        let elsewhere = remote_device_id(2, 7);
        split.copies =
            vec![CrossCopy { to: elsewhere, ..plain.copies[0] }, CrossCopy { from: elsewhere, ..plain.copies[0] }];
        for op in &mut split.devices[1].ops {
            *op = match *op {
                Op::Wait(_) => Op::Wait(CopyId(1)),
                Op::CopyIn(_) => Op::CopyIn(CopyId(1)),
                op => op,
            };
        }
        let options = || ExecOptions { chunk_bytes: 64 * 16 * 5, ..ExecOptions::default() };
        let transport: Arc<dyn RemoteTransport> = Arc::new(Loopback::default());
        let remote = ExecOptions { remote: Some(transport), ..options() };
        let bytes = plain.copy_bytes(CopyId(0));
        {
            let executor = Executor::new(&context, split.clone(), remote.clone()).unwrap();
            let links: Vec<_> = executor.links().iter().map(|l| (l.from, l.to, l.kind, l.bytes_per_frame)).collect();
            assert_eq!(links, vec![(0, 9, LinkKind::Remote, bytes), (9, 1, LinkKind::Remote, bytes)]);
        }
        let expected = received(&context, plain, options(), 3);
        assert!(expected.iter().any(|&b| b != 0), "the fill wrote something");
        assert_eq!(received(&context, split.clone(), remote, 3), expected);
        // Without a transport the plan is refused before any work.
        let refused = Executor::new(&context, split, options()).err().expect("refused");
        assert!(matches!(refused, BackendError::Remote(ref m) if m.contains("ExecOptions::remote")), "{refused}");
        context.check_validation().unwrap();
    }

    /// Copies in both directions between device 0 and two devices of other processes (run
    /// numbers 3 and 5): each direction's copies are numbered apart, in plan order.
    #[test]
    fn remote_copies_are_numbered_per_pair_and_direction_in_plan_order() {
        let mut plan = crate::bench::gather_plan(2, 4, 4).unwrap();
        let n = plan.devices.len();
        let copy = |from, to| CrossCopy { from, to, ..plan.copies[0] };
        let (local, three, five) = (DeviceId(0), remote_device_id(n, 3), remote_device_id(n, 5));
        plan.copies = vec![
            copy(local, three),
            copy(three, local),
            copy(local, three),
            copy(local, five),
            copy(DeviceId(1), local),
            copy(local, three),
        ];
        plan.copies[1].region = Region::new(0, 1);
        let wire = |local, remote, copy| Some(Wire { local, remote, copy });
        assert_eq!(wires(&plan), vec![wire(0, 3, 0), wire(0, 3, 0), wire(0, 3, 1), wire(0, 5, 0), None, wire(0, 3, 2)]);
        assert_eq!(remote_device(n, five), Some(5));
        assert_eq!(remote_device(n, DeviceId(1)), None);
    }
}
