//! Auto-exposure on the GPU, added to the standard pipeline and run with `parallax render`'s
//! frame loop, reports and outputs. This file and its kernel, `auto_exposure.comp` beside it
//! (compiled by the root build.rs with every example's shaders), are all it takes.
//!
//! Before the tonemapper ([`InsertionPoint::BeforeTonemap`]) two passes are inserted:
//! `measure_luminance` reduces each view's linear radiance to a per-view 1×1 image (the sum of
//! the logarithms of its 8×8 tiles' mean luminance, and how many tiles are lit), and the global
//! pass `expose` reads every view's and writes one global 1×1 image: the log-average luminance
//! mapped to middle grey. The tonemapper multiplies its exposure by it ([`Layers::exposure`]).
//! Over several devices the planner copies the per-view measures to the device of `expose` and
//! the exposure to every device that tonemaps.
//!
//! After the last frame the example reads the exposure back and checks it against the host's
//! log-average of the read-back radiance (`parallax_accuracy::exposure::LogAverage`, what
//! `render --exposure auto` uses), and every display pixel against the tonemap curve at that
//! exposure.
//!
//! Run: `cargo run --example auto_exposure -- --lf 4x2 --resolution 64x48 --fake-devices 2
//! --frames 2 --exposure 1 --out-dir out/auto_exposure` (the flags of [`Cli`], each as
//! `parallax render` spells it, over `parallax_render`'s default settings; with `--exposure 1`
//! the PNGs are the GPU's display images).

use std::sync::{Arc, Mutex};

use anyhow::{Context as _, Result, ensure};
use clap::Parser;
use parallax_accuracy::exposure::{Exposure, LogAverage};
use parallax_backend::DeviceSelection;
use parallax_backend::{InstanceId, KernelGraph, PassInstance, PassKernel, Recorder};
use parallax_graph::{Format, LayoutSpec, ReadSlot, Role, Scheme, SourcesSlot, WriteSlot};
use parallax_passes::LightFieldRenderer;
use parallax_passes::pipeline::{InsertionPoint, Layers, PipelineBuilder, PipelineHandles};
use parallax_passes::tonemap::tonemap_pixel;
use parallax_render::settings::{RenderExtension, RenderSettings};

/// The kernels' push-constant structs and typed ids, generated from their SPIR-V by the
/// build (parallax-glsl); the table holds every example's kernels, this one dispatches `auto_exposure`.
#[allow(dead_code)]
mod shaders {
    parallax_backend::shader_bindings!();
}
use shaders::ExposurePush;

/// The global 1×1 image the tonemapper scales its exposure by.
const EXPOSURE: &str = "exposure";

/// `measure_luminance`: one view's radiance into its 1×1 measure (mode 0).
struct MeasureKernel {
    radiance: ReadSlot,
    measure: WriteSlot,
}

impl PassKernel for MeasureKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let src = pass.read(self.radiance)?.alloc;
        let (width, height) = (rec.resource(src).width, rec.resource(src).height);
        let push = ExposurePush {
            mode: 0,
            src: rec.image(src)?,
            dst: rec.image(pass.write(self.measure)?.alloc)?,
            width,
            height,
            ..Default::default()
        };
        rec.dispatch(shaders::AUTO_EXPOSURE, &push, [1, 1, 1])
    }
}

/// `expose`: every view's measure into the global exposure (mode 1). The measures' image
/// indices go to the shader in a buffer recorded with the command buffer.
struct ExposeKernel {
    measures: SourcesSlot,
    exposure: WriteSlot,
}

impl PassKernel for ExposeKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let images: Vec<u32> =
            pass.sources(self.measures)?.map(|a| rec.image(a.alloc)).collect::<parallax_backend::Result<_>>()?;
        let list = rec.recording_buffer("expose: measures", bytemuck::cast_slice(&images))?;
        let push = ExposurePush {
            mode: 1,
            dst: rec.image(pass.write(self.exposure)?.alloc)?,
            views: images.len() as u32,
            list: list.address(),
            ..Default::default()
        };
        rec.dispatch(shaders::AUTO_EXPOSURE, &push, [1, 1, 1])
    }
}

/// The stage inserted before the tonemapper: measure every view, expose once, hand the
/// exposure to the tonemapper.
fn declare_auto_exposure(graph: &mut KernelGraph, layers: &mut Layers) -> parallax_passes::Result<()> {
    let mut measure = graph.image_sized("view_luminance", 1, 1, Format::Rgba32f);
    let mut exposure = graph.global_image(EXPOSURE, 1, 1, Format::R32f);
    let mut pass = graph.pass("measure_luminance", Role::All);
    let kernel =
        MeasureKernel { radiance: pass.read_whole_slot(layers.linear()), measure: pass.write_slot(&mut measure) };
    pass.kernel(Arc::new(kernel)).add();
    let mut pass = graph.global_pass("expose");
    let kernel =
        ExposeKernel { measures: pass.read_every_view_slot(&measure), exposure: pass.write_slot(&mut exposure) };
    pass.kernel(Arc::new(kernel)).add();
    layers.exposure = Some(exposure);
    Ok(())
}

/// What the GPU measured in the last frame, and the host's check of it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExposureCheck {
    /// The exposure `expose` wrote.
    pub gpu: f32,
    /// `LogAverage::exposure` of the read-back linear radiance of every view.
    pub host: f32,
    /// Largest difference, in 8-bit steps, between a display pixel and the tonemap curve of
    /// the read-back radiance at the GPU's exposure.
    pub display_steps: u32,
}

