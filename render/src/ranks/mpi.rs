//! The MPI side of a render over several ranks (`--features mpi`, run under `mpirun`), through
//! rsmpi. Rank 0 sends every rank the run's settings and each frame's camera; every other rank
//! sends rank 0 a few bytes after each frame (its frame time: the run's heartbeat), then its
//! finished views, or the reason it failed. Rank 0 never blocks on a receive: it polls
//! matched probes (MPI_Improbe) against `--rank-timeout`, so a rank that hangs or vanished ends
//! the run with a message naming it instead of a wait without end.
//!
//! Messages are bytes: a JSON header, then the raw blobs it lists.
//!
//! Under a fine scheme the ranks' devices also exchange bands every frame: the executor's
//! `remote` links, through [`LinkTransport`], on a communicator of their own.

use std::cell::RefCell;
use std::collections::{HashMap, VecDeque};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context as _, Result, bail};
use mpi::Threading;
use mpi::environment::Universe;
use mpi::point_to_point::MatchedReceiveVec;
use mpi::request::{Request, StaticScope};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use parallax_backend::{RemoteTransport, Wire};

use crate::ranks::RankLayout;

/// rank 0 → rank r: the run's settings and the camera of every frame.
const TAG_FRAMES: i32 = 10;
/// rank r → rank 0: one frame done (its index and host wall time).
const TAG_FRAME: i32 = 11;
/// rank r → rank 0: the length of its finished views and statistics, which follow in parts
/// ([`TAG_PART`]) of at most [`PART_BYTES`]: MPI counts elements in an `int`.
const TAG_DONE: i32 = 12;
const TAG_PART: i32 = 14;
const PART_BYTES: usize = 1 << 30;
/// rank r → rank 0: why the rank stopped.
const TAG_FAILED: i32 = 13;

/// Longest host name exchanged (longer ones are cut).
const HOST_BYTES: usize = 64;

/// This process's place in an MPI run of several ranks.
pub struct Cluster {
    /// The communicator of the links between ranks' devices (a duplicate of the world's, so
    /// that their messages never match the run's own), until a [`LinkTransport`] takes it;
    /// freed before MPI is finalised (fields drop in order).
    links: RefCell<Option<SimpleCommunicator>>,
    /// Finalised when dropped (MPI_Finalize): only after a successful run, as finalising waits
    /// for every rank.
    _universe: Universe,
    world: SimpleCommunicator,
    pub rank: usize,
    /// Every rank's host, by rank.
    pub hosts: Vec<String>,
    /// Whether MPI lets the links' thread call it beside the main thread.
    threads_allowed: bool,
}

thread_local! {
    /// The cluster of this process: MPI lives on the main thread only.
    static CLUSTER: RefCell<Option<Cluster>> = const { RefCell::new(None) };
}

/// Joins the MPI run when a launcher started this process with more than one rank; the
/// cluster then lives until [`leave`]. A single rank runs as a plain process.
pub fn join() -> Result<()> {
    if crate::ranks::launched_ranks().is_none_or(|n| n < 2) {
        return Ok(());
    }
    // The links of a fine scheme make their MPI calls on a thread of their own.
    let (universe, threading) =
        mpi::initialize_with_threading(Threading::Multiple).context("MPI was already initialised in this process")?;
    let world = universe.world();
    if world.size() < 2 {
        return Ok(());
    }
    let mut name = [0u8; HOST_BYTES];
    let host = mpi::environment::processor_name().unwrap_or_else(|_| "unknown host".into());
    let cut = host.len().min(HOST_BYTES);
    name[..cut].copy_from_slice(&host.as_bytes()[..cut]);
    let mut names = vec![0u8; HOST_BYTES * world.size() as usize];
    world.all_gather_into(&name[..], &mut names[..]);
    let hosts = names
        .chunks_exact(HOST_BYTES)
        .map(|n| String::from_utf8_lossy(&n[..n.iter().position(|&b| b == 0).unwrap_or(HOST_BYTES)]).into_owned())
        .collect();
    let rank = world.rank() as usize;
    if rank != 0 {
        crate::ranks::set_silent_rank();
    }
    // A collective: every rank makes it here, whatever its scheme.
    let links = RefCell::new(Some(world.duplicate()));
    let threads_allowed = threading == Threading::Multiple;
    CLUSTER
        .with(|c| *c.borrow_mut() = Some(Cluster { links, _universe: universe, world, rank, hosts, threads_allowed }));
    Ok(())
}

