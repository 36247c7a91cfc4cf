//! Error types. Each variant names the input at fault and, through its message, the fix.

use std::panic::Location;

use thiserror::Error;

use crate::ids::{AllocId, BatchId, CopyId, DeviceId, FamilyId, InstanceId, Op, PassId, Region, ResourceId, ViewId};
use crate::scope::SlotAccess;

/// Bad planning input: layouts, device counts, source lists, strategy names.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum PartitionError {
    #[error("--lf '{0}' is not a layout: use multiscopic, nelf or WxH (e.g. 8x4)")]
    BadLayout(String),
    #[error("--lf {cols}x{rows} has no views: both grid dimensions must be at least 1")]
    EmptyLayout { cols: u32, rows: u32 },
    #[error("--spacing {0} is invalid: use a finite, non-negative distance in metres (e.g. 0.001)")]
    BadSpacing(f64),
    #[error("--resolution {width}x{height} is invalid: both dimensions must be at least 1")]
    BadResolution { width: u32, height: u32 },
    #[error("focus distance {0} is invalid: use a finite distance greater than 0")]
    BadFocus(f64),
    #[error("--gpus 0: at least one device is needed")]
    NoDevices,
    #[error(
        "--gpus/--fake-devices {devices} exceeds the {views} views: the paper excludes N > M (a view would be split over devices); use at most {views} devices"
    )]
    MoreDevicesThanViews { devices: u32, views: u32 },
    #[error("--sources: view {view} is out of range, the light field has {views} views (0..{views})")]
    SourceOutOfRange { view: u32, views: u32 },
    #[error("--sources: view {0} is listed twice; list each source once")]
    DuplicateSource(u32),
    #[error("--sources is empty: list at least one view index")]
    NoSources,
    #[error("--sources '{0}' is not a list of view indices (e.g. 0,99)")]
    BadSourceList(String),
    #[error("--sources lists {sources} views but there are {views}: keep at least one target view")]
    AllViewsSources { sources: u32, views: u32 },
    #[error(
        "--sources does not apply to multi-source: it picks one medoid per set; use it with fine-sources or fine-all"
    )]
    SourcesWithMultiSource,
    #[error(
        "--sources-per-set {per_set} is more than the {smallest} views of the smallest set: use at most {smallest}, or fewer devices"
    )]
    TooManySourcesPerSet { per_set: u32, smallest: u32 },
    #[error("--sources-per-set 0: every set needs at least one source")]
    NoSourcesPerSet,
    #[error("--sources-per-set applies to multi-source only: the fine schemes take --sources")]
    SourcesPerSetWithFineScheme,
    #[error("unknown scheme '{0}': use multi-source, fine-sources or fine-all")]
    UnknownScheme(String),
    #[error("unknown assignment '{0}': use round-robin, contiguous or compact")]
    UnknownAssignment(String),
}

/// Errors found while declaring or compiling a render graph. Locations are where the offending
/// pass or resource was declared (`#[track_caller]`).
#[derive(Clone, Debug, Error, PartialEq)]
pub enum GraphError {
    #[error(
        "pass '{pass}' (declared at {at}) reads '{resource}' of {view} at version {version}, which no pass writes: declare a producer first or import the resource"
    )]
    ReadOfUnwritten { pass: String, resource: String, view: ViewId, version: u32, at: &'static Location<'static> },
    #[error(
        "'{resource}' of {view} is exported (at {at}) but no pass writes it: export a handle after the pass that produces it"
    )]
    ExportOfUnwritten { resource: String, view: ViewId, at: &'static Location<'static> },
    #[error(
        "'{resource}' of {view} version {version} is written by both '{first}' and '{second}' (declared at {at}): write through a `&mut` handle so each write makes a new version"
    )]
    DoubleWrite {
        resource: String,
        view: ViewId,
        version: u32,
        first: String,
        second: String,
        at: &'static Location<'static>,
    },
    #[error(
        "the passes {passes:?} depend on each other in a cycle: a pass reads a version that only a later pass produces"
    )]
    Cycle { passes: Vec<String> },
    #[error("pass '{pass}' (declared at {at}) uses handle {family} from another graph")]
    ForeignHandle { pass: String, family: FamilyId, at: &'static Location<'static> },
    #[error(
        "pass '{pass}' reads the history of '{resource}' of {view} on {reader}, but its last writer runs on {writer}: history must stay on the device that wrote it"
    )]
    HistoryAcrossDevices { pass: String, resource: String, view: ViewId, reader: u32, writer: u32 },
    #[error(
        "resource '{name}' is declared twice (first at {first}, again at {at}): give each resource its own name, kernels and reports tell resources apart by it"
    )]
    DuplicateResource { name: String, first: &'static Location<'static>, at: &'static Location<'static> },
    #[error(
        "pass '{pass}' (declared at {at}) declares the {access} of '{slot}' twice: declare each access once, the kernel binds it through one slot"
    )]
    DuplicateSlot { pass: String, slot: String, access: SlotAccess, at: &'static Location<'static> },
    #[error(
        "pass '{pass}' (declared at {at}) reads {}'{resource}' as {scope}: a per-view pass reads a global resource whole (read, read_whole), a global pass reads per-view resources with read_every_view and global ones with read or read_history",
        kind_of(.global)
    )]
    ReadScope { pass: String, resource: String, global: bool, scope: String, at: &'static Location<'static> },
    #[error(
        "pass '{pass}' (declared at {at}) writes {}'{resource}': a global resource is written only by a global pass (Graph::global_pass), which writes only global resources",
        kind_of(.global)
    )]
    WriteScope { pass: String, resource: String, global: bool, at: &'static Location<'static> },
    #[error("the graph has no roots: export a resource or mark a pass side_effect(), otherwise every pass is culled")]
    NoRoots,
    #[error(
        "internal error: compiling gave a schedule that does not validate ({0}); this is a bug of the compiler, please report it with the command that gave it"
    )]
    Unsound(ValidationReport),
}

