//! The light-field pipelines as graphs (docs/PIPELINE.md): the paper's reconstruction
//! (`Reproject`: G-buffer → path trace sources → reproject targets → hole filling → firefly
//! suppression → SVGF → tonemap) and the baseline that path traces every view (`PathTrace`), declared once and
//! placed by any of the three schemes. What differs between the schemes is only the plan's
//! sources and placement, which is what makes the comparison side by side fair.
//!
//! Where the denoiser runs is [`Denoiser`]: over every view after reconstruction (`Views`), or
//! over the samples (`Samples`: SVGF on the sources before reprojection, the targets reproject
//! the denoised radiance, and their hole pixels are accumulated by [`crate::hole_denoise`]).
//! Which hole pixels are traced is [`HoleFillMode`]: all of them every frame (`Full`), or a
//! rotating subset, the others reconstructed from traced neighbours (`Subsampled`,
//! [`crate::hole_subsample`]).
//!
//! [`PipelineBuilder`] declares it stage by stage; a caller adds stages of its own at named
//! [`InsertionPoint`]s and replaces the denoiser or the tonemapper, and gets the standard
//! pipeline, pass for pass, when it does neither ([`declare_pipeline`]):
//!
//! ```
//! # use parallax_backend::KernelGraph;
//! # use parallax_graph::{Format, Role, ViewTopology};
//! use parallax_passes::pipeline::{InsertionPoint, PipelineBuilder, PipelineConfig};
//!
//! let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(2, 16, 16));
//! let handles = PipelineBuilder::new(PipelineConfig::default())
//!     .insert(InsertionPoint::BeforeTonemap, |graph, layers| {
//!         let mut exposure = graph.global_image("exposure", 1, 1, Format::R32f);
//!         let mut pass = graph.global_pass("expose");
//!         pass.read_every_view_slot(layers.linear());
//!         pass.write_slot(&mut exposure);
//!         // ... .kernel(...) and .add(); tonemap then scales by it:
//!         # drop(pass);
//!         layers.exposure = Some(exposure);
//!         Ok(())
//!     })
//!     .declare(&mut graph)?;
//! assert!(handles.exposure.is_some());
//! # Ok::<(), parallax_passes::PassError>(())
//! ```

use std::sync::Arc;

use parallax_backend::KernelGraph;
use parallax_graph::{FamilyId, Format, Handle, Image, Role};

use crate::error::Result;
use crate::firefly::{FireflyMode, declare_firefly_suppression};
use crate::gbuffer::{Gbuffer, declare_gbuffer, declare_gbuffer_rasterised};
use crate::hole_denoise::declare_hole_denoise;
use crate::hole_subsample::{HoleFillMode, SubsampledHoles, declare_hole_reconstruction, declare_subsampled_hole_fill};
use crate::holes::declare_hole_fill;
use crate::path_trace::{PATH_TRACE, PathTraceKernel};
use crate::reproject::{ReprojectionTolerances, declare_reproject};
use crate::svgf::{SvgfInputs, declare_svgf};
use crate::tonemap::declare_tonemap_scaled;

// The G-buffer kinds stand beside the G-buffer; a pipeline's config names one.
pub use crate::gbuffer::GbufferSource;

/// Which pipeline renders the light field.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum PipelineKind {
    /// The paper's: only sources are path traced, targets are reprojected and their holes filled.
    Reproject,
    /// The baseline: every view path traced.
    PathTrace,
}

/// Where the pipeline denoises (docs/PIPELINE.md, "Denoising in sample space").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Denoiser {
    /// SVGF over every view after reconstruction, between the radiance and the tonemapper.
    Views,
    /// Where fresh samples are: SVGF over the sources before reprojection (the targets reproject
    /// the denoised radiance), then each target's hole pixels accumulated over frames
    /// ([`crate::hole_denoise`]). With [`PipelineKind::PathTrace`] every view is a source, so
    /// this is `Views`.
    Samples,
    /// No denoising (and no firefly suppression, which belongs to it).
    None,
}

