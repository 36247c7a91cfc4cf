//! Errors of the passes crate: what the backend, the planner or the scene reported, plus the
//! inconsistencies between them that only this crate can see.

use parallax_backend::{BackendError, CompileError};

/// Errors of parallax-passes.
#[derive(Debug, thiserror::Error)]
pub enum PassError {
    #[error(transparent)]
    Backend(#[from] BackendError),

    #[error(transparent)]
    Partition(#[from] parallax_graph::PartitionError),

    #[error(transparent)]
    Graph(#[from] parallax_graph::GraphError),

    #[error(transparent)]
    Tonemap(#[from] TonemapError),

    #[error(transparent)]
    Scene(#[from] parallax_scene::SceneError),

    /// The trace parameters are indexed by view: `views[i].index` must be `i`.
    #[error("view {position} of the list has index {index}; trace parameters must list views 0, 1, 2, ... in order")]
    ViewOrder { position: usize, index: u32 },

    /// Every frame gives the parameters of every view of the plan, no more and no fewer.
    #[error("the plan has views 0..{plan_views} but a frame gave {given} views")]
    MissingViews { plan_views: u32, given: usize },

    /// A compiled trace whose outputs have no radiance image for a view.
    #[error("the compiled trace traces no radiance for view {view}: its outputs must name the image path_trace writes")]
    MissingRadiance { view: u32 },

    /// `LightFieldRenderer::trace` on a renderer that was not made from a `CompiledTrace`.
    #[error(
        "this renderer runs a plan without trace outputs: make it with LightFieldRenderer::tracing(context, compiled_trace, ...)"
    )]
    NoTraceOutputs,

    /// Nothing in the plan writes the declared resource `family` for `view`. The message leaves
    /// the family's id out: it is an index, which tells a user nothing.
    #[error(
        "no pass of the plan writes the resource read back for view {view}: read a resource the pipeline produces for that view"
    )]
    MissingOutput { family: parallax_graph::FamilyId, view: u32 },

    /// A view's size differs from its images in the plan.
    #[error("view {view} is {width}x{height} but the plan's `{name}` image is {plan_width}x{plan_height} {format}")]
    ViewSize { view: u32, name: String, width: u32, height: u32, plan_width: u32, plan_height: u32, format: String },

    /// Pixel coordinates are packed as 16 + 16 bits.
    #[error("a {width}x{height} view is beyond the 65536x65536 that packed pixel lists can address")]
    ViewTooLarge { width: u32, height: u32 },

    /// A hole fraction is a share of the view's pixels.
    #[error("hole fraction {fraction} is not in [0, 1]")]
    HoleFraction { fraction: f64 },

    /// The GPU compacted another number of holes than its mask holds: a bug in compaction.
    #[error("compaction listed {compacted} holes but the mask has {expected}")]
    HoleCount { compacted: u64, expected: u64 },
    /// A reprojection tolerance out of its range (`ReprojectionTolerances::validate`).
    #[error(
        "reprojection tolerance `{name}` is {value}: it must be a finite number (view_dependence and position \
         at least 0, normal_cos at most 1)"
    )]
    ReprojectionTolerance { name: &'static str, value: f32 },

    /// The raster camera's near plane must be a positive distance.
    #[error("raster near plane {near} must be a finite distance > 0 (scene units)")]
    NearPlane { near: f32 },

    /// More rays than the raycaster was created for.
    #[error("{rays} rays exceed the raycaster's capacity of {capacity}")]
    TooManyRays { rays: usize, capacity: usize },

    /// Two ray schedules of the `raycast` kernel returned different hits for the same rays:
    /// a bug, since each ray is traced by the same code whichever invocation takes it.
    #[error("ray schedule {schedule} returned {differing} hits that differ from schedule {reference}")]
    ScheduleChangedHits { schedule: String, reference: String, differing: usize },
}

/// Each step's error of `Compiled::compile` becomes the error it becomes alone: compiling's
/// [`PassError::Graph`], the kernel plan's [`BackendError::KernelPlan`].
impl From<CompileError> for PassError {
    fn from(error: CompileError) -> PassError {
        match error {
            CompileError::Graph(e) => PassError::Graph(e),
            CompileError::KernelPlan(e) => PassError::Backend(e.into()),
        }
    }
}

/// Shorthand used across the crate.
pub type Result<T> = std::result::Result<T, PassError>;

/// What [`declare_tonemap`](crate::declare_tonemap) refuses.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TonemapError {
    #[error("tonemap exposure {exposure} must be a finite number greater than 0")]
    Exposure { exposure: f32 },
}
