//! Executor settings: frames in flight, copy chunking and queues, barrier placement, timing
//! granularity, readback, external shaders and deliberate faults.
//!
//! Not a leaf: it names what it configures (the shader library, a plan's copy ids, the link
//! kinds, the remote transport), but none of the modules that read these settings (the
//! executor, its device state, the recording), so those can import it.

use crate::shaders::ShaderLibrary;

/// Deliberate faults, for tests that must show the synchronisation is really needed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultInjection {
    /// The consumer of `copy` does not wait for it. To make the resulting race lose every
    /// time instead of now and then, the producer device is held back (by a host-signalled
    /// semaphore) until the consumer has executed the copy-in; the copy-in then reads the
    /// zero-initialised staging memory. Only possible when nothing the consumer does up to
    /// that copy-in waits for another copy.
    DropCrossDeviceWait { copy: crate::plan::CopyId },
    /// Submitting frame `frame` fails as on a lost device ([`BackendError::DeviceLost`]) before
    /// its last run of segments, so the rest of its segments are on the queues: what every
    /// caller must end cleanly from (one error, no hang, nothing half-written).
    LoseDevice { frame: u64 },
}

/// Executor settings.
#[derive(Clone, Debug)]
pub struct ExecOptions {
    /// Frames submitted before the host waits for the oldest (at least 1).
    pub frames_in_flight: usize,
    /// Copies larger than this are split into row bands submitted separately, so that the
    /// consumer's upload of one band overlaps the producer's download of the next. The schedule
    /// batches the copies that fit one chunk (`parallax_graph::Batching::SmallCopies`, whose
    /// default is this default): compile with the same size when changing it.
    pub chunk_bytes: u64,
    /// Submit copies to a transfer-only queue (a GPU's copy engines) where the device has one.
    /// Copies then form submissions of their own, ordered against the passes through the
    /// device's progress timeline. On a device without such a queue the same submissions go to
    /// the main queue (which is how lavapipe tests this path). On by default: on two H200s the
    /// copy engines let download and upload overlap (38 GB/s end to end against 23 GB/s on the
    /// main queue, docs/RESULTS.md).
    pub separate_copy_queue: bool,
    /// Capacity of the per-frame data buffer ([`Executor::set_frame_data`]).
    pub frame_data_bytes: u64,
    /// Copy the plan's exported resources to host memory at the end of every frame, for
    /// [`Executor::submit_frame`]. Off by default: it costs a host-visible copy of every export
    /// per frame in flight and a device→host copy per frame, which callers that read results
    /// once with [`Executor::read_resource`] do not need.
    pub read_back_exports: bool,
    pub fault: Option<FaultInjection>,
    /// SPIR-V of the plan's kernels, by the name they dispatch: the crates' libraries layered
    /// over one another (a user's over `parallax_passes::shader_library()`, which the passes'
    /// runners layer beneath it themselves), then the backend's own shaders.
    pub shaders: ShaderLibrary,
    /// Most segments (submissions) of one device the host keeps submitted and not yet done; the
    /// host waits for the device before submitting more (at least 1). Drivers hold a bounded
    /// number of pending submissions and block vkQueueSubmit beyond it; the fine schemes cut a
    /// frame into hundreds of segments per device (a few per stage once small copies are batched).
    pub max_queued_segments: usize,
    /// Where the recorded command buffers put barriers between ops.
    pub barriers: Barriers,
    /// What each GPU timestamp pair covers.
    pub timing: Timing,
    /// The kind of every link between two devices (links.rs): `None` takes the best each pair
    /// offers; a kind some pair cannot use makes `Executor::new` fail with
    /// `BackendError::LinkUnavailable` naming the pair and what it lacks.
    pub link: Option<crate::links::LinkKind>,
    /// Host staging memory of `relay` links over every link and frame slot: each link's copies
    /// take turns in a ring of its share (at least its largest copy; larger where a smaller
    /// ring would make the devices wait on each other in a cycle), see staging_ring.rs.
    pub host_staging_bytes: u64,
    /// Moves the chunks of copies to and from devices of other processes (remote.rs): needed
    /// by a plan that names such devices.
    pub remote: Option<std::sync::Arc<dyn crate::remote::RemoteTransport>>,
}

/// Where barriers go between the ops of a device (record.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Barriers {
    /// Before every op: always right, and what synchronisation validation can check. (A group
    /// of instances that a kernel records together is one op; groups end at the plan's
    /// barriers, so a hand-laid plan with such a kernel states its barriers too:
    /// `ExecutionPlan::place_barriers`.)
    #[default]
    EveryOp,
    /// Where the compiled schedule put one (`parallax_graph::DeviceProgram::barriers`: an op
    /// touches what an op since the last barrier touched), at the start of each submission, and
    /// around kernels that touch undeclared memory, so instances of one pass for many views
    /// overlap on the GPU. A hand-laid plan states its barriers (`ExecutionPlan::place_barriers`). Synchronisation
    /// validation reports false hazards here: it takes every dispatch to touch the whole
    /// bindless image array.
    Tracked,
}

/// What the GPU timestamp pairs of a frame cover (record.rs). A timestamp waits for every
/// earlier command of its queue to finish (NVIDIA drains the queue for one), so timing every op
/// serialises ops that `Barriers::Tracked` would let overlap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Timing {
    /// One pair around every op: per-view figures and timelines, at the price of the overlap.
    /// Instances a kernel records as one group (`PassKernel::record_group`) are one op, timed
    /// together; the event carries the first one's view and index.
    #[default]
    PerOp,
    /// One pair around each run of consecutive instances of one pass on a queue (and around
    /// every copy): per-stage figures, and the instances of a stage overlap under tracked
    /// barriers. An event then stands for the run: its `view` and `index` are its first op's.
    PerStage,
}

impl Default for ExecOptions {
    fn default() -> Self {
        Self {
            frames_in_flight: 2,
            chunk_bytes: 8 << 20,
            separate_copy_queue: true,
            frame_data_bytes: 64 << 10,
            read_back_exports: false,
            fault: None,
            shaders: ShaderLibrary::default(),
            max_queued_segments: 256,
            barriers: Barriers::EveryOp,
            timing: Timing::PerOp,
            link: None,
            host_staging_bytes: 512 << 20,
            remote: None,
        }
    }
}