/// Runs `f` with this process's cluster (None: one process).
pub fn with_cluster<T>(f: impl FnOnce(Option<&Cluster>) -> T) -> T {
    CLUSTER.with(|c| f(c.borrow().as_ref()))
}

/// Ends this rank's part in the run before the process exits with `code`: a success finalises
/// MPI (waiting for the other ranks to finish theirs); a failure on rank 0, whose message is
/// already printed and whose staged outputs are removed, aborts every rank, since the others
/// may be waiting for it or hanging.
pub fn leave(code: i32) {
    let cluster = CLUSTER.with(|c| c.borrow_mut().take());
    if let Some(cluster) = cluster
        && code != 0
        && cluster.rank == 0
    {
        cluster.world.abort(code);
    }
}

/// A failure rank 0 already knows of: the rank that failed prints nothing and exits 1.
#[derive(Debug)]
pub struct Reported;

impl std::fmt::Display for Reported {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("this rank's failure was reported to rank 0")
    }
}

impl std::error::Error for Reported {}

impl Cluster {
    pub fn size(&self) -> usize {
        self.hosts.len()
    }

    /// Every rank's device count, gathered (a collective: every rank calls it once, before any
    /// work).
    pub fn layout(&self, own_devices: u32) -> RankLayout {
        let mut devices = vec![0u32; self.size()];
        self.world.all_gather_into(&own_devices, &mut devices[..]);
        RankLayout { devices }
    }

    /// Who a message names: `rank 2 on host node3`.
    pub fn who(&self, rank: usize) -> String {
        format!("rank {rank} on host {}", self.hosts[rank])
    }

    /// Rank 0: sends every other rank the run's frames.
    pub fn send_frames(&self, frames: &serde_json::Value) {
        let bytes = serde_json::to_vec(frames).expect("JSON of plain values");
        for r in 1..self.size() {
            self.world.process_at_rank(r as i32).send_with_tag(&bytes[..], TAG_FRAMES);
        }
    }

    /// Rank r > 0: the run's frames, from rank 0 (which is alive, or mpirun ends this rank too).
    pub fn receive_frames(&self) -> Result<serde_json::Value> {
        let (bytes, _) = self.world.process_at_rank(0).receive_vec_with_tag::<u8>(TAG_FRAMES);
        serde_json::from_slice(&bytes).context("rank 0's frames are not JSON")
    }

    /// Rank r > 0: frame `frame` is done (a small message, sent eagerly).
    pub fn send_frame_done(&self, stat: &FrameStat) {
        let bytes = serde_json::to_vec(stat).expect("JSON of plain values");
        self.world.process_at_rank(0).send_with_tag(&bytes[..], TAG_FRAME);
    }

    /// Rank r > 0: the finished views and statistics.
    pub fn send_done(&self, header: &serde_json::Value, blobs: &[Vec<u8>]) {
        let message = encode(header, blobs);
        let zero = self.world.process_at_rank(0);
        zero.send_with_tag(&(message.len() as u64).to_le_bytes()[..], TAG_DONE);
        for part in message.chunks(PART_BYTES) {
            zero.send_with_tag(part, TAG_PART);
        }
    }

    /// Rank r > 0: why it stopped.
    pub fn send_failed(&self, cause: &str) {
        self.world.process_at_rank(0).send_with_tag(cause.as_bytes(), TAG_FAILED);
    }
}

/// rank r → rank s: a chunk of a link between their devices, on the links' communicator: the
/// chunk's [`ChunkKey`] (3 × u32 LE), then its bytes.
const TAG_CHUNK: i32 = 20;

/// How long the link thread sleeps when it has nothing to do.
const LINK_IDLE: Duration = Duration::from_micros(200);

/// What names the messages of one remote copy on both ranks: its producer and consumer by the
/// run's device numbers, and its place among the copies between them ([`Wire::copy`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct ChunkKey {
    from: u32,
    to: u32,
    copy: u32,
}

enum LinkCommand {
    Send { to_rank: usize, key: ChunkKey, bytes: Vec<u8> },
    Receive { from_rank: usize, key: ChunkKey, reply: Sender<std::result::Result<Vec<u8>, String>> },
}

/// The links between this rank's devices and other ranks' ([`parallax_backend::RemoteTransport`]):
/// one thread makes every MPI call for them, on a communicator of their own, without ever
/// blocking: sends are non-blocking (MPI_Isend), arrivals are taken by matched probes
/// (MPI_Improbe) in whatever order they come and handed to the receive that waits for their
/// key, so no order of sends and receives between ranks can deadlock. The chunks of one copy
/// arrive in the order they were sent (MPI's messages from one rank do not overtake each
/// other), frame after frame. A receive that waits while its rank has sent nothing for
/// `--rank-timeout` fails naming the rank.
pub struct LinkTransport {
    layout: crate::ranks::RankLayout,
    rank: usize,
    commands: Mutex<Option<Sender<LinkCommand>>>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl std::fmt::Debug for LinkTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LinkTransport(rank {})", self.rank)
    }
}