/// What a pipeline declaration needs to know.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineConfig {
    pub kind: PipelineKind,
    pub gbuffer: GbufferSource,
    pub tolerances: ReprojectionTolerances,
    /// Energy-conserving firefly suppression of the complete radiance, before the denoiser
    /// ([`crate::firefly`]).
    pub fireflies: FireflyMode,
    /// Where SVGF runs, if anywhere.
    pub denoise: Denoiser,
    /// Whether every hole pixel is traced every frame ([`crate::hole_subsample`]).
    pub hole_fill: HoleFillMode,
    /// Exposure of the tonemapper (finite, > 0).
    pub exposure: f32,
}

/// Handles of a declared pipeline, for callers that read layers back or add passes.
pub struct PipelineHandles {
    pub gbuffer: Gbuffer,
    /// Linear radiance before denoising (targets: reprojected, then their holes path traced;
    /// then its fireflies suppressed, with [`FireflyMode::Suppress`]).
    pub radiance: Handle<Image>,
    /// Targets' hole masks (`Reproject` only).
    pub holes: Option<Handle<Image>>,
    /// The traced and reconstructed hole pixels ([`HoleFillMode::Subsampled`] only).
    pub subsampled_holes: Option<SubsampledHoles>,
    /// Linear radiance after denoising (`denoise` not `None`). Under [`Denoiser::Samples`] a
    /// target's is its reprojected denoised radiance with its holes traced and accumulated.
    pub denoised: Option<Handle<Image>>,
    /// The declared resource of the final linear radiance, what the tonemapper reads and the
    /// linear views are read back by: the denoiser's output (`denoised` for SVGF), or
    /// `radiance` without denoising.
    pub linear: FamilyId,
    /// The global 1×1 image the tonemapper scaled its exposure by, if a stage declared one.
    pub exposure: Option<Handle<Image>>,
    /// The tonemapped RGBA8 image of every view (not exported: the caller decides).
    pub display: Handle<Image>,
}

/// Where [`PipelineBuilder::insert`] puts a stage, in pipeline order. Stages at one point run
/// in the order they were inserted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum InsertionPoint {
    /// The G-buffer is written; nothing is traced yet.
    AfterGbuffer,
    /// The radiance of the path-traced views (sources; every view for `PathTrace`) is written.
    AfterTrace,
    /// Targets' radiance is reprojected and their hole masks written (`Reproject` only).
    AfterReprojection,
    /// Targets' holes are path traced (`Reproject` only).
    AfterHoleFill,
    /// Fireflies are suppressed (with [`FireflyMode::Suppress`]; else the same place as
    /// [`Self::AfterHoleFill`]): the radiance the denoiser reads.
    AfterFireflies,
    /// The radiance is denoised (with `denoise`; else the same place as [`Self::BeforeTonemap`]).
    AfterDenoise,
    /// Last before the tonemapper: where an exposure is measured ([`Layers::exposure`]).
    BeforeTonemap,
}

/// The pipeline's layers while it is declared: what an inserted stage reads, and writes new
/// versions of (through `&mut`), so the stages after it see what it wrote.
pub struct Layers {
    pub gbuffer: Gbuffer,
    pub radiance: Handle<Image>,
    pub holes: Option<Handle<Image>>,
    /// The traced and reconstructed hole pixels ([`HoleFillMode::Subsampled`] only).
    pub subsampled_holes: Option<SubsampledHoles>,
    pub denoised: Option<Handle<Image>>,
    /// A global 1×1 `R32f` image whose texel the tonemapper multiplies its exposure by; none
    /// (the default) tonemaps at the configured exposure alone.
    pub exposure: Option<Handle<Image>>,
}

impl Layers {
    /// The linear radiance the next stage sees: denoised once the denoiser ran, else the radiance.
    pub fn linear(&mut self) -> &mut Handle<Image> {
        self.denoised.as_mut().unwrap_or(&mut self.radiance)
    }
}