/// `render`'s extension: the stage, the example's shaders, and the check after the last
/// frame, whose result lands in `check`. `exposure` is the `--exposure` the tonemapper scales.
pub fn extension(exposure: f32, check: Arc<Mutex<ExposureCheck>>) -> Result<RenderExtension> {
    let stages = |builder: PipelineBuilder| builder.insert(InsertionPoint::BeforeTonemap, declare_auto_exposure);
    Ok(RenderExtension {
        stages: Some(Box::new(stages)),
        shaders: parallax_backend::include_shaders!()?,
        after_frames: Some(Box::new(move |renderer: &mut LightFieldRenderer, handles: &PipelineHandles| {
            *check.lock().expect("not poisoned") = check_exposure(renderer, handles, exposure)?;
            Ok(())
        })),
    })
}

/// Reads the last frame's exposure, linear radiance and display images back and checks them.
fn check_exposure(
    renderer: &mut LightFieldRenderer,
    handles: &PipelineHandles,
    exposure: f32,
) -> Result<ExposureCheck> {
    let exposure_image = handles.exposure.as_ref().context("the stage declares the exposure image")?;
    let gpu = f32::from_le_bytes(renderer.read(exposure_image.family(), 0)?[..4].try_into()?);
    ensure!(gpu.is_finite() && gpu > 0.0, "the GPU exposure {gpu} is not a positive number");
    let plan = renderer.executor().plan();
    let linear = handles.linear;
    let width = plan.resources.iter().find(|r| r.family == linear).map_or(1, |r| r.width as usize);
    let views = plan.passes.iter().map(|p| p.view.0 + 1).max().unwrap_or(0);
    let mut average = LogAverage::default();
    let mut display_steps = 0;
    for v in 0..views {
        let rgb = rgb_texels(&renderer.read(linear, v)?);
        average.add_image(width, &rgb);
        let display = renderer.read(handles.display.family(), v)?;
        for (texel, pixel) in rgb.iter().zip(display.chunks_exact(4)) {
            let expected = tonemap_pixel(*texel, exposure * gpu);
            for (want, &got) in expected.iter().zip(pixel).take(3) {
                let want = (want.clamp(0.0, 1.0) * 255.0).round() as i32;
                display_steps = display_steps.max((want - i32::from(got)).unsigned_abs());
            }
        }
    }
    Ok(ExposureCheck { gpu, host: average.exposure(), display_steps })
}

/// The RGB of Rgba32f texels.
fn rgb_texels(bytes: &[u8]) -> Vec<[f32; 3]> {
    bytemuck::pod_collect_to_vec::<u8, f32>(bytes).chunks_exact(4).map(|t| [t[0], t[1], t[2]]).collect()
}

/// The render's settings that the example takes, spelt as `parallax render`'s flags.
#[derive(Parser, Debug)]
#[command(about = "parallax render with a GPU auto-exposure pass before the tonemapper")]
pub struct Cli {
    /// Light-field layout: multiscopic, nelf or WxH.
    #[arg(long, default_value = "8x4")]
    lf: LayoutSpec,
    /// Per-view resolution WxH (default: the preset's).
    #[arg(long, value_parser = parse_size)]
    resolution: Option<(u32, u32)>,
    /// Spacing between neighbouring views in metres (default: the layout's).
    #[arg(long)]
    spacing: Option<f64>,
    /// N logical devices on one GPU (default: the first GPU alone).
    #[arg(long)]
    fake_devices: Option<usize>,
    /// multi-source, fine-sources or fine-all.
    #[arg(long, default_value = "multi-source")]
    scheme: Scheme,
    /// Measured frames.
    #[arg(long, default_value_t = 1)]
    frames: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 1)]
    spp: u32,
    /// `auto` or a multiplier of the pictures' exposure.
    #[arg(long, default_value = "auto")]
    exposure: Exposure,
    /// Folder of the views, viewer.html and render.json.
    #[arg(long, default_value = "out/auto_exposure")]
    out_dir: std::path::PathBuf,
}

/// `WxH`.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once('x').ok_or("expected WxH")?;
    Ok((w.parse().map_err(|_| "a bad width")?, h.parse().map_err(|_| "a bad height")?))
}

impl Cli {
    /// The library's default settings with these flags applied.
    pub fn settings(&self) -> RenderSettings {
        let mut settings = RenderSettings::default();
        settings.light_field.layout.lf = self.lf;
        settings.light_field.layout.resolution = self.resolution;
        settings.light_field.layout.spacing = self.spacing;
        if let Some(n) = self.fake_devices {
            settings.devices = DeviceSelection::FakeDevices(n);
        }
        settings.pipeline.scheme = self.scheme;
        settings.pipeline.config.exposure = parallax_render::report::pictures::gpu_exposure(self.exposure);
        (settings.frames, settings.spp, settings.exposure) = (self.frames, self.spp, self.exposure);
        settings.out_dir = self.out_dir.clone();
        settings
    }
}

fn main() {
    if let Err(err) = run(&Cli::parse().settings()) {
        eprintln!("error: {err:#}");
        std::process::exit(1);
    }
}

fn run(settings: &RenderSettings) -> Result<()> {
    let check = Arc::new(Mutex::new(ExposureCheck::default()));
    parallax_render::job::run(settings, extension(settings.tonemap_exposure(), check.clone())?)?;
    let check = *check.lock().expect("not poisoned");
    println!(
        "GPU exposure {:.6}, host log-average {:.6}; display within {} step(s) of the curve",
        check.gpu, check.host, check.display_steps
    );
    Ok(())
}
