//! The options that decide what `render` runs — pipeline, G-buffer source, denoising, scheme,
//! assignment, sources — declared once and flattened into `plan` and `render`, and the one
//! function both compile their schedule with: `plan` shows exactly the schedule `render` runs
//! with the same flags. Declaring the pipeline's kernel graph needs no device, so `plan` runs
//! without a GPU.

use anyhow::Result;
use clap::{Args, ValueEnum};
use parallax_graph::{LightField, Schedule, SourcesPerSet};
use parallax_passes::firefly::FireflyMode;
use parallax_passes::hole_subsample::HoleFillMode;
use parallax_passes::pipeline::{Denoiser, GbufferSource, PipelineConfig, PipelineKind};
use parallax_passes::reproject::ReprojectionTolerances;
use parallax_render::compile::{PipelineSchedule, PipelineSettings};

use crate::options::sink_parser;
use crate::options::{AssignArg, DotDetail, SchemeArg, SourceList, UsageError, assignment, parse_sources};
use parallax_render::outputs::Sink;

/// `--pipeline`: what renders the views.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PipelineArg {
    /// The paper's: sources path traced, targets reprojected and their holes filled.
    Reproject,
    /// Every view path traced (the baseline).
    PathTrace,
}

impl From<PipelineArg> for PipelineKind {
    fn from(p: PipelineArg) -> PipelineKind {
        match p {
            PipelineArg::Reproject => PipelineKind::Reproject,
            PipelineArg::PathTrace => PipelineKind::PathTrace,
        }
    }
}

/// `--gbuffer`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GbufferArg {
    FirstHits,
    Raster,
    Visibility,
}

impl From<GbufferArg> for GbufferSource {
    fn from(g: GbufferArg) -> GbufferSource {
        match g {
            GbufferArg::FirstHits => GbufferSource::FirstHits,
            GbufferArg::Raster => GbufferSource::Raster,
            GbufferArg::Visibility => GbufferSource::Visibility,
        }
    }
}

/// `--fireflies`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum FirefliesArg {
    Suppress,
    Keep,
}

impl From<FirefliesArg> for FireflyMode {
    fn from(f: FirefliesArg) -> FireflyMode {
        match f {
            FirefliesArg::Suppress => FireflyMode::Suppress,
            FirefliesArg::Keep => FireflyMode::Keep,
        }
    }
}

/// `--denoise`: where SVGF runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DenoiseArg {
    /// SVGF over every view after reconstruction.
    Views,
    /// SVGF over the sources before reprojection, targets reproject the denoised radiance and
    /// accumulate their hole pixels.
    Samples,
    /// No denoising (and no firefly suppression).
    None,
}

impl From<DenoiseArg> for Denoiser {
    fn from(d: DenoiseArg) -> Denoiser {
        match d {
            DenoiseArg::Views => Denoiser::Views,
            DenoiseArg::Samples => Denoiser::Samples,
            DenoiseArg::None => Denoiser::None,
        }
    }
}

/// `--hole-fill`: which hole pixels are path traced each frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum HoleFillArg {
    /// Every hole pixel, every frame.
    Full,
    /// One hole pixel of each 2×2 block per frame, taking turns; the others reconstructed from
    /// traced neighbours on the same surface (isolated holes always traced).
    Subsampled,
}

impl From<HoleFillArg> for HoleFillMode {
    fn from(h: HoleFillArg) -> HoleFillMode {
        match h {
            HoleFillArg::Full => HoleFillMode::Full,
            HoleFillArg::Subsampled => HoleFillMode::Subsampled,
        }
    }
}

