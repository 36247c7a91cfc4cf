//! The one place a pipeline becomes what runs: the light field planned over its devices, the
//! pipeline (extended by a user crate's stages) declared on the plan's topology, and both
//! compiled and lowered in one call. `plan` and `render` compile through here, so `plan` shows
//! exactly the schedule `render` runs.

use anyhow::Result;
use parallax_backend::{Compiled, KernelGraph, KernelPlan};
use parallax_graph::{LightField, Plan, PlanConfig, PlanSummary, ProvenSchedule, SourcesPerSet};
use parallax_passes::pipeline::{PipelineBuilder, PipelineConfig, PipelineHandles, PipelineKind};

/// A compiled, checked schedule of the pipeline, with what running it needs.
pub struct PipelineSchedule {
    pub plan: Plan,
    pub handles: PipelineHandles,
    pub schedule: ProvenSchedule,
    /// What executes `schedule`, lowered from it once here (a rank runs its part of it).
    pub exec: KernelPlan,
    pub summary: PlanSummary,
    pub kind: PipelineKind,
}

/// Plans `lf` as `config` says, declares the pipeline `pipeline` extended by `extend` (only the
/// display images are exported: they travel to device 0; float layers are read where they were
/// made) and compiles it into its schedule and the plan that executes it (`Compiled::compile`).
/// The plan depends only on the views' positions in the rig plane, never on the rig's pose, so
/// any rig gives the same schedule.
pub fn compile(
    lf: &LightField,
    config: &PlanConfig,
    sources_per_set: SourcesPerSet,
    pipeline: PipelineConfig,
    extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder,
) -> Result<PipelineSchedule> {
    let kind = pipeline.kind;
    let plan = Plan::with_sources(lf, config, sources_per_set)?;
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let handles = extend(PipelineBuilder::new(pipeline)).declare(&mut graph)?;
    graph.export(&handles.display);
    let Compiled { schedule, plan: exec } = Compiled::compile(&graph, &plan)?;
    let summary = PlanSummary::new(lf, &plan, &schedule);
    Ok(PipelineSchedule { plan, handles, schedule, exec, summary, kind })
}