/// "global " or "per-view ", as the scope errors name a resource.
fn kind_of(global: &bool) -> &'static str {
    if *global { "global " } else { "per-view " }
}

/// A kernel asked a pass instance for a slot token of another pass: kernels bind only the
/// slots their own pass declared (`PassInstance::read`, `sources`, `history_read`, `write`).
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error(
    "pass `{pass}`'s kernel binds {slot}, which its pass did not declare: use the slot tokens returned where `{pass}` is declared"
)]
pub struct UnboundSlot {
    /// The instance's pass.
    pub pass: String,
    /// The token asked for (its `Debug` form: kind, declaring pass, index).
    pub slot: String,
}

/// One broken invariant.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ScheduleError {
    #[error("pass instance {instance} is on no device program")]
    InstanceNotScheduled { instance: InstanceId },
    #[error("pass instance {instance} appears more than once")]
    InstanceScheduledTwice { instance: InstanceId },
    #[error("pass instance {instance} was placed on {placed} but is listed on {listed}")]
    InstanceOnWrongDevice { instance: InstanceId, placed: DeviceId, listed: DeviceId },
    #[error("copy {copy} joins a device to itself")]
    CopyWithinDevice { copy: CopyId },
    #[error("copy {copy}: its {op} op is missing from the device it belongs on")]
    CopyOpMissing { copy: CopyId, op: &'static str },
    #[error("copy {copy}: its {op} op appears more than once")]
    CopyOpDuplicated { copy: CopyId, op: &'static str },
    #[error("copy {copy}: Signal before CopyOut, or CopyIn before Wait")]
    CopyOpsOutOfOrder { copy: CopyId },
    #[error("copy {copy}: no instance on the source device writes the copied rows of that version")]
    CopyWithoutProducer { copy: CopyId },
    #[error("copy {copy} leaves before its producer {producer} has run")]
    CopyBeforeProducer { copy: CopyId, producer: InstanceId },
    #[error("copy {copy} moves {actual} bytes; its rows hold {expected}")]
    CopyBytesMismatch { copy: CopyId, expected: u64, actual: u64 },
    #[error("{instance} reads {resource} version {version} ({rows}) that no earlier producer or copy provides")]
    UnsatisfiedRead { instance: InstanceId, resource: ResourceId, version: u32, rows: Region },
    #[error("{instance} reads {resource} version {version} through more than one copy: {copies:?}")]
    AmbiguousRead { instance: InstanceId, resource: ResourceId, version: u32, copies: Vec<CopyId> },
    #[error("producer {producer} runs after its consumer {consumer} on the same device")]
    OrderViolation { producer: InstanceId, consumer: InstanceId },
    #[error("copy {copy} arrives after its consumer {consumer} runs")]
    CopyArrivesLate { copy: CopyId, consumer: InstanceId },
    #[error("view {view}: the finished rows of {resource} are not all on device 0 at the end of the frame")]
    ViewNotGathered { view: ViewId, resource: ResourceId },
    #[error("{device} waits forever at {op:?}: waits and signals form a cycle across devices")]
    Deadlock { device: DeviceId, op: Op },
    #[error("{device}: {op:?} touches what {after:?} touched since the last barrier, with no barrier between them")]
    MissingBarrier { device: DeviceId, op: Op, after: Op },
    #[error("{device}: {op:?}, its first op that touches memory, has no barrier after the previous frame's ops")]
    NoBarrierAfterLastFrame { device: DeviceId, op: Op },
    #[error("{device}: barrier before op {index}, but the program has {ops} ops")]
    BarrierOutOfRange { device: DeviceId, index: u32, ops: usize },
    #[error("{device}: its barriers are not listed in increasing op order")]
    BarriersOutOfOrder { device: DeviceId },
    #[error("{what} {index} refers to a missing {missing} {target}")]
    Dangling { what: &'static str, index: u32, missing: &'static str, target: u32 },
    #[error(
        "{instance}: access to {resource} version {version} uses allocation {alloc}, which is not on its device or not of that resource and version"
    )]
    AllocationMismatch { instance: InstanceId, resource: ResourceId, version: u32, alloc: AllocId },
    #[error(
        "copy {copy}: its source or destination allocation is not on its device or not of that resource and version"
    )]
    CopyAllocationMismatch { copy: CopyId },
    #[error("{instance} reads and writes allocation {alloc} without declaring the write in place")]
    UndeclaredInPlace { instance: InstanceId, alloc: AllocId },
    #[error(
        "{instance} writes version {version} of {resource} in place into allocation {written}, not into {read}, which holds the version it replaces"
    )]
    InPlaceElsewhere { instance: InstanceId, resource: ResourceId, version: u32, read: AllocId, written: AllocId },
    #[error(
        "allocation {alloc} on {device}: {later:?} touches version {later_version} after {earlier:?} wrote version {earlier_version} there"
    )]
    AllocationHazard {
        alloc: AllocId,
        device: DeviceId,
        earlier: Op,
        earlier_version: u32,
        later: Op,
        later_version: u32,
    },
    #[error(
        "{instance} reads history of {resource} from allocation {alloc}, which is not storage of that resource on its own device"
    )]
    HistoryOnOtherDevice { instance: InstanceId, resource: ResourceId, alloc: AllocId },
    #[error(
        "{instance} reads history of {resource} from allocation {alloc}, which is not the previous half of a history pair"
    )]
    HistoryReadOutsidePair { instance: InstanceId, resource: ResourceId, alloc: AllocId },
    #[error(
        "{instance} reads history of {resource} version {version}, which the current half {current} of its pair does not hold"
    )]
    HistoryVersionNotCurrent { instance: InstanceId, resource: ResourceId, version: u32, current: AllocId },
    #[error("history pair {pair}: its current and previous halves are one allocation, {alloc}")]
    HistoryHalvesAlias { pair: u32, alloc: AllocId },
    #[error("history pair {pair}: halves {current} and {previous} are not storage of one resource on one device")]
    HistoryHalvesDiffer { pair: u32, current: AllocId, previous: AllocId },
    #[error("allocation {alloc} is a half of more than one history pair")]
    HistoryHalfShared { alloc: AllocId },
    #[error(
        "allocation {alloc}, the previous half of a history pair, holds versions {versions:?} of the frame: it holds only last frame's"
    )]
    PreviousHalfHoldsVersions { alloc: AllocId, versions: Vec<u32> },
    #[error("{op:?} touches allocation {alloc}, the previous half of a history pair: only history reads may see it")]
    PreviousHalfTouched { alloc: AllocId, op: Op },
    #[error("{resource} has no texels or bytes")]
    EmptyResource { resource: ResourceId },
    #[error("{what} {index}: rows {rows} are empty or outside the {height} rows of {resource}")]
    RowsOutsideResource { what: &'static str, index: u32, resource: ResourceId, rows: Region, height: u32 },
    #[error("the instances of {pass} for view {view} do not tile its rows exactly (rows 0..{height})")]
    BandsDoNotTile { pass: PassId, view: ViewId, height: u32 },
    #[error("{instance} writes global resource {resource} but its pass runs per view, not as a global pass")]
    GlobalWrittenPerView { instance: InstanceId, resource: ResourceId },
    #[error("{instance} touches rows {rows} of global resource {resource}, not all of it")]
    GlobalAccessedInPart { instance: InstanceId, resource: ResourceId, rows: Region },
    #[error("global pass {pass} has {instances} instances; a global pass runs once per frame")]
    GlobalPassInstances { pass: PassId, instances: u32 },
    #[error("copy {copy} is in {batches} batches; a dependency copy is in one, a gather in none")]
    CopyBatchCount { copy: CopyId, batches: u32 },
    #[error("batch {batch} holds copy {copy}, a gather or a copy between other devices")]
    BatchForeignCopy { batch: BatchId, copy: CopyId },
    #[error("batch {batch} says it moves {actual} bytes; its copies move {expected}")]
    BatchBytesMismatch { batch: BatchId, expected: u64, actual: u64 },
    #[error("batch {batch}: its copy ops on {device} are split by a pass or a copy the other way")]
    BatchSplit { batch: BatchId, device: DeviceId },
    #[error("batch {batch}: copies {first} and {second} write the same rows of one allocation")]
    BatchRegionsOverlap { batch: BatchId, first: CopyId, second: CopyId },
    #[error("copy {copy} moves {copied}, but its consumers read {read} of the producer's rows")]
    CopyRowsUnread { copy: CopyId, read: Region, copied: Region },
}

/// Every broken invariant found; empty when the schedule is sound.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ValidationReport {
    pub errors: Vec<ScheduleError>,
}

impl ValidationReport {
    pub fn is_ok(&self) -> bool {
        self.errors.is_empty()
    }
}

impl std::fmt::Display for ValidationReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.errors.first() {
            None => write!(f, "the schedule breaks no invariant"),
            Some(first) => write!(f, "the schedule breaks {} invariant(s), first: {first}", self.errors.len()),
        }
    }
}

impl std::error::Error for ValidationReport {}