/// The pipeline and its placement. The field names are the clap ids that `bench` checks with
/// `value_source`.
#[derive(Args, Debug, Clone)]
pub struct PipelineArgs {
    /// What renders the views.
    #[arg(long, value_enum, default_value_t = PipelineArg::Reproject)]
    pub pipeline: PipelineArg,
    /// Where the G-buffer comes from: first hits of the pixel-centre rays (fast on compute GPUs
    /// such as the H200), rasterised (the paper's way; fast with fixed-function raster), or a
    /// compute visibility buffer of 64-bit atomics resolved into the first-hit G-buffer (no
    /// tracing; render falls back to first hits, and says so in render.json, on devices without
    /// shaderBufferInt64Atomics).
    #[arg(long, value_enum, default_value_t = GbufferArg::FirstHits)]
    pub gbuffer: GbufferArg,
    /// Where SVGF runs: over every view after reconstruction (`views`), over the path-traced
    /// samples (`samples`: the sources before reprojection, then each target's hole pixels
    /// accumulated over frames), or nowhere (`none`: the display shows the radiance after
    /// reprojection and hole filling).
    #[arg(long, value_enum, default_value_t = DenoiseArg::Views)]
    pub denoise: DenoiseArg,
    /// The same as `--denoise none` (kept for older command lines and run files).
    #[arg(long, conflicts_with = "denoise")]
    pub no_denoise: bool,
    /// Before denoising, a pixel brighter than its 5×5 neighbourhood's mean + 3 standard
    /// deviations (luminance; × √n on a still camera's n-th frame, so it fades as the image
    /// converges) keeps that bound and shares the rest among its neighbours (`suppress`: each
    /// view's per-channel sum unchanged), or the radiance stays as traced (`keep`). Suppression
    /// belongs to denoising: with `--no-denoise` the radiance always stays as traced.
    #[arg(long, value_enum, default_value_t = FirefliesArg::Suppress)]
    pub fireflies: FirefliesArg,
    /// Which of the targets' hole pixels are path traced each frame: all of them (`full`), or,
    /// where holes are dense, one of each 2×2 block of hole pixels per frame, taking turns, the
    /// others reconstructed from traced neighbours whose G-buffer normal and depth agree
    /// (`subsampled`: holes without such a neighbour are traced; docs/PIPELINE.md).
    #[arg(long, value_enum, default_value_t = HoleFillArg::Full)]
    pub hole_fill: HoleFillArg,
    /// Partitioning scheme.
    #[arg(long, value_enum, default_value_t = SchemeArg::MultiSource)]
    pub scheme: SchemeArg,
    /// How views are grouped into sets (multi-source only) [default: compact]
    #[arg(long, value_enum)]
    pub assign: Option<AssignArg>,
    /// Sources per set (multi-source, the paper's k_s), 1 to 64, or `auto`: per set, the number
    /// and places that minimise the predicted frame time (path tracing a source against the
    /// holes it removes; at least one per connected block of the layout, one per eye for NELF).
    /// Each target reprojects from the nearest source of its set.
    #[arg(long, default_value = "auto", value_parser = parse_sources_per_set)]
    pub sources_per_set: SourcesPerSetArg,
    /// The fine schemes' sources, view indices, e.g. 0,99 (default: k = N placed as in the paper).
    #[arg(long, value_parser = parse_sources)]
    pub sources: Option<SourceList>,
    /// Largest relative radiance error that view-dependence may cause in a reprojected pixel
    /// (the bound of docs/PIPELINE.md, from the angle between target and source view
    /// directions, the GGX lobe width and Fresnel); pixels over it are holes, path traced.
    /// 0 reuses only sources at the target's own position.
    #[arg(long, allow_negative_numbers = true, default_value_t = parallax_render::compile::default_reprojection_tolerance(),
          value_parser = parse_reprojection_tolerance)]
    pub reprojection_tolerance: f64,
}

/// `--sources-per-set`: `auto` or a count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SourcesPerSetArg(pub SourcesPerSet);

impl serde::Serialize for SourcesPerSetArg {
    /// `"auto"` or the count, as the flag is spelt (render.json, run files).
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self.0 {
            SourcesPerSet::Auto => s.serialize_str("auto"),
            SourcesPerSet::Count(n) => s.serialize_u32(n),
        }
    }
}

/// The most sources per set a count may ask for.
const MAX_SOURCES_PER_SET: u32 = 64;

