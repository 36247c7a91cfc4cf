//! Error types. Each variant names the input at fault and, through its message, the fix.

use std::panic::Location;

use thiserror::Error;

use crate::builder::SlotAccess;
use crate::ids::{FamilyId, ViewId};

/// Bad planning input: layouts, device counts, source lists, strategy names.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum PlanError {
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
    Unsound(crate::validate::ValidationReport),
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