/// The links' communicator, moved to their thread, the one thread that uses it.
struct LinkComm(SimpleCommunicator);

// SAFETY: MPI runs with MPI_THREAD_MULTIPLE (checked before the thread starts), and only the
// link thread uses this communicator.
unsafe impl Send for LinkComm {}

impl LinkTransport {
    /// Starts the link thread of this rank (at most once a run).
    pub fn start(cluster: &Cluster, layout: &crate::ranks::RankLayout, timeout: Duration) -> Result<Arc<Self>> {
        if !cluster.threads_allowed {
            bail!(
                "this MPI library does not offer MPI_THREAD_MULTIPLE, which the links of a fine scheme between ranks \
                 need: use --scheme multi-source, or an MPI built with thread support (Debian's OpenMPI has it)"
            );
        }
        let comm = cluster.links.borrow_mut().take().context("the links between ranks were started twice")?;
        let (sender, commands) = channel();
        let (comm, hosts) = (LinkComm(comm), cluster.hosts.clone());
        let thread = std::thread::Builder::new()
            .name("parallax-mpi-links".into())
            .spawn(move || serve_links(comm, &commands, &hosts, timeout))
            .context("starting the thread of the links between ranks")?;
        Ok(Arc::new(LinkTransport {
            layout: layout.clone(),
            rank: cluster.rank,
            commands: Mutex::new(Some(sender)),
            thread: Mutex::new(Some(thread)),
        }))
    }

    fn command(&self, command: LinkCommand) -> std::result::Result<(), String> {
        let commands = self.commands.lock().unwrap_or_else(|p| p.into_inner());
        commands.as_ref().and_then(|c| c.send(command).ok()).ok_or_else(|| "the links between ranks stopped".into())
    }

    /// The run's number of this rank's device `local`.
    fn global(&self, local: usize) -> u32 {
        self.layout.first(self.rank) + local as u32
    }
}

impl RemoteTransport for LinkTransport {
    fn send(&self, wire: Wire, bytes: Vec<u8>) -> std::result::Result<(), String> {
        let key = ChunkKey { from: self.global(wire.local), to: wire.remote, copy: wire.copy };
        self.command(LinkCommand::Send { to_rank: self.layout.rank_of(wire.remote), key, bytes })
    }

    /// The length is the backend's to check: a chunk arrives whole, as sent.
    fn receive(&self, wire: Wire, _bytes: usize) -> Receiver<std::result::Result<Vec<u8>, String>> {
        let key = ChunkKey { from: wire.remote, to: self.global(wire.local), copy: wire.copy };
        let (reply, received) = channel();
        let from_rank = self.layout.rank_of(wire.remote);
        if let Err(e) = self.command(LinkCommand::Receive { from_rank, key, reply: reply.clone() }) {
            let _ = reply.send(Err(e));
        }
        received
    }
}

impl Drop for LinkTransport {
    /// Ends the link thread once its sends are delivered (every rank receives all it is sent).
    fn drop(&mut self) {
        self.commands.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(thread) = self.thread.lock().unwrap_or_else(|p| p.into_inner()).take() {
            let _ = thread.join();
        }
    }
}

/// A send in flight: its request and the bytes it owns until MPI is done with them.
struct Sending {
    request: Request<'static, [u8], StaticScope>,
    bytes: *mut [u8],
}

