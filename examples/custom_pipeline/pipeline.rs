//! The pipeline of the `custom_pipeline` example, as a module its integration test
//! (tests/example_custom_pipeline.rs) runs too.
//!
//! Two passes with their own kernels and GLSL (this folder, compiled by the root build.rs):
//! `pattern` writes a procedural pattern into `radiance` on every view; `blend` runs on every
//! target, reads its own `radiance` and its sources' (`read_sources`: the δ-edges, which become
//! cross-device copies where a source sits on another device) and writes the next version of
//! `radiance`. The finished views are gathered on device 0, compared with the same computation on
//! the CPU and written as a PNG contact sheet.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context as _, Result, bail, ensure};
use glam::Vec3;
use parallax_backend::{
    AllocId, BackendError, Compiled, Context, ContextDesc, DeviceId, DeviceSelection, ExecOptions, Executor, FamilyId,
    InstanceId, KernelGraph, PassInstance, PassKernel, Recorder, Validation,
};
use parallax_graph::{
    AssignStrategy, Format, LightField, Partition, PartitionConfig, ReadSlot, Rig, Role, Scheme, SourcesSlot,
    WriteSlot, compile,
};
use parallax_scene::output::write_contact_sheet;
use parallax_scene::{Frame, PixelSample};

/// The kernels' push-constant structs and typed ids, generated from their SPIR-V by the
/// build (parallax-glsl); the table holds every example's kernels, this one dispatches `pattern` and `blend`.
#[allow(dead_code)]
mod shaders {
    parallax_backend::shader_bindings!();
}
use shaders::BlendParams;

/// Light field of the example: 4×2 views of 64×32.
const LAYOUT: &str = "4x2";
const RESOLUTION: (u32, u32) = (64, 32);
/// Sources one target can blend (`MAX_SOURCES` in blend.comp).
const MAX_SOURCES: usize = 4;
const RADIANCE: &str = "radiance";

/// What to run.
#[derive(Clone, Debug)]
pub struct Options {
    pub devices: DeviceSelection,
    /// Khronos validation (`validation_from_env()`: on with PARALLAX_VALIDATION=1).
    pub validation: Validation,
    pub scheme: Scheme,
    /// Where the contact sheet of every view goes.
    pub out: PathBuf,
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct Report {
    pub views: usize,
    pub instances: usize,
    pub delta_edges: usize,
    pub copies: usize,
    /// Width and height of the PNG written.
    pub png_size: (u32, u32),
}

/// Pass `pattern`: `pattern.comp` into its `radiance` write over the instance's rows.
struct PatternKernel {
    radiance: WriteSlot,
}

impl PassKernel for PatternKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let dst = pass.write(self.radiance)?.alloc;
        let params = rec.row_params(pass, dst)?;
        rec.dispatch_rows(shaders::PATTERN, params)
    }
}

/// Pass `blend`: `blend.comp` with the target's own `radiance` and every source's.
struct BlendKernel {
    own: ReadSlot,
    sources: SourcesSlot,
    blended: WriteSlot,
    /// Views per row of the grid, for the disparity of a source.
    cols: u32,
}

impl PassKernel for BlendKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let (own, dst) = (pass.read(self.own)?, pass.write(self.blended)?);
        let width = rec.resource(dst.alloc).width;
        let mut params = BlendParams {
            dst: rec.image(dst.alloc)?,
            own: rec.image(own.alloc)?,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            ..Default::default()
        };
        for (i, source) in pass.sources(self.sources)?.enumerate() {
            if i == MAX_SOURCES {
                return Err(misuse("blend", index, &format!("blends at most {MAX_SOURCES} sources")));
            }
            params.source_image[i] = rec.image(source.alloc)?;
            params.shift[i] = shift(pass.view.0, rec.resource(source.alloc).view, self.cols, width);
            params.sources += 1;
        }
        rec.dispatch(shaders::BLEND, &params, [width.div_ceil(8), pass.region.len().div_ceil(8), 1])
    }
}

fn misuse(kernel: &str, instance: InstanceId, detail: &str) -> BackendError {
    BackendError::KernelMisuse { kernel: kernel.into(), instance: Some(instance), detail: detail.into() }
}

/// Columns by which `target` samples `source`: its distance in the grid, as a disparity.
fn shift(target: u32, source: u32, cols: u32, width: u32) -> u32 {
    let (tc, tr) = (target % cols, target / cols);
    let (sc, sr) = (source % cols, source / cols);
    (4 * tc.abs_diff(sc) + 2 * tr.abs_diff(sr)) % width
}

/// `pattern.comp` on the CPU.
fn pattern(x: u32, y: u32, view: u32) -> [f32; 4] {
    let stripes = ((x + 5 * view) & 31) as f32 * (1.0 / 32.0);
    let bands = ((3 * y + view) & 15) as f32 * (1.0 / 16.0);
    let checker = (((x >> 3) ^ (y >> 3) ^ view) & 1) as f32;
    [stripes, bands, checker, 1.0]
}

