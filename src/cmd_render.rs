//! `parallax render`: a light field of a scene through the paper's reconstruction pipeline
//! (`--pipeline reproject`: G-buffer, path tracing of the sources, reprojection of the targets,
//! hole filling, SVGF, tonemapping) or with every view path traced (`--pipeline path-trace`, the
//! baseline), over N devices under any of the three schemes, for F frames of a still camera, a
//! dolly or the scene's glTF animation (its camera, and its skinned or node-animated meshes
//! posed at each frame's time).
//! Writes the last frame's views (EXR, linear radiance after denoising; PNG at one exposure for
//! the whole light field), the contact sheet, `viewer.html` (the views in a browser, with
//! parallax), an optional Looking Glass quilt and wiggle, and render.json with the paper's
//! Table 1 / Table 4 measures and the `setup` that comparisons check.
//!
//! The flags become [`RenderSettings`] ([`RenderArgs::settings`]) and `parallax_render::job::run`
//! renders them (a user crate calls it too, with stages of its own: `examples/auto_exposure.rs`).

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use std::time::Duration;

use anyhow::Result;
use clap::{Args, FromArgMatches as _, ValueEnum};
use parallax_backend::{Barriers, Timing};
use parallax_render::settings::{MotionRequest, RenderExtension, RenderSettings};

use crate::options::sink_parser;
use crate::options::{DeviceArgs, Exposure, UsageError, count_u32_in, parse_exposure};
use crate::pipeline_args::{DotArgs, PipelineArgs};
use crate::scene_args::{DepthArgs, LightFieldArgs, SceneArgs};
use parallax_render::outputs::Sink;

/// `--barriers`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BarrierArg {
    EveryOp,
    Tracked,
}

/// `--link`: how two devices exchange data (parallax_backend's links.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinkArg {
    /// The best each pair of devices offers.
    Auto,
    /// Logical devices of one GPU: shared device memory, GPU-side waits.
    Gpu,
    /// Logical devices of one GPU: shared device memory, signals forwarded by the host.
    Shared,
    /// Host staging memory, signals forwarded by the host.
    Relay,
}

impl LinkArg {
    /// The kind asked for (`None`: the best each pair offers).
    pub fn kind(self) -> Option<parallax_backend::LinkKind> {
        match self {
            LinkArg::Auto => None,
            LinkArg::Gpu => Some(parallax_backend::LinkKind::Gpu),
            LinkArg::Shared => Some(parallax_backend::LinkKind::Shared),
            LinkArg::Relay => Some(parallax_backend::LinkKind::Relay),
        }
    }
}

/// `--motion`: how the rig moves over the measured frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MotionArg {
    /// The scene's glTF animation when it has one (its camera's only when no `--camera` is
    /// given; its moving meshes in any case); else still.
    Auto,
    /// Still: every frame at the first frame's camera, meshes posed at t = 0.
    None,
    /// A smooth sideways dolly across 10 % of the scene, centred on the camera; meshes posed
    /// at t = 0.
    Dolly,
    /// The scene's glTF animation (camera and moving meshes), spread over the measured frames.
    Animation,
}

