//! The one place a pipeline becomes what runs: the light field planned over its devices, the
//! pipeline (extended by a user crate's stages) declared on the plan's topology, and both
//! compiled and made into its kernel plan in one call. `plan` and `render` compile through here, so `plan` shows
//! exactly the schedule `render` runs.

use std::sync::Arc;

use anyhow::Result;
use parallax_backend::{Compiled, KernelGraph, KernelPlan};
use parallax_graph::{
    AssignStrategy, LightField, Partition, PartitionConfig, ProvenSchedule, Schedule, ScheduleSummary, Scheme,
    SourcesPerSet,
};
use parallax_passes::firefly::FireflyMode;
use parallax_passes::hole_subsample::HoleFillMode;
use parallax_passes::pipeline::{
    Denoiser, GbufferSource, PipelineBuilder, PipelineConfig, PipelineHandles, PipelineKind,
};
use parallax_passes::reproject::ReprojectionTolerances;

use crate::outputs::budget::PlanShape;

/// The pipeline and its placement over the devices.
#[derive(Clone, Debug)]
pub struct PipelineSettings {
    /// The pipeline declared (its exposure is the GPU tonemap's).
    pub config: PipelineConfig,
    pub scheme: Scheme,
    /// How views are grouped into sets (multi-source).
    pub assign: AssignStrategy,
    /// Explicit sources for the fine-grained schemes.
    pub sources: Option<Vec<u32>>,
    pub sources_per_set: SourcesPerSet,
    /// The reprojection's view-dependence tolerance as given (`config` holds it as the
    /// shader's f32), for render.json.
    pub reprojection_tolerance: f64,
}

impl Default for PipelineSettings {
    /// The paper's pipeline (PipelineConfig's default) under multi-source with compact sets,
    /// the sources per set chosen by their predicted cost.
    fn default() -> Self {
        PipelineSettings {
            config: PipelineConfig::default(),
            scheme: Scheme::MultiSource,
            assign: AssignStrategy::Compact,
            sources: None,
            sources_per_set: SourcesPerSet::Auto,
            reprojection_tolerance: default_reprojection_tolerance(),
        }
    }
}

/// `ReprojectionTolerances::DEFAULT_VIEW_DEPENDENCE` as the decimal it is written as (0.2, not
/// the f32's 0.20000000298...), for `--help` and render.json.
pub fn default_reprojection_tolerance() -> f64 {
    ReprojectionTolerances::DEFAULT_VIEW_DEPENDENCE.to_string().parse().expect("a float prints as a float")
}

impl PipelineSettings {
    fn partition_config(&self, devices: u32) -> PartitionConfig {
        PartitionConfig { devices, scheme: self.scheme, assign: self.assign, sources: self.sources.clone() }
    }

    fn partition_shape(&self, lf: &LightField, config: &PartitionConfig) -> PlanShape {
        let devices = config.devices;
        let (sources, sources_flag) = match (&config.sources, config.scheme) {
            (Some(s), _) => (s.len() as u64, Some("--sources")),
            (None, Scheme::MultiSource) => match self.sources_per_set {
                SourcesPerSet::Count(n) if n > 1 => (u64::from(devices) * u64::from(n), Some("--sources-per-set")),
                // Multi-source plans grow with the views, not the sources (PlanShape::items).
                _ => (u64::from(devices), None),
            },
            (None, _) => (u64::from(devices), None),
        };
        PlanShape { views: lf.len() as u64, devices: u64::from(devices), sources, scheme: config.scheme, sources_flag }
    }

    /// Refuses a plan of `lf` over `devices` that the planner could not hold, before planning
    /// (render checks it beside its other limits, to name them all at once).
    pub fn check_plan_size(&self, lf: &LightField, devices: u32) -> Result<()> {
        self.partition_shape(lf, &self.partition_config(devices)).check()
    }

    /// [`compile`] of these settings over `devices`, the pipeline extended by `extend` (a user
    /// crate's stages), after refusing a plan too large to hold.
    pub fn compile_with(
        &self,
        lf: &LightField,
        devices: u32,
        extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder,
    ) -> Result<PipelineSchedule> {
        let config = self.partition_config(devices);
        self.partition_shape(lf, &config).check()?;
        compile(lf, &config, self.sources_per_set, self.config, extend)
    }
}

/// A compiled, checked schedule of the pipeline, with what running it needs.
pub struct PipelineSchedule {
    pub partition: Partition,
    pub handles: PipelineHandles,
    pub schedule: ProvenSchedule,
    /// What executes `schedule`, built from it once here (a rank runs its part of it).
    pub exec: Arc<KernelPlan>,
    pub summary: ScheduleSummary,
    pub kind: PipelineKind,
}