/// The finished `radiance` of `view` on the CPU: the pattern of a source, the blend of a target.
fn expected(x: u32, y: u32, view: u32, sources: &[u32], lf: &LightField) -> [f32; 4] {
    let own = pattern(x, y, view);
    if sources.is_empty() {
        return own;
    }
    let seen = sources.iter().fold([0.0f32; 4], |seen, &s| {
        let p = pattern((x + shift(view, s, lf.cols, lf.width)) % lf.width, y, s);
        std::array::from_fn(|c| seen[c].max(p[c]))
    });
    [0.5 * own[0] + 0.5 * seen[0], 0.5 * own[1] + 0.5 * seen[1], 0.5 * own[2] + 0.5 * seen[2], 1.0]
}

/// The light field, the planner's placement, the declared graph and its radiance's family.
fn declare(scheme: Scheme, devices: u32) -> Result<(LightField, Partition, KernelGraph, FamilyId)> {
    let lf = LightField::new(LAYOUT.parse()?, None, Some(RESOLUTION), Rig::default())?;
    let config = PartitionConfig { devices, scheme, assign: AssignStrategy::Compact, sources: None };
    let partition = Partition::new(&lf, &config)?;
    let mut graph = KernelGraph::with_payload(partition.topology.clone());
    let mut radiance = graph.image(RADIANCE, Format::Rgba32f);
    let mut pass = graph.pass("pattern", Role::All);
    let pattern = PatternKernel { radiance: pass.write_slot(&mut radiance) };
    pass.kernel(Arc::new(pattern)).add();
    let mut pass = graph.pass("blend", Role::Targets);
    let own = pass.read_slot(&radiance);
    let sources = pass.read_sources_slot(&radiance); // the δ-edges
    let blended = pass.write_slot(&mut radiance);
    pass.kernel(Arc::new(BlendKernel { own, sources, blended, cols: lf.cols })).add();
    graph.export(&radiance);
    Ok((lf, partition, graph, radiance.family()))
}

/// The schedule over `devices` devices as DOT (no GPU needed).
pub fn schedule_dot(scheme: Scheme, devices: u32) -> Result<String> {
    let (_, partition, graph, _) = declare(scheme, devices)?;
    Ok(compile(&graph, &partition)?.to_dot())
}

/// Runs the pipeline on the devices, checks every pixel against the CPU and writes the PNG.
pub fn run(options: &Options) -> Result<Report> {
    let (lf, partition, graph, radiance) = declare(options.scheme, options.devices.count() as u32)?;
    // Compiling proves the schedule (its invariants hold) before the executor's plan is built from it.
    let Compiled { schedule, plan: exec_plan } = Compiled::compile(&graph, &partition)?;
    let shaders = parallax_backend::include_shaders!()?;

    let context = Context::new(&ContextDesc { selection: options.devices, validation: options.validation })?;
    let outputs: Vec<(DeviceId, AllocId)> = lf
        .views()
        .map(|v| exec_plan.final_output(radiance, v.0).with_context(|| format!("view {} has no `radiance`", v.0)))
        .collect::<Result<_>>()?;
    let copies = exec_plan.copies.len();
    let mut executor = Executor::new(&context, exec_plan, ExecOptions { shaders, ..ExecOptions::default() })?;
    executor.run_frame()?;
    executor.finish()?;
    let mut frames = Vec::with_capacity(outputs.len());
    for (view, &(device, resource)) in outputs.iter().enumerate() {
        let bytes = executor.read_resource(device, resource)?;
        let view = view as u32;
        frames.push(check_view(&bytes, view, &partition.topology.sources_of[view as usize], &lf)?);
    }
    drop(executor);
    context.check_validation()?;

    if let Some(dir) = options.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    write_contact_sheet(&options.out, &frames.iter().collect::<Vec<_>>(), lf.cols, 1.0)?;
    Ok(Report {
        views: frames.len(),
        instances: schedule.instances.len(),
        delta_edges: schedule.delta_edges.len(),
        copies,
        png_size: png_size(&lf),
    })
}

/// Compares the RGBA32F `bytes` of `view` with [`expected`]; returns it as a frame to draw.
fn check_view(bytes: &[u8], view: u32, sources: &[parallax_graph::ViewId], lf: &LightField) -> Result<Frame> {
    let sources: Vec<u32> = sources.iter().map(|s| s.0).collect();
    let texels: Vec<f32> = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    ensure!(texels.len() == (lf.width * lf.height * 4) as usize, "view {view}: read back {} bytes", bytes.len());
    let mut pixels = Vec::with_capacity((lf.width * lf.height) as usize);
    for (i, gpu) in texels.chunks_exact(4).enumerate() {
        let (x, y) = (i as u32 % lf.width, i as u32 / lf.width);
        let cpu = expected(x, y, view, &sources, lf);
        if gpu != cpu {
            bail!(
                "view {view}, pixel ({x}, {y}): the GPU wrote {gpu:?}, the CPU computes {cpu:?} (sources {sources:?})"
            );
        }
        let radiance = Vec3::new(gpu[0], gpu[1], gpu[2]);
        pixels.push(PixelSample { radiance, ..PixelSample::default() });
    }
    Ok(Frame { width: lf.width, height: lf.height, pixels })
}

/// Size of the contact sheet `write_contact_sheet` draws: the grid with 2-pixel gaps.
fn png_size(lf: &LightField) -> (u32, u32) {
    (lf.cols * lf.width + (lf.cols - 1) * 2, lf.rows * lf.height + (lf.rows - 1) * 2)
}