/// `--sources-per-set`: `auto`, or a count from 1 to 64.
pub fn parse_sources_per_set(s: &str) -> Result<SourcesPerSetArg, String> {
    match s.trim() {
        "auto" => Ok(SourcesPerSetArg(SourcesPerSet::Auto)),
        t => match t.parse::<u32>() {
            Ok(n) if (1..=MAX_SOURCES_PER_SET).contains(&n) => Ok(SourcesPerSetArg(SourcesPerSet::Count(n))),
            _ => Err(format!("'{s}' is neither `auto` nor a count of sources from 1 to {MAX_SOURCES_PER_SET}")),
        },
    }
}

/// `--reprojection-tolerance`: a relative error, finite and at least 0.
pub fn parse_reprojection_tolerance(s: &str) -> Result<f64, String> {
    s.trim().parse::<f64>().map_err(|_| format!("'{s}' is not a number")).and_then(check_reprojection_tolerance)
}

/// A reprojection tolerance is a relative error: finite (also as the shader's f32) and at least 0.
pub fn check_reprojection_tolerance(v: f64) -> Result<f64, String> {
    if (v as f32).is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not a relative error >= 0 and < 3.4e38 (0.2 = 20 %)"))
    }
}

/// `--dot` and `--dot-detail`: the schedule drawn for Graphviz.
#[derive(Args, Debug, Clone)]
pub struct DotArgs {
    /// Write the schedule as Graphviz DOT (.dot or .gv; `-` = stdout).
    #[arg(long, value_parser = sink_parser())]
    pub dot: Option<Sink>,
    /// How much of the schedule the DOT shows.
    #[arg(long, value_enum, default_value_t = DotDetail::Auto)]
    pub dot_detail: DotDetail,
}

impl DotArgs {
    /// The DOT text to write, if `--dot` was given.
    pub fn render(&self, schedule: &Schedule) -> Option<String> {
        self.dot.as_ref().map(|_| parallax_render::compile::DotDetail::from(self.dot_detail).render(schedule))
    }
}

impl PipelineArgs {
    /// Refuses flags that do not go together (a usage error), before any work.
    pub fn check(&self) -> Result<(), UsageError> {
        assignment(self.scheme, self.assign).map(|_| ())
    }

    /// Where these flags denoise: `--denoise`, or `none` with `--no-denoise`.
    pub fn denoise_applied(&self) -> DenoiseArg {
        if self.no_denoise { DenoiseArg::None } else { self.denoise }
    }

    /// What `--fireflies` does with these flags: without denoising the display is the radiance
    /// as traced (`--denoise none`), so nothing is suppressed and no G-buffer is computed for it.
    pub fn fireflies_applied(&self) -> FirefliesArg {
        if self.denoise_applied() == DenoiseArg::None { FirefliesArg::Keep } else { self.fireflies }
    }

    /// The pipeline declaration these flags ask for.
    pub fn config(&self, exposure: f32) -> PipelineConfig {
        PipelineConfig {
            kind: self.pipeline.into(),
            gbuffer: self.gbuffer.into(),
            tolerances: ReprojectionTolerances {
                view_dependence: self.reprojection_tolerance as f32,
                ..Default::default()
            },
            fireflies: self.fireflies_applied().into(),
            denoise: self.denoise_applied().into(),
            hole_fill: self.hole_fill.into(),
            exposure,
        }
    }

    /// The pipeline and placement these flags ask for, the GPU's tonemap at `exposure`.
    pub fn settings(&self, exposure: f32) -> Result<PipelineSettings, UsageError> {
        Ok(PipelineSettings {
            config: self.config(exposure),
            scheme: self.scheme.into(),
            assign: assignment(self.scheme, self.assign)?,
            sources: self.sources.as_ref().map(|s| s.0.clone()),
            sources_per_set: self.sources_per_set.0,
            reprojection_tolerance: self.reprojection_tolerance,
        })
    }

    /// Plans `lf` over `devices` and compiles the standard pipeline into its schedule and the
    /// plan that executes it ([`PipelineSettings::compile_with`]).
    pub fn compile(&self, lf: &LightField, devices: u32, exposure: f32) -> Result<PipelineSchedule> {
        self.settings(exposure)?.compile_with(lf, devices, &|builder| builder)
    }
}