/// `--timing`: what the GPU timestamp pairs cover.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum TimingArg {
    PerOp,
    PerStage,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Repeat a run: a render.json (its `run`) or a TOML run file with the same keys (`spp = 4`,
    /// `lf = "8x4"`, `still = true`, ...). Flags given here as well win over the file's.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    light_field: LightFieldArgs,
    #[command(flatten)]
    devices: DeviceArgs,
    #[command(flatten)]
    pipeline: PipelineArgs,
    /// Samples per pixel of path tracing (sources, holes, or every view).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1, value_parser = count_u32_in(1..=65536))]
    spp: u32,
    #[command(flatten)]
    depth: DepthArgs,
    /// Measured frames (the rig moves over them as `--motion` says; one frame is a still
    /// camera).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    frames: u32,
    /// Frames submitted before the host waits for the oldest: the host prepares and submits the
    /// next frames while the GPU runs this one.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=8))]
    frames_in_flight: u32,
    /// Frames rendered before measuring, at the first measured frame's camera (timings and
    /// outputs ignore them). The first frame pays for pipeline creation and first-use costs
    /// (seconds on some drivers), so measuring from frame 0 with `--warmup 0` times those too.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(0..=100_000))]
    warmup: u32,
    /// How the rig and the scene move over the frames: `auto` (the scene's glTF animation when
    /// it has one — its camera's only when no --camera is given, so a camera you place stays
    /// there; skinned and animated meshes posed at each frame's time — else still), `none`,
    /// `dolly` (sideways across 10 % of the scene) or `animation`; under `none` and `dolly`
    /// meshes keep their pose of t = 0. render.json's `motion` says which ran.
    #[arg(long, value_enum, default_value_t = MotionArg::Auto)]
    motion: MotionArg,
    /// Keep the camera still over the frames and the meshes in their pose of t = 0: `--motion
    /// none`, what accuracy against a reference of the same camera needs.
    #[arg(long, conflicts_with = "motion")]
    still: bool,
    /// Also write the views of every N-th measured frame to frame_FFFFF/ under --out-dir.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    save_every: Option<u32>,
    /// Folder for view_NNN.exr and view_NNN.png, lightfield.png, viewer.html and render.json
    /// (created if missing). Every view_NNN.exr or .png already there that this run does not
    /// write is removed, so the folder holds exactly the views render.json lists; nothing
    /// changes there if the run fails.
    #[arg(long, default_value = "out/lightfield")]
    out_dir: PathBuf,
    /// Exposure of the PNGs, sheet, quilt, wiggle and viewer: `auto` (the last frame's
    /// log-average luminance over every view mapped to 0.18, computed on the host from the
    /// read-back linear views; the value is written to render.json) or a multiplier > 0 (the
    /// GPU tonemap pass's own output).
    #[arg(long, allow_negative_numbers = true, default_value = "auto", value_parser = parse_exposure)]
    exposure: Exposure,
    /// Also write an animated PNG sweeping through the views of the middle row, there and back
    /// (for slides and READMEs).
    #[arg(long, value_name = "FILE.png")]
    wiggle: Option<PathBuf>,
    /// Add the hole mask, albedo, normal and depth to every view's EXR.
    #[arg(long)]
    layers: bool,
    /// Also write a Looking Glass quilt, lightfield_qs{cols}x{rows}a{aspect}.png, of the views a
    /// device shows (a grid's row through the rig centre, left to right): `auto` (as square as
    /// the views allow; `--quilt` alone), a device's own (go 11x6, portrait 8x6, 16in 7x7, 65in
    /// 8x9; every tile shows the view nearest its place in the sweep) or COLSxROWS.
    #[arg(long, value_name = "SHAPE", num_args = 0..=1, default_missing_value = "auto",
          value_parser = parallax_render::report::images::parse_quilt)]
    quilt: Option<parallax_render::report::images::QuiltShape>,
    /// Barriers between GPU ops: `tracked` (where the compiled schedule put them, which `plan
    /// --dot` lists: only where declared accesses conflict, so the instances of one pass for
    /// many views overlap; synchronisation validation reports false hazards with it), or
    /// `every-op`.
    #[arg(long, value_enum, default_value_t = BarrierArg::Tracked)]
    barriers: BarrierArg,
    /// What each GPU timestamp pair times: `per-stage` (each run of one pass's instances; with
    /// `--barriers tracked` the instances overlap, and stage and frame times are those of the
    /// overlapped run) or `per-op` (every pass instance and copy, for per-view timelines; a
    /// timestamp drains the queue on NVIDIA, so ops cannot overlap).
    #[arg(long, value_enum, default_value_t = TimingArg::PerStage)]
    timing: TimingArg,
    /// How devices exchange data: `auto` (the best each pair offers), `gpu` (logical devices of
    /// one GPU: shared device memory and GPU-side waits), `shared` (shared device memory,
    /// signals forwarded by a host thread) or `relay` (host staging memory and forwarded
    /// signals). A kind some pair of devices cannot use is refused before any frame.
    #[arg(long, value_enum, default_value_t = LinkArg::Auto)]
    link: LinkArg,
    /// Write a Chrome trace-event JSON of the measured frames (open in Perfetto or
    /// chrome://tracing; `-` = stdout). With the default `--timing per-stage` an event is a
    /// run of one pass over many views; add `--timing per-op` for one event per view.
    #[arg(long, value_parser = sink_parser())]
    trace: Option<Sink>,
    #[command(flatten)]
    dot: DotArgs,
    /// Under mpirun (a build with `--features mpi`): how long rank 0 waits for a word from
    /// another rank (a frame done, its views) before it ends the run naming the silent rank.
    #[arg(long, value_name = "SECONDS", default_value_t = 600, value_parser = clap::value_parser!(u64).range(1..=86_400))]
    rank_timeout: u64,
}

impl RenderArgs {
    /// `render`'s arguments from the run file `path`, then the flags of the command line
    /// `invocation` (the program's name first, as `std::env::args_os()` gives it), parsed by
    /// render's own parser so that a run file is checked exactly as a command line is.
    fn of_run_file(path: &Path, invocation: impl IntoIterator<Item = OsString>) -> Result<RenderArgs> {
        let words = crate::run_file::render_words(path, invocation)?;
        let command =
            RenderArgs::augment_args(clap::Command::new("render").no_binary_name(true)).args_override_self(true);
        let matches = command.try_get_matches_from(&words).map_err(|e| {
            let text = e.to_string();
            let line = text.lines().next().unwrap_or("").trim_start_matches("error: ").to_string();
            UsageError(format!("--config {}: {line}", path.display()))
        })?;
        Ok(RenderArgs::from_arg_matches(&matches)?)
    }