/// A stage a caller inserts: declares its passes into the graph, reading and writing layers.
pub type Stage = Box<dyn FnOnce(&mut KernelGraph, &mut Layers) -> Result<()>>;
/// A stage that replaces one of the pipeline's own and returns the image it makes.
pub type Replacement = Box<dyn FnOnce(&mut KernelGraph, &mut Layers) -> Result<Handle<Image>>>;

/// Declares the standard pipeline of a [`PipelineConfig`], with stages of the caller's own.
#[must_use = "nothing is declared until .declare(graph)"]
pub struct PipelineBuilder {
    config: PipelineConfig,
    inserted: Vec<(InsertionPoint, Stage)>,
    denoiser: Option<Replacement>,
    tonemapper: Option<Replacement>,
}

impl Default for PipelineConfig {
    /// What `parallax render` runs without flags: the paper's pipeline with first-hit G-buffer,
    /// firefly suppression, SVGF and exposure 1.
    fn default() -> Self {
        PipelineConfig {
            kind: PipelineKind::Reproject,
            gbuffer: GbufferSource::FirstHits,
            tolerances: ReprojectionTolerances::default(),
            fireflies: FireflyMode::Suppress,
            denoise: Denoiser::Views,
            hole_fill: HoleFillMode::Full,
            exposure: 1.0,
        }
    }
}

impl PipelineBuilder {
    pub fn new(config: PipelineConfig) -> Self {
        PipelineBuilder { config, inserted: Vec::new(), denoiser: None, tonemapper: None }
    }

    /// Runs `stage` at `at`, after the stages already inserted there.
    pub fn insert(
        mut self,
        at: InsertionPoint,
        stage: impl FnOnce(&mut KernelGraph, &mut Layers) -> Result<()> + 'static,
    ) -> Self {
        self.inserted.push((at, Box::new(stage)));
        self
    }

    /// Declares `denoiser` instead of SVGF (when the config denoises): it returns the denoised
    /// radiance. Under [`Denoiser::Samples`] it runs before reprojection, when only the sources
    /// have radiance: its passes must be declared for [`Role::Sources`].
    pub fn replace_denoiser(
        mut self,
        denoiser: impl FnOnce(&mut KernelGraph, &mut Layers) -> Result<Handle<Image>> + 'static,
    ) -> Self {
        self.denoiser = Some(Box::new(denoiser));
        self
    }

    /// Declares `tonemapper` instead of `tonemap`: it returns every view's display image.
    pub fn replace_tonemapper(
        mut self,
        tonemapper: impl FnOnce(&mut KernelGraph, &mut Layers) -> Result<Handle<Image>> + 'static,
    ) -> Self {
        self.tonemapper = Some(Box::new(tonemapper));
        self
    }