/// The link thread: takes commands, progresses sends, takes arrivals, answers receives, and
/// fails receives from ranks silent for `timeout`; ends when the transport is dropped and every
/// send is delivered (or after `timeout` without progress: a rank that died takes nothing).
fn serve_links(comm: LinkComm, commands: &Receiver<LinkCommand>, hosts: &[String], timeout: Duration) {
    let comm = comm.0;
    let mut sending: Vec<Sending> = Vec::new();
    let mut arrived: HashMap<ChunkKey, VecDeque<Vec<u8>>> = HashMap::new();
    type Reply = Sender<std::result::Result<Vec<u8>, String>>;
    let mut waiting: HashMap<ChunkKey, VecDeque<(usize, Reply, Instant)>> = HashMap::new();
    let mut last_heard = vec![Instant::now(); hosts.len()];
    let mut open = true;
    let mut idle_since = Instant::now();
    loop {
        let mut busy = false;
        while open {
            match commands.try_recv() {
                Ok(LinkCommand::Send { to_rank, key, bytes }) => {
                    let mut message = Vec::with_capacity(12 + bytes.len());
                    for word in [key.from, key.to, key.copy] {
                        message.extend_from_slice(&word.to_le_bytes());
                    }
                    message.extend_from_slice(&bytes);
                    let bytes: &'static mut [u8] = Box::leak(message.into_boxed_slice());
                    let owned: *mut [u8] = bytes;
                    // SAFETY: the bytes stay alive (leaked) until the request completes below.
                    let request = comm.process_at_rank(to_rank as i32).immediate_send_with_tag(
                        StaticScope,
                        unsafe { &*owned },
                        TAG_CHUNK,
                    );
                    sending.push(Sending { request, bytes: owned });
                    busy = true;
                }
                Ok(LinkCommand::Receive { from_rank, key, reply }) => {
                    waiting.entry(key).or_default().push_back((from_rank, reply, Instant::now()));
                    busy = true;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => open = false,
            }
        }
        let mut still = Vec::with_capacity(sending.len());
        for s in sending.drain(..) {
            match s.request.test() {
                Ok(_) => {
                    // SAFETY: MPI is done with the bytes; they were leaked from this box.
                    drop(unsafe { Box::from_raw(s.bytes) });
                    busy = true;
                }
                Err(request) => still.push(Sending { request, ..s }),
            }
        }
        sending = still;
        while let Some(probed) = comm.any_process().immediate_matched_probe_with_tag(TAG_CHUNK) {
            let rank = probed.1.source_rank() as usize;
            let (mut message, _) = probed.matched_receive_vec::<u8>();
            last_heard[rank] = Instant::now();
            if message.len() < 12 {
                continue;
            }
            let word = |i: usize| u32::from_le_bytes(message[4 * i..4 * i + 4].try_into().expect("4 bytes"));
            let key = ChunkKey { from: word(0), to: word(1), copy: word(2) };
            // The chunk's bytes, moved down over the key in place: no second allocation.
            message.drain(..12);
            arrived.entry(key).or_default().push_back(message);
            busy = true;
        }
        for (key, queue) in &mut waiting {
            while let Some(bytes) = queue.front().and_then(|_| arrived.get_mut(key)?.pop_front()) {
                let (_, reply, _) = queue.pop_front().expect("a receive waits");
                let _ = reply.send(Ok(bytes));
            }
            for (rank, reply, since) in queue.iter() {
                if last_heard[*rank].max(*since).elapsed() > timeout {
                    let _ = reply.send(Err(format!(
                        "rank {rank} on host {} sent nothing for {} s (--rank-timeout): it hangs or died; raise \
                         --rank-timeout if its frames are that slow",
                        hosts[*rank],
                        timeout.as_secs()
                    )));
                }
            }
            queue.retain(|(rank, _, since)| last_heard[*rank].max(*since).elapsed() <= timeout);
        }
        waiting.retain(|_, queue| !queue.is_empty());
        if busy {
            idle_since = Instant::now();
        } else if !open && (sending.is_empty() || idle_since.elapsed() > timeout) {
            // Sends nobody takes (a rank died) are left to MPI: their bytes are not freed.
            sending.drain(..).for_each(|s| std::mem::forget(s.request));
            return;
        } else {
            std::thread::sleep(LINK_IDLE);
        }
    }
}

/// One frame of one rank, as it reports it.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FrameStat {
    pub frame: u32,
    /// Host wall time of the frame's preparation and submission, milliseconds.
    pub wall_ms: f64,
}

/// What rank 0 got from another rank at the end: its header and blobs, and the bytes received.
pub struct Finished {
    pub header: serde_json::Value,
    pub blobs: Vec<Vec<u8>>,
    pub bytes: usize,
}

/// Rank 0's view of the other ranks: what each sent, and when it was last heard of.
pub struct Collector {
    timeout: Duration,
    last_heard: Vec<Instant>,
    pub frames: Vec<Vec<FrameStat>>,
    /// Per rank, the bytes of its finished views as they arrive and their announced length.
    arriving: Vec<Option<(Vec<u8>, usize)>>,
    finished: Vec<Option<Finished>>,
}

impl Collector {
    pub fn new(ranks: usize, timeout: Duration) -> Collector {
        Collector {
            timeout,
            last_heard: vec![Instant::now(); ranks],
            frames: vec![Vec::new(); ranks],
            arriving: vec![None; ranks],
            finished: (0..ranks).map(|_| None).collect(),
        }
    }