/// Partitions `lf` as `config` says, declares the pipeline `pipeline` extended by `extend` (only the
/// display images are exported: they travel to device 0; float layers are read where they were
/// made) and compiles it into its schedule and the plan that executes it (`Compiled::compile`).
/// The partition depends only on the views' positions in the rig plane, never on the rig's pose, so
/// any rig gives the same schedule.
pub fn compile(
    lf: &LightField,
    config: &PartitionConfig,
    sources_per_set: SourcesPerSet,
    pipeline: PipelineConfig,
    extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder,
) -> Result<PipelineSchedule> {
    let kind = pipeline.kind;
    let partition = Partition::with_sources(lf, config, sources_per_set)?;
    let mut graph = KernelGraph::with_payload(partition.topology.clone());
    let handles = extend(PipelineBuilder::new(pipeline)).declare(&mut graph)?;
    graph.export(&handles.display);
    let Compiled { schedule, plan: exec } = Compiled::compile(&graph, &partition)?;
    let summary = ScheduleSummary::new(lf, &partition, &schedule);
    Ok(PipelineSchedule { partition, handles, schedule, exec: Arc::new(exec), summary, kind })
}

/// The light field `lf` of `resolution` on the default rig and its default pipeline compiled
/// under `scheme` (with `sources`, if given) over `devices`: what `render` runs with those flags.
#[cfg(test)]
pub(crate) fn compiled(
    lf: &str,
    resolution: (u32, u32),
    scheme: Scheme,
    sources: Option<Vec<u32>>,
    devices: u32,
) -> (LightField, PipelineSchedule) {
    let layout =
        crate::settings::LayoutSettings { lf: lf.parse().unwrap(), spacing: None, resolution: Some(resolution) };
    let lf = layout.with_rig(parallax_graph::Rig::default()).unwrap();
    let pipeline = PipelineSettings { scheme, sources, ..PipelineSettings::default() };
    let compiled = pipeline.compile_with(&lf, devices, &|builder| builder).unwrap();
    (lf, compiled)
}

/// How much of a schedule the DOT drawing shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DotDetail {
    /// `full` while one pass has at most 40 instances (the drawing's widest row: 8x4 views on
    /// any number of devices), `summary` above (NELF's 72 views drawn in full are 14,800 pt
    /// wide, past reading).
    #[default]
    Auto,
    /// One node per pass and device with instance counts, one per copy kind and device pair.
    Summary,
    /// Every pass instance and copy (large schedules take Graphviz minutes or longer).
    Full,
}

impl DotDetail {
    /// The most instances of one pass `auto` draws in full: Graphviz sets a pass's instances
    /// side by side, about 110 pt each, so 40 make a row of 4,400 pt.
    const AUTO_FULL_WIDTH: usize = 40;

    /// `schedule` as Graphviz DOT, in this much detail.
    pub fn render(self, schedule: &Schedule) -> String {
        let full = match self {
            DotDetail::Auto => widest_pass(schedule) <= Self::AUTO_FULL_WIDTH,
            DotDetail::Summary => false,
            DotDetail::Full => true,
        };
        if full { schedule.to_dot() } else { schedule.to_dot_summary() }
    }
}

fn widest_pass(schedule: &Schedule) -> usize {
    let mut per_pass = std::collections::HashMap::new();
    for instance in &schedule.instances {
        *per_pass.entry(instance.pass).or_insert(0) += 1;
    }
    per_pass.into_values().max().unwrap_or(0)
}

/// The plan's summary as `plan --json` and render.json's `plan` write it, with the G-buffer
/// that runs.
pub fn plan_json(summary: &ScheduleSummary, gbuffer: GbufferSource) -> serde_json::Value {
    let mut json = serde_json::to_value(summary).expect("a plan summary serialises");
    json["gbuffer"] = gbuffer_name(gbuffer).into();
    json
}

/// The settings' values as the JSON outputs spell them (the command line's flag values).
pub fn pipeline_name(kind: PipelineKind) -> &'static str {
    match kind {
        PipelineKind::Reproject => "reproject",
        PipelineKind::PathTrace => "path-trace",
    }
}

/// `first-hits`, `raster` or `visibility`.
pub fn gbuffer_name(gbuffer: GbufferSource) -> &'static str {
    match gbuffer {
        GbufferSource::FirstHits => "first-hits",
        GbufferSource::Raster => "raster",
        GbufferSource::Visibility => "visibility",
    }
}

/// `suppress` or `keep`.
pub fn fireflies_name(fireflies: FireflyMode) -> &'static str {
    match fireflies {
        FireflyMode::Suppress => "suppress",
        FireflyMode::Keep => "keep",
    }
}

/// `views`, `samples` or `none`.
pub fn denoiser_name(denoiser: Denoiser) -> &'static str {
    match denoiser {
        Denoiser::Views => "views",
        Denoiser::Samples => "samples",
        Denoiser::None => "none",
    }
}

/// `full` or `subsampled`.
pub fn hole_fill_name(hole_fill: HoleFillMode) -> &'static str {
    match hole_fill {
        HoleFillMode::Full => "full",
        HoleFillMode::Subsampled => "subsampled",
    }
}

/// `"auto"` or the count.
pub fn sources_per_set_json(sources_per_set: SourcesPerSet) -> serde_json::Value {
    match sources_per_set {
        SourcesPerSet::Auto => "auto".into(),
        SourcesPerSet::Count(n) => n.into(),
    }
}