    /// Declares the pipeline; nothing is exported (the caller exports what it reads).
    pub fn declare(mut self, graph: &mut KernelGraph) -> Result<PipelineHandles> {
        let config = self.config;
        let gbuffer = match config.gbuffer {
            // Hole filling bounds its camera rays by the centre rays' first hits.
            GbufferSource::FirstHits => declare_gbuffer(graph, config.kind == PipelineKind::Reproject),
            GbufferSource::Raster => declare_gbuffer_rasterised(graph),
            GbufferSource::Visibility => {
                crate::visibility::declare_gbuffer_visibility(graph, config.kind == PipelineKind::Reproject)
            }
        };
        let radiance = graph.image("radiance", Format::Rgba32f);
        let mut layers =
            Layers { gbuffer, radiance, holes: None, subsampled_holes: None, denoised: None, exposure: None };
        self.run_stages(InsertionPoint::AfterGbuffer, graph, &mut layers)?;
        let traced = if config.kind == PipelineKind::PathTrace { Role::All } else { Role::Sources };
        declare_path_trace(graph, traced, &mut layers.radiance);
        self.run_stages(InsertionPoint::AfterTrace, graph, &mut layers)?;
        if config.kind == PipelineKind::Reproject && config.denoise == Denoiser::Samples {
            return self.declare_sample_space(graph, layers);
        }
        if config.kind == PipelineKind::Reproject {
            layers.holes = Some(declare_reproject(graph, &layers.gbuffer, &mut layers.radiance, config.tolerances)?);
            self.run_stages(InsertionPoint::AfterReprojection, graph, &mut layers)?;
            let holes = layers.holes.as_ref().expect("declared just above");
            match config.hole_fill {
                HoleFillMode::Full => {
                    declare_hole_fill(graph, holes, layers.gbuffer.first_hit.as_ref(), &mut layers.radiance);
                }
                HoleFillMode::Subsampled => {
                    let (gbuffer, radiance) = (&layers.gbuffer, &mut layers.radiance);
                    let subsampled = declare_subsampled_hole_fill(graph, holes, gbuffer, radiance);
                    // SVGF takes the reconstructed radiance as it takes the traced.
                    declare_hole_reconstruction(graph, &subsampled, gbuffer, None, radiance);
                    layers.subsampled_holes = Some(subsampled);
                }
            }
            self.run_stages(InsertionPoint::AfterHoleFill, graph, &mut layers)?;
        }
        self.declare_fireflies_and_denoiser(graph, &mut layers, Role::All)?;
        self.finish(graph, layers)
    }

    /// Firefly suppression and the denoiser (SVGF, or the replaced one) over the radiance of
    /// the views of `role`, each followed by its insertion point's stages.
    fn declare_fireflies_and_denoiser(
        &mut self,
        graph: &mut KernelGraph,
        layers: &mut Layers,
        role: Role,
    ) -> Result<()> {
        if self.config.fireflies == FireflyMode::Suppress {
            declare_firefly_suppression(graph, role, &layers.gbuffer.position_depth, &mut layers.radiance);
        }
        self.run_stages(InsertionPoint::AfterFireflies, graph, layers)?;
        if self.config.denoise != Denoiser::None {
            let denoised = match self.denoiser.take() {
                Some(denoiser) => denoiser(graph, layers)?,
                None => declare_standard_svgf(graph, role, layers),
            };
            layers.denoised = Some(denoised);
        }
        self.run_stages(InsertionPoint::AfterDenoise, graph, layers)
    }

    /// The reprojection pipeline denoised in sample space ([`Denoiser::Samples`]): the sources'
    /// radiance is suppressed and denoised first (SVGF for [`Role::Sources`]), the targets
    /// reproject that denoised radiance into their `denoised` image, their holes are traced into
    /// it and accumulated there. The insertion points come in the order the stages run: the
    /// fireflies and the denoiser before the reprojection.
    fn declare_sample_space(mut self, graph: &mut KernelGraph, mut layers: Layers) -> Result<PipelineHandles> {
        self.declare_fireflies_and_denoiser(graph, &mut layers, Role::Sources)?;
        // Reads the sources' denoised radiance, writes the targets' own.
        let denoised = layers.denoised.as_mut().expect("`Samples` declares the denoiser");
        let holes = declare_reproject(graph, &layers.gbuffer, denoised, self.config.tolerances)?;
        layers.holes = Some(holes);
        self.run_stages(InsertionPoint::AfterReprojection, graph, &mut layers)?;
        let holes = layers.holes.as_ref().expect("set above");
        let denoised = layers.denoised.as_mut().expect("set above");
        match self.config.hole_fill {
            HoleFillMode::Full => {
                let list = declare_hole_fill(graph, holes, layers.gbuffer.first_hit.as_ref(), denoised);
                declare_hole_denoise(graph, &list, None, denoised);
            }
            HoleFillMode::Subsampled => {
                let subsampled = declare_subsampled_hole_fill(graph, holes, &layers.gbuffer, denoised);
                // Only the traced pixels join their running means; the others show theirs.
                let accum = declare_hole_denoise(graph, &subsampled.traced, Some(&subsampled.reconstructed), denoised);
                declare_hole_reconstruction(graph, &subsampled, &layers.gbuffer, Some(&accum), denoised);
                layers.subsampled_holes = Some(subsampled);
            }
        }
        self.run_stages(InsertionPoint::AfterHoleFill, graph, &mut layers)?;
        self.finish(graph, layers)
    }