    /// Takes every message already there, without waiting; a rank's failure is the run's.
    pub fn poll(&mut self, cluster: &Cluster) -> Result<()> {
        while let Some(probed) = cluster.world.any_process().immediate_matched_probe() {
            let (rank, tag) = (probed.1.source_rank() as usize, probed.1.tag());
            let (bytes, _) = probed.matched_receive_vec::<u8>();
            self.last_heard[rank] = Instant::now();
            match tag {
                TAG_FRAME => {
                    self.frames[rank].push(serde_json::from_slice(&bytes).context("a rank's frame is not JSON")?)
                }
                TAG_DONE => {
                    let length = u64::from_le_bytes(bytes[..].try_into().context("a rank's length is 8 bytes")?);
                    self.arriving[rank] = Some((Vec::new(), length as usize));
                }
                TAG_PART => {
                    let Some((message, length)) = self.arriving[rank].as_mut() else {
                        bail!("{} sent views before their length", cluster.who(rank));
                    };
                    message.extend_from_slice(&bytes);
                    if message.len() >= *length {
                        let (header, blobs) = decode(message)?;
                        self.finished[rank] = Some(Finished { header, blobs, bytes: message.len() });
                        self.arriving[rank] = None;
                    }
                }
                TAG_FAILED => bail!("{} failed: {}", cluster.who(rank), String::from_utf8_lossy(&bytes)),
                tag => bail!("{} sent a message of unknown tag {tag}", cluster.who(rank)),
            }
        }
        Ok(())
    }

    /// Waits, polling, until every other rank has finished; a rank silent for the timeout ends
    /// the run.
    pub fn wait_all(&mut self, cluster: &Cluster) -> Result<Vec<Finished>> {
        loop {
            self.poll(cluster)?;
            let waiting: Vec<usize> = (1..cluster.size()).filter(|&r| self.finished[r].is_none()).collect();
            if waiting.is_empty() {
                return Ok(self.finished.drain(1..).map(|f| f.expect("every rank finished")).collect());
            }
            let silent: Vec<String> = waiting
                .iter()
                .filter(|&&r| self.last_heard[r].elapsed() > self.timeout)
                .map(|&r| cluster.who(r))
                .collect();
            if !silent.is_empty() {
                bail!(
                    "{} sent nothing for {} s (--rank-timeout): it hangs or died; raise --rank-timeout if its frames \
                     are that slow",
                    silent.join(", "),
                    self.timeout.as_secs()
                );
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

/// `header` as JSON with the blobs' lengths, then the blobs: [u64 LE header length][header][blobs].
fn encode(header: &serde_json::Value, blobs: &[Vec<u8>]) -> Vec<u8> {
    let lengths: Vec<usize> = blobs.iter().map(Vec::len).collect();
    let head = serde_json::to_vec(&serde_json::json!({ "header": header, "lengths": lengths })).expect("plain JSON");
    let mut out = Vec::with_capacity(8 + head.len() + lengths.iter().sum::<usize>());
    out.extend_from_slice(&(head.len() as u64).to_le_bytes());
    out.extend_from_slice(&head);
    blobs.iter().for_each(|b| out.extend_from_slice(b));
    out
}

fn decode(bytes: &[u8]) -> Result<(serde_json::Value, Vec<Vec<u8>>)> {
    let broken = || anyhow::anyhow!("a rank's views arrived truncated");
    let length = u64::from_le_bytes(bytes.get(..8).ok_or_else(broken)?.try_into()?) as usize;
    let head: serde_json::Value = serde_json::from_slice(bytes.get(8..8 + length).ok_or_else(broken)?)?;
    let lengths: Vec<usize> = serde_json::from_value(head["lengths"].clone())?;
    let mut at = 8 + length;
    let mut blobs = Vec::with_capacity(lengths.len());
    for l in lengths {
        blobs.push(bytes.get(at..at + l).ok_or_else(broken)?.to_vec());
        at += l;
    }
    Ok((head["header"].clone(), blobs))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_message_decodes_to_what_was_encoded() {
        let header = serde_json::json!({ "host": "a", "views": [[1, 3]] });
        let blobs = vec![vec![1u8, 2, 3], Vec::new(), vec![9u8; 100]];
        let (h, b) = decode(&encode(&header, &blobs)).unwrap();
        assert_eq!((&h, &b), (&header, &blobs));
        assert_eq!(decode(&encode(&header, &blobs)[..20]).unwrap_err().to_string(), "a rank's views arrived truncated");
    }
}
