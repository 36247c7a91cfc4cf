//! The light-field pipelines as graphs (docs/PIPELINE.md): the paper's reconstruction
//! (`Reproject`: G-buffer → path trace sources → reproject targets → hole filling → SVGF →
//! tonemap) and the baseline that path traces every view (`PathTrace`), declared once and
//! placed by any of the three schemes. What differs between the schemes is only the plan's
//! sources and placement, which is what makes the comparison side by side fair.

use std::sync::Arc;

use parallax_backend::KernelGraph;
use parallax_graph::{Format, Handle, Image, Role};

use crate::gbuffer::{Gbuffer, declare_gbuffer};
use crate::path_trace::{PATH_TRACE, PathTraceKernel};
use crate::reproject::{ReprojectionTolerances, declare_reproject};

/// Which pipeline renders the light field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum PipelineKind {
    /// The paper's: only sources are path traced, targets are reprojected and their holes filled.
    Reproject,
    /// The baseline: every view path traced.
    PathTrace,
}

/// What a pipeline declaration needs to know.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineConfig {
    pub kind: PipelineKind,
    pub tolerances: ReprojectionTolerances,
}

/// Handles of a declared pipeline, for callers that read layers back or add passes.
pub struct PipelineHandles {
    pub gbuffer: Gbuffer,
    /// Linear radiance before denoising (targets: reprojected, holes filled).
    pub radiance: Handle<Image>,
    /// Targets' hole masks (`Reproject` only).
    pub holes: Option<Handle<Image>>,
}

/// Declares `path_trace` for every view of `role`, writing only `radiance`.
pub fn declare_path_trace(graph: &mut KernelGraph, role: Role, radiance: &mut Handle<Image>) {
    graph.pass(PATH_TRACE, role).write(radiance).kernel(Arc::new(PathTraceKernel)).record();
}

/// Declares the pipeline of `config`; nothing is exported (the caller exports what it reads).
pub fn declare_pipeline(graph: &mut KernelGraph, config: &PipelineConfig) -> PipelineHandles {
    let gbuffer = declare_gbuffer(graph);
    let mut radiance = graph.image("radiance", Format::Rgba32f);
    let holes = match config.kind {
        PipelineKind::PathTrace => {
            declare_path_trace(graph, Role::All, &mut radiance);
            None
        }
        PipelineKind::Reproject => {
            declare_path_trace(graph, Role::Sources, &mut radiance);
            Some(declare_reproject(graph, &gbuffer, &mut radiance, config.tolerances))
        }
    };
    PipelineHandles { gbuffer, radiance, holes }
}