    /// The stages before the tonemapper, the tonemapper, and the handles.
    fn finish(mut self, graph: &mut KernelGraph, mut layers: Layers) -> Result<PipelineHandles> {
        self.run_stages(InsertionPoint::BeforeTonemap, graph, &mut layers)?;
        let display = match self.tonemapper.take() {
            Some(tonemapper) => tonemapper(graph, &mut layers)?,
            None => {
                let linear = layers.denoised.as_ref().unwrap_or(&layers.radiance);
                declare_tonemap_scaled(graph, linear, self.config.exposure, layers.exposure.as_ref())?
            }
        };
        let linear = layers.denoised.as_ref().unwrap_or(&layers.radiance).family();
        let Layers { gbuffer, radiance, holes, subsampled_holes, denoised, exposure } = layers;
        Ok(PipelineHandles { gbuffer, radiance, holes, subsampled_holes, denoised, linear, exposure, display })
    }

    /// Runs the stages inserted at `at`, in insertion order.
    fn run_stages(&mut self, at: InsertionPoint, graph: &mut KernelGraph, layers: &mut Layers) -> Result<()> {
        let (here, later): (Vec<_>, Vec<_>) =
            std::mem::take(&mut self.inserted).into_iter().partition(|(p, _)| *p == at);
        self.inserted = later;
        here.into_iter().try_for_each(|(_, stage)| stage(graph, layers))
    }
}

/// SVGF over the pipeline's radiance and G-buffer of the views of `role`.
fn declare_standard_svgf(graph: &mut KernelGraph, role: Role, layers: &Layers) -> Handle<Image> {
    let gbuffer = &layers.gbuffer;
    let inputs = SvgfInputs {
        radiance: &layers.radiance,
        albedo_roughness: &gbuffer.albedo_roughness,
        normal_metallic: &gbuffer.normal_metallic,
        position_depth: &gbuffer.position_depth,
        motion: &gbuffer.motion,
    };
    declare_svgf(graph, role, &inputs)
}

/// Declares `path_trace` for every view of `role`, writing only `radiance`.
pub fn declare_path_trace(graph: &mut KernelGraph, role: Role, radiance: &mut Handle<Image>) {
    let mut pass = graph.pass(PATH_TRACE, role);
    let kernel = PathTraceKernel::new(pass.write_slot(radiance));
    pass.kernel(Arc::new(kernel)).add();
}