    /// The settings these flags give the library (a bad `--assign` is a usage error).
    pub fn settings(&self) -> Result<RenderSettings> {
        let exposure = parallax_render::report::pictures::gpu_exposure(self.exposure);
        Ok(RenderSettings {
            scene: self.scene.settings(),
            light_field: self.light_field.settings(),
            devices: self.devices.selection(),
            pipeline: self.pipeline.settings(exposure)?,
            spp: self.spp,
            max_depth: self.depth.max_depth,
            frames: self.frames,
            frames_in_flight: self.frames_in_flight,
            warmup: self.warmup,
            motion: match (self.still, self.motion) {
                (true, _) | (false, MotionArg::None) => MotionRequest::None,
                (false, MotionArg::Auto) => MotionRequest::Auto,
                (false, MotionArg::Dolly) => MotionRequest::Dolly,
                (false, MotionArg::Animation) => MotionRequest::Animation,
            },
            save_every: self.save_every,
            out_dir: self.out_dir.clone(),
            exposure: self.exposure,
            wiggle: self.wiggle.clone(),
            layers: self.layers,
            quilt: self.quilt,
            barriers: match self.barriers {
                BarrierArg::EveryOp => Barriers::EveryOp,
                BarrierArg::Tracked => Barriers::Tracked,
            },
            timing: match self.timing {
                TimingArg::PerOp => Timing::PerOp,
                TimingArg::PerStage => Timing::PerStage,
            },
            link: self.link.kind(),
            trace: self.trace.clone(),
            dot: self.dot.dot.clone(),
            dot_detail: self.dot.dot_detail.into(),
            rank_timeout: Duration::from_secs(self.rank_timeout),
            run: self.run_file(),
        })
    }

    /// The run's settings as a run file for `--config`: every flag that shapes the pixels and
    /// the timing, by its long name, typed (outputs such as `--out-dir` are left to the command
    /// line).
    fn run_file(&self) -> serde_json::Value {
        use crate::bench_matrix::name_of as name;
        let (gpus, fake_devices) = self.devices.given();
        let camera = self.scene.camera.map(|c| c.numbers);
        let sun =
            self.scene.sun.map(|s| [s.to_sun.x, s.to_sun.y, s.to_sun.z, s.irradiance.x, s.angular_radius.to_degrees()]);
        let sky = self.scene.sky.map(|sky| match sky {
            parallax_scene::Sky::Constant(c) => c.to_array().to_vec(),
            parallax_scene::Sky::Gradient { zenith, horizon, ground } => {
                [zenith.to_array(), horizon.to_array(), ground.to_array()].concat()
            }
        });
        let (lf, p) = (&self.light_field, &self.pipeline);
        serde_json::json!({
            "scene": self.scene.scene.to_string_lossy(), "camera": camera, "sun": sun, "no_sun": self.scene.no_sun, "sky": sky,
            "lf": crate::run_file::layout_spelling(&lf.layout.lf), "spacing": lf.layout.spacing,
            "resolution": lf.layout.resolution.map(|r| format!("{}x{}", r.width, r.height)), "focus": lf.focus,
            "gpus": gpus, "fake_devices": fake_devices,
            "pipeline": name(&p.pipeline), "scheme": name(&p.scheme), "assign": p.assign.map(|a| name(&a)),
            "sources_per_set": p.sources_per_set, "sources": p.sources.as_ref().map(|s| s.0.clone()),
            "denoise": name(&p.denoise_applied()), "fireflies": name(&p.fireflies), "hole_fill": name(&p.hole_fill), "reprojection_tolerance": p.reprojection_tolerance, "spp": self.spp, "max_depth": self.depth.max_depth,
            "frames": self.frames, "warmup": self.warmup, "still": self.still, "motion": (!self.still).then(|| name(&self.motion)),
            "save_every": self.save_every,
            "exposure": match self.exposure { Exposure::Auto => serde_json::json!("auto"), Exposure::Fixed(v) => serde_json::json!(v) },
            "layers": self.layers, "quilt": self.quilt.map(|q| q.spelling()), "gbuffer": name(&p.gbuffer), "barriers": name(&self.barriers),
            "timing": name(&self.timing), "link": name(&self.link),
        })
    }
}

/// `parallax render`; the flags of the command line `invocation` (the program's name first) win
/// over those of a `--config` file.
pub fn run(args: RenderArgs, invocation: &[OsString]) -> Result<()> {
    let args = match &args.config {
        Some(file) => RenderArgs::of_run_file(file, invocation.iter().cloned())?,
        None => args,
    };
    parallax_render::job::run(&args.settings()?, RenderExtension::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `parallax render` without flags runs the library's default settings (but for render.json's
    /// `run`, which only the command line spells).
    #[test]
    fn no_flags_give_the_default_settings() {
        let command = RenderArgs::augment_args(clap::Command::new("render").no_binary_name(true));
        let args = RenderArgs::from_arg_matches(&command.try_get_matches_from(Vec::<String>::new()).unwrap()).unwrap();
        let settings = RenderSettings { run: serde_json::Value::Null, ..args.settings().unwrap() };
        assert_eq!(format!("{settings:?}"), format!("{:?}", RenderSettings::default()));
    }
}