/// Declares the standard pipeline of `config` (a [`PipelineBuilder`] with no stage of the
/// caller's); nothing is exported (the caller exports what it reads).
pub fn declare_pipeline(graph: &mut KernelGraph, config: &PipelineConfig) -> Result<PipelineHandles> {
    PipelineBuilder::new(*config).declare(graph)
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    use parallax_graph::ViewTopology;

    use super::*;

    /// Two sources and two targets of 8×8, each target reprojecting from both sources.
    fn topology() -> ViewTopology {
        let sources = vec![parallax_graph::ViewId(0), parallax_graph::ViewId(1)];
        ViewTopology {
            width: 8,
            height: 8,
            sources_of: vec![vec![], vec![], sources.clone(), sources],
            is_source: vec![true, true, false, false],
        }
    }

    /// The names of the declared passes.
    fn pass_names(graph: &KernelGraph) -> Vec<String> {
        graph.passes().iter().map(|p| p.name.clone()).collect()
    }

    #[test]
    fn inserted_stages_run_at_their_points_in_insertion_order() {
        let seen: Arc<Mutex<Vec<(InsertionPoint, usize, String)>>> = Arc::default();
        let mut builder = PipelineBuilder::new(PipelineConfig::default());
        // Inserted out of pipeline order, two at one point.
        for (i, at) in [
            InsertionPoint::BeforeTonemap,
            InsertionPoint::AfterHoleFill,
            InsertionPoint::AfterGbuffer,
            InsertionPoint::AfterDenoise,
            InsertionPoint::AfterReprojection,
            InsertionPoint::AfterTrace,
            InsertionPoint::AfterFireflies,
            InsertionPoint::BeforeTonemap,
        ]
        .into_iter()
        .enumerate()
        {
            let seen = seen.clone();
            builder = builder.insert(at, move |graph, _| {
                let last = graph.passes().last().map(|p| p.name.clone()).unwrap_or_default();
                seen.lock().unwrap().push((at, i, last));
                Ok(())
            });
        }
        let mut graph = KernelGraph::with_payload(topology());
        builder.declare(&mut graph).unwrap();
        let seen = seen.lock().unwrap().clone();
        let points: Vec<InsertionPoint> = seen.iter().map(|(at, ..)| *at).collect();
        let mut sorted = points.clone();
        sorted.sort();
        assert_eq!(points, sorted, "stages run in pipeline order");
        let at_tonemap: Vec<usize> =
            seen.iter().filter(|(at, ..)| *at == InsertionPoint::BeforeTonemap).map(|(_, i, _)| *i).collect();
        assert_eq!(at_tonemap, [0, 7], "two stages at one point run in insertion order");
        let last_before = |at| seen.iter().find(|(p, ..)| *p == at).unwrap().2.clone();
        assert_eq!(last_before(InsertionPoint::AfterTrace), crate::path_trace::PATH_TRACE);
        assert_eq!(last_before(InsertionPoint::AfterHoleFill), crate::holes::HOLE_FILL);
        assert_eq!(last_before(InsertionPoint::AfterFireflies), crate::firefly::FIREFLY_SPREAD);
        assert!(!pass_names(&graph).is_empty() && pass_names(&graph).last().unwrap() == crate::tonemap::TONEMAP);
    }

    #[test]
    fn the_builder_with_nothing_added_declares_the_standard_pipeline() {
        let (mut a, mut b) = (KernelGraph::with_payload(topology()), KernelGraph::with_payload(topology()));
        let config = PipelineConfig::default();
        let handles = declare_pipeline(&mut a, &config).unwrap();
        PipelineBuilder::new(config).insert(InsertionPoint::AfterDenoise, |_, _| Ok(())).declare(&mut b).unwrap();
        // The paper's pipeline, as Table 1 lists its stages.
        let standard = [
            "gbuffer",
            "path_trace",
            "reproject",
            "compact_holes",
            "hole_fill",
            "firefly_bound",
            "firefly_spread",
            "svgf_history",
            "svgf_temporal",
            "svgf_atrous_1",
            "svgf_atrous_2",
            "svgf_atrous_3",
            "svgf_atrous_4",
            "svgf_atrous_5",
            "tonemap",
        ];
        assert_eq!(pass_names(&a), standard);
        assert_eq!(pass_names(&b), standard);
        let denoised = handles.denoised.as_ref().unwrap();
        assert_eq!((handles.linear, b.name_of(denoised)), (denoised.family(), crate::svgf::DENOISED));
    }

    #[test]
    fn keeping_fireflies_declares_the_pipeline_without_their_passes() {
        let mut graph = KernelGraph::with_payload(topology());
        let config = PipelineConfig { fireflies: FireflyMode::Keep, ..PipelineConfig::default() };
        declare_pipeline(&mut graph, &config).unwrap();
        let mut suppressing = KernelGraph::with_payload(topology());
        declare_pipeline(&mut suppressing, &PipelineConfig::default()).unwrap();
        let mut without: Vec<String> = pass_names(&suppressing);
        without.retain(|n| n != crate::firefly::FIREFLY_BOUND && n != crate::firefly::FIREFLY_SPREAD);
        assert_eq!(without.len() + 2, pass_names(&suppressing).len());
        assert_eq!(pass_names(&graph), without);
    }

    #[test]
    fn a_replaced_denoiser_is_what_the_tonemapper_and_the_readback_see() {
        let mut graph = KernelGraph::with_payload(topology());
        let handles = PipelineBuilder::new(PipelineConfig::default())
            .replace_denoiser(|graph, layers| {
                let mut denoised = graph.image("my_denoised", Format::Rgba32f);
                graph.pass("my_denoiser", Role::All).read(&layers.radiance).write(&mut denoised).add();
                Ok(denoised)
            })
            .declare(&mut graph)
            .unwrap();
        let denoised = handles.denoised.as_ref().unwrap();
        assert_eq!((handles.linear, graph.name_of(denoised)), (denoised.family(), "my_denoised"));
        assert!(!pass_names(&graph).iter().any(|p| p.starts_with("svgf")));
    }

    #[test]
    fn a_replaced_tonemapper_is_declared_instead_of_tonemap() {
        let mut graph = KernelGraph::with_payload(topology());
        let handles = PipelineBuilder::new(PipelineConfig { denoise: Denoiser::None, ..PipelineConfig::default() })
            .replace_tonemapper(|graph, layers| {
                let mut display = graph.image("my_display", Format::Rgba8);
                graph.pass("my_tonemap", Role::All).read(layers.linear()).write(&mut display).add();
                Ok(display)
            })
            .declare(&mut graph)
            .unwrap();
        let names = pass_names(&graph);
        assert!(!names.iter().any(|n| n == crate::tonemap::TONEMAP), "{names:?}");
        assert_eq!(names.last().map(String::as_str), Some("my_tonemap"));
        assert_eq!(handles.linear, handles.radiance.family());
    }

    /// The passes of the pipeline denoised in sample space, in order, with their roles.
    const SAMPLE_SPACE: [(&str, Role); 16] = [
        ("gbuffer", Role::All),
        ("path_trace", Role::Sources),
        ("firefly_bound", Role::Sources),
        ("firefly_spread", Role::Sources),
        ("svgf_history", Role::Sources),
        ("svgf_temporal", Role::Sources),
        ("svgf_atrous_1", Role::Sources),
        ("svgf_atrous_2", Role::Sources),
        ("svgf_atrous_3", Role::Sources),
        ("svgf_atrous_4", Role::Sources),
        ("svgf_atrous_5", Role::Sources),
        ("reproject", Role::Targets),
        ("compact_holes", Role::Targets),
        ("hole_fill", Role::Targets),
        ("hole_temporal", Role::Targets),
        // Reads every view's `denoised`: the sources' from SVGF, the targets' from reprojection,
        // hole filling and `hole_temporal`.
        ("tonemap", Role::All),
    ];

    #[test]
    fn denoising_in_sample_space_runs_svgf_on_the_sources_before_reprojection() {
        let mut graph = KernelGraph::with_payload(topology());
        let config = PipelineConfig { denoise: Denoiser::Samples, ..PipelineConfig::default() };
        let handles = declare_pipeline(&mut graph, &config).unwrap();
        let declared: Vec<(&str, Role)> = graph.passes().iter().map(|p| (p.name.as_str(), p.role)).collect();
        assert_eq!(declared, SAMPLE_SPACE);
        let denoised = handles.denoised.as_ref().unwrap();
        assert_eq!((handles.linear, graph.name_of(denoised)), (denoised.family(), crate::svgf::DENOISED));
        // The path-tracing baseline has no targets: samples are every view's, as `Views`.
        let (mut samples, mut views) = (KernelGraph::with_payload(topology()), KernelGraph::with_payload(topology()));
        let path_trace = PipelineConfig { kind: PipelineKind::PathTrace, ..config };
        declare_pipeline(&mut samples, &path_trace).unwrap();
        declare_pipeline(&mut views, &PipelineConfig { denoise: Denoiser::Views, ..path_trace }).unwrap();
        assert_eq!(pass_names(&samples), pass_names(&views));
    }

    #[test]
    fn subsampled_hole_filling_reconstructs_after_the_trace_and_after_hole_temporal_in_sample_space() {
        let declared = |denoise| {
            let mut graph = KernelGraph::with_payload(topology());
            let config = PipelineConfig { denoise, hole_fill: HoleFillMode::Subsampled, ..PipelineConfig::default() };
            let handles = declare_pipeline(&mut graph, &config).unwrap();
            assert!(handles.subsampled_holes.is_some(), "{denoise:?}");
            let names = pass_names(&graph);
            let from = names.iter().position(|n| n == crate::holes::COMPACT_HOLES).unwrap();
            names[from..from + if denoise == Denoiser::Samples { 5 } else { 4 }].to_vec()
        };
        let reconstruct = [crate::hole_subsample::HOLE_RECONSTRUCT, crate::hole_subsample::HOLE_RECONSTRUCT_APPLY];
        assert_eq!(declared(Denoiser::Views), [["compact_holes", "hole_fill"].as_slice(), &reconstruct].concat());
        // Only the traced pixels join their means; a reconstructed pixel then shows its own.
        let samples = [["compact_holes", "hole_fill", "hole_temporal"].as_slice(), &reconstruct].concat();
        assert_eq!(declared(Denoiser::Samples), samples);
        // `Full` declares none of it.
        let mut graph = KernelGraph::with_payload(topology());
        assert!(declare_pipeline(&mut graph, &PipelineConfig::default()).unwrap().subsampled_holes.is_none());
    }

    #[test]
    fn the_sample_space_schedule_has_svgf_instances_on_sources_only_under_every_scheme() {
        use parallax_graph::{
            AssignStrategy, LayoutSpec, LightField, Partition, PartitionConfig, Rig, Scheme, compile,
        };
        let lf =
            LightField::new(LayoutSpec::Grid { cols: 4, rows: 2 }, Some(0.02), Some((16, 12)), Rig::default()).unwrap();
        for scheme in Scheme::ALL {
            for devices in [1, 3] {
                let sources = (scheme != Scheme::MultiSource).then(|| vec![1, 6]);
                let plan =
                    Partition::new(&lf, &PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources })
                        .unwrap();
                let mut graph = KernelGraph::with_payload(plan.topology.clone());
                let config = PipelineConfig { denoise: Denoiser::Samples, ..PipelineConfig::default() };
                let handles = declare_pipeline(&mut graph, &config).unwrap();
                graph.export(&handles.display);
                let schedule = compile(&graph, &plan).unwrap();
                assert!(schedule.validate().is_ok(), "{scheme:?} on {devices}: {:?}", schedule.validate());
                let is_source = &plan.topology.is_source;
                let views_of = |prefix: &str| -> std::collections::BTreeSet<u32> {
                    schedule.instances.iter().filter(|i| i.name.starts_with(prefix)).map(|i| i.view.0).collect()
                };
                let sources: std::collections::BTreeSet<u32> =
                    (0..lf.len() as u32).filter(|&v| is_source[v as usize]).collect();
                let targets: std::collections::BTreeSet<u32> =
                    (0..lf.len() as u32).filter(|&v| !is_source[v as usize]).collect();
                assert!(!sources.is_empty() && !targets.is_empty());
                for (prefix, views) in [
                    ("svgf_", &sources),
                    ("firefly_", &sources),
                    ("hole_temporal", &targets),
                    ("tonemap", &(0..8).collect()),
                ] {
                    assert_eq!(&views_of(prefix), views, "{scheme:?} on {devices} device(s): views of {prefix}*");
                }
                // Seven SVGF passes per source, each over the source's bands.
                let svgf = schedule.instances.iter().filter(|i| i.name.starts_with("svgf_")).count();
                let bands = if scheme == Scheme::MultiSource { 1 } else { devices as usize };
                assert_eq!(svgf, 7 * sources.len() * bands, "{scheme:?} on {devices} device(s)");
            }
        }
    }
}
