//! Preparing a render: everything decided before a device is touched. The flags are checked
//! together, the outputs can be written, the work fits the host, the pipeline (with a user
//! crate's stages) is compiled as `plan` compiles it, the scene is loaded and the camera of
//! every frame is known.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use glam::Vec3;
use parallax_backend::DeviceInfo;
use parallax_graph::{LightField, Rig};
use parallax_passes::pipeline::{PipelineBuilder, PipelineKind};
use parallax_passes::visibility::{GbufferChoice, choose_gbuffer};
use parallax_scene::animation::CameraAnimation;
use parallax_scene::{Camera, Scene, TraceSettings};

use crate::compile::PipelineSchedule;
use crate::outputs::budget::{TraceWork, refuse_every_exceeded};
use crate::outputs::disk::{RenderOutputs, free_bytes};
use crate::outputs::{Format, Output, Sink, check_creating};
use crate::report::startup::{Startup, Step};
use crate::settings::{MotionRequest, RenderSettings};

/// A render, planned: what the frame loop runs and the report describes.
pub(super) struct RenderJob {
    pub sheet: PathBuf,
    pub render_json: PathBuf,
    pub trace_settings: TraceSettings,
    /// Warm-up and measured frames.
    pub total_frames: u32,
    /// The views of one frame over the frames (memory is per frame: the frames reuse the same
    /// images).
    pub one_frame: TraceWork,
    pub compiled: PipelineSchedule,
    /// `--dot`'s text, drawn from the schedule that runs.
    pub dot: Option<String>,
    pub scene: Scene,
    /// The camera of the first measured frame.
    pub camera: Camera,
    /// How the rig moves over the measured frames, resolved against the scene.
    pub motion: Motion,
    /// The views' spacing over every frame (None: the preset's): `--spacing`, or a grid's
    /// default for the first measured frame's rig, kept as the rig moves.
    pub spacing: Option<f64>,
    centre: Vec3,
    /// Whether this process writes the outputs (a rank other than 0 of a render over several
    /// ranks does not).
    pub writes_outputs: bool,
    /// A rank of a render over several ranks: what it runs.
    pub rank: Option<crate::ranks::RankPart>,
    /// Every frame's camera as rank 0 sent it (None: computed here).
    pub cameras: Option<Vec<Camera>>,
    /// When each step of the start ended (render.json's `startup`).
    pub startup: Startup,
    /// The G-buffer asked for and the one that runs (render.json's `gbuffer`): what `--gbuffer`
    /// asked for until the devices are known ([`RenderJob::choose_gbuffer`]).
    pub gbuffer: GbufferChoice,
}

/// The motion that runs (`--motion` resolved against the scene and `--camera`).
pub(super) enum Motion {
    Still,
    Dolly,
    /// The scene's glTF animation, its whole length spread over the measured frames: the camera
    /// follows its own animation when it has one (None: the camera stays), and moving meshes
    /// ([`Scene::geometry_moves`]) are posed at each frame's time.
    Animation {
        camera: Option<CameraAnimation>,
        duration: f32,
    },
}

impl Motion {
    /// The motion asked for, for this scene: `auto` is the glTF animation when the scene has
    /// one, its camera's part only when the user placed no camera (`placed`), so a `--camera`
    /// stays where it was put while the scene's meshes move; one measured frame of `frames` is
    /// still.
    fn resolve(request: MotionRequest, placed: bool, frames: u32, scene: &Scene) -> Result<Motion> {
        let geometry = scene.geometry_animation.as_ref().map(|a| a.duration());
        let animation = |camera: Option<CameraAnimation>| {
            let duration = camera.as_ref().map(|c| c.duration).into_iter().chain(geometry).reduce(f32::max);
            duration.map(|duration| Motion::Animation { camera, duration })
        };
        let motion = match request {
            MotionRequest::None => Motion::Still,
            MotionRequest::Dolly => Motion::Dolly,
            MotionRequest::Auto => {
                animation(scene.camera_animation.clone().filter(|_| !placed)).unwrap_or(Motion::Still)
            }
            MotionRequest::Animation if placed && scene.camera_animation.is_some() => {
                return Err(crate::error::UsageError(
                    "--motion animation moves the scene's own camera, so --camera would be ignored: drop --camera, or \
                     use --motion dolly to move the camera you give"
                        .into(),
                )
                .into());
            }
            MotionRequest::Animation => match animation(scene.camera_animation.clone()) {
                Some(motion) => motion,
                None => bail!(
                    "--motion animation: scene '{}' has no animation of its camera or meshes; use --motion dolly or \
                     --motion none",
                    scene.name
                ),
            },
        };
        // One measured frame is a still camera whatever the motion.
        Ok(if frames == 1 { Motion::Still } else { motion })
    }

    /// render.json's `motion`.
    pub fn name(&self) -> &'static str {
        match self {
            Motion::Still => "none",
            Motion::Dolly => "dolly",
            Motion::Animation { .. } => "animation",
        }
    }

    /// Whether the scene's meshes move over the frames: the glTF animation runs and moves them.
    pub fn moves_geometry(&self, scene: &Scene) -> bool {
        matches!(self, Motion::Animation { .. }) && scene.geometry_moves()
    }
}

impl RenderJob {
    /// Decides which G-buffer runs on `devices` ([`choose_gbuffer`]): where `--gbuffer
    /// visibility` lacks 64-bit buffer atomics, the pipeline is compiled again with first hits
    /// (the same images, traced), and the reason is kept for render.json. A rank of a render
    /// over several ranks refuses instead: every rank must run one schedule.
    pub fn choose_gbuffer(
        &mut self,
        settings: &RenderSettings,
        extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder,
        devices: &[DeviceInfo],
    ) -> Result<()> {
        let choice = choose_gbuffer(settings.pipeline.config.gbuffer, devices);
        if let Some(reason) = &choice.fallback {
            if self.rank.is_some() {
                bail!(
                    "--gbuffer visibility: {reason}, and every rank of a render over several ranks must run the same                      schedule: pass --gbuffer first-hits"
                );
            }
            tracing::warn!("--gbuffer visibility: {reason}");
            let mut pipeline = settings.pipeline.clone();
            pipeline.config.gbuffer = choice.runs;
            let sized = settings.light_field.with_rig(Rig::default())?;
            let devices = self.compiled.summary.devices;
            self.compiled = pipeline.compile_with(&sized, devices, extend)?;
            self.dot = settings.dot.as_ref().map(|_| settings.dot_detail.render(&self.compiled.schedule));
        }
        self.gbuffer = choice;
        Ok(())
    }

    /// Checks `settings` and plans the run over `devices` devices (every rank's, in a render over
    /// several ranks), the pipeline extended by `extend`; only a process that `writes_outputs`
    /// checks them.
    pub fn prepare(
        settings: &RenderSettings,
        extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder,
        devices: u32,
        writes_outputs: bool,
    ) -> Result<RenderJob> {
        let mut startup = Startup::start();
        let sheet = settings.out_dir.join("lightfield.png");
        let render_json = settings.out_dir.join("render.json");
        let (trace, dot) = (settings.trace.as_ref(), settings.dot.as_ref());
        if writes_outputs {
            check_outputs(&settings.out_dir, &sheet, &render_json, trace, dot, settings.wiggle.as_deref())?;
        }
        let trace_settings = TraceSettings { spp: settings.spp, max_depth: settings.max_depth, ..Default::default() };
        trace_settings.validate()?;
        let total_frames = settings.warmup + settings.frames;
        let sized = settings.light_field.with_rig(Rig::default())?;
        if settings.quilt.is_some() {
            // Refused before any frame: NELF holds no one sweep for a Looking Glass.
            crate::report::images::quilt_views(sized.cols, sized.rows, sized.name == "nelf")?;
        }
        if writes_outputs {
            crate::outputs::check_targets_in(
                &settings.out_dir,
                (0..sized.len() as u32).map(view_file_name),
                "--out-dir",
            )?;
        }
        let one_frame = TraceWork {
            views: sized.len() as u64,
            frames: u64::from(total_frames),
            width: sized.width,
            height: sized.height,
            spp: settings.spp,
            devices: u64::from(devices),
            views_flag: "--lf",
            frames_flag: "--frames, --warmup",
        };
        // At most: the pipeline may compute fewer layers (path tracing without denoising none).
        let (layers, holes) =
            (settings.layers, settings.layers && settings.pipeline.config.kind == PipelineKind::Reproject);
        let outputs = RenderOutputs {
            views: sized.len() as u64,
            width: sized.width,
            height: sized.height,
            channels: 3 + if layers { 7 } else { 0 } + u64::from(holes),
            frames: settings.frames,
            save_every: settings.save_every,
            layer_pictures: u64::from(layers) + u64::from(holes),
            quilt: settings.quilt.is_some(),
        };
        let disk = free_bytes(&settings.out_dir)
            .filter(|_| writes_outputs)
            .map(|free| outputs.check_fits(&settings.out_dir, free));
        refuse_every_exceeded([
            settings.pipeline.check_plan_size(&sized, devices),
            one_frame.check_duration(),
            one_frame.check_host(),
            disk.unwrap_or(Ok(())),
        ])?;
        // Planned from the layout alone, as `plan` plans it: the schedule depends on the views'
        // positions in the rig plane, not on where the rig stands.
        let compiled = settings.pipeline.compile_with(&sized, devices, extend)?;
        let dot = settings.dot.as_ref().map(|_| settings.dot_detail.render(&compiled.schedule));
        startup.ended(Step::Planned);

        let scene = settings.scene.load()?;
        startup.ended(Step::SceneLoaded);
        let mut written = vec![("--out-dir", render_json.as_path()), ("--out-dir", sheet.as_path())];
        if let Some(crate::outputs::Sink::File(trace)) = &settings.trace {
            written.push(("--trace", trace.as_path()));
        }
        if writes_outputs {
            crate::outputs::check_inputs(&written, &settings.scene.inputs(&scene))?;
        }
        let camera = settings.scene.camera_or_default(&scene);
        let centre = scene.bounds().center();
        let motion = Motion::resolve(settings.motion, settings.scene.camera.is_some(), settings.frames, &scene)?;
        tracing::info!("motion over the {} measured frame(s): {}", settings.frames, motion.name());
        let mut job = RenderJob {
            sheet,
            render_json,
            trace_settings,
            total_frames,
            one_frame,
            compiled,
            dot,
            scene,
            camera,
            motion,
            spacing: None,
            centre,
            writes_outputs,
            rank: None,
            cameras: None,
            startup,
            gbuffer: GbufferChoice {
                requested: settings.pipeline.config.gbuffer,
                runs: settings.pipeline.config.gbuffer,
                fallback: None,
            },
        };
        let first = &settings.light_field;
        job.spacing = first.layout.spacing_on(&first.rig_around(&job.camera_at(settings, 0), job.centre));
        Ok(job)
    }

    /// The animation time of frame `f`, seconds: under the glTF animation its whole length spread
    /// over the measured frames, else 0, the time the scene was loaded at. Warm-up frames have
    /// the first measured frame's.
    pub fn time_at(&self, settings: &RenderSettings, f: u32) -> f32 {
        let m = f.saturating_sub(settings.warmup);
        match &self.motion {
            Motion::Animation { duration, .. } => duration * m as f32 / settings.frames.saturating_sub(1).max(1) as f32,
            Motion::Still | Motion::Dolly => 0.0,
        }
    }

    /// The camera of frame `f`. Warm-up frames see the first measured frame's camera, so one
    /// measured frame is a still camera whatever the warm-up.
    pub fn camera_at(&self, settings: &RenderSettings, f: u32) -> Camera {
        if let Some(camera) = self.cameras.as_ref().and_then(|c| c.get(f as usize)) {
            return *camera;
        }
        let m = f.saturating_sub(settings.warmup);
        match &self.motion {
            Motion::Still | Motion::Animation { camera: None, .. } => self.camera,
            Motion::Animation { camera: Some(a), .. } => a.camera_at(self.time_at(settings, f)),
            Motion::Dolly => dolly(&self.camera, &self.scene, m, settings.frames),
        }
    }

    /// The light field of frame `f`.
    pub fn lf_of(&self, settings: &RenderSettings, f: u32) -> Result<LightField> {
        let rig = settings.light_field.rig_around(&self.camera_at(settings, f), self.centre);
        settings.light_field.layout.with_rig_spaced(rig, self.spacing)
    }
}

/// The rig of frame `f` of `total`: a smooth sideways dolly across 10 % of the scene's size,
/// eased in and out, centred on the starting camera.
fn dolly(camera: &Camera, scene: &Scene, f: u32, total: u32) -> Camera {
    if total <= 1 {
        return *camera;
    }
    let (right, _, _) = camera.basis();
    let t = f as f32 / (total - 1) as f32;
    let eased = 0.5 - 0.5 * (std::f32::consts::PI * t).cos();
    let offset: Vec3 = right * (0.1 * scene.bounds().diagonal() * (eased - 0.5));
    Camera { eye: camera.eye + offset, ..*camera }
}

pub(super) fn view_file_name(index: u32) -> String {
    format!("view_{index:03}.exr")
}

/// Checks the outputs before any work. The folder may not exist yet (it is created when the
/// views are written), but the nearest folder above it must be writable.
pub(super) fn check_outputs(
    out_dir: &Path,
    sheet: &Path,
    render_json: &Path,
    trace: Option<&Sink>,
    dot: Option<&Sink>,
    wiggle: Option<&Path>,
) -> Result<()> {
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("--out-dir {} is a file: give a folder", out_dir.display());
    }
    let existing = out_dir.ancestors().find(|a| a.as_os_str().is_empty() || a.exists()).unwrap_or(Path::new("."));
    let existing = if existing.as_os_str().is_empty() { Path::new(".") } else { existing };
    if !existing.is_dir() {
        bail!("--out-dir {}: {} is not a folder", out_dir.display(), existing.display());
    }
    if let Err(e) = tempfile::NamedTempFile::new_in(existing) {
        let why = parallax_accuracy::write_failure(existing, &e);
        bail!("--out-dir {}: folder {} is not writable: {why}", out_dir.display(), existing.display());
    }
    let sheet_sink = Sink::File(sheet.to_path_buf());
    let json_sink = Sink::File(render_json.to_path_buf());
    let viewer_sink = Sink::File(out_dir.join("viewer.html"));
    let mut outputs = Vec::new();
    if out_dir.is_dir() {
        outputs.push(Output { flag: "--out-dir", sink: &sheet_sink, format: Format::Png });
        outputs.push(Output { flag: "--out-dir", sink: &json_sink, format: Format::Json });
        outputs.push(Output { flag: "--out-dir", sink: &viewer_sink, format: Format::Html });
    }
    let in_out_dir = |flag: &str, path: &Path| {
        if path.parent().is_some_and(|p| p == out_dir)
            && path.file_name().and_then(|n| n.to_str()).is_some_and(|n| n == "render.json" || n.starts_with("view_"))
        {
            bail!("{flag} {} would overwrite an output of --out-dir: give it another name", path.display());
        }
        Ok(())
    };
    if let Some(sink) = trace {
        if let Sink::File(path) = sink {
            in_out_dir("--trace", path)?;
        }
        outputs.push(Output { flag: "--trace", sink, format: Format::Json });
    }
    if let Some(sink) = dot {
        outputs.push(Output { flag: "--dot", sink, format: Format::Dot });
    }
    let wiggle_sink = wiggle.map(|p| Sink::File(p.to_path_buf()));
    if let Some(sink @ Sink::File(path)) = &wiggle_sink {
        in_out_dir("--wiggle", path)?;
        outputs.push(Output { flag: "--wiggle", sink, format: Format::Png });
    }
    check_creating(&outputs, Some(out_dir))
}

#[cfg(test)]
mod tests {
    use parallax_scene::default_scene;

    use super::*;

    /// The motion that runs for `request` over `frames` frames, a camera `placed` or not.
    fn motion(request: MotionRequest, placed: bool, frames: u32, scene: &Scene) -> String {
        Motion::resolve(request, placed, frames, scene).map(|m| m.name().to_string()).unwrap_or_else(|e| e.to_string())
    }

    /// A placed camera stays where it was put; the scene's own animation runs only when no
    /// camera is given; the dolly only when asked for.
    #[test]
    fn a_camera_moves_only_when_a_motion_is_asked_for() {
        use MotionRequest::{Animation, Auto, Dolly, None};
        let still = default_scene();
        let mut animated = default_scene();
        animated.camera_animation = Some(CameraAnimation { nodes: Vec::new(), yfov: 0.8, duration: 1.0 });
        assert_eq!(motion(Auto, false, 3, &still), "none");
        assert_eq!(motion(Auto, false, 3, &animated), "animation");
        assert_eq!(motion(Auto, true, 3, &animated), "none");
        assert_eq!(motion(Dolly, true, 3, &still), "dolly");
        assert!(
            motion(Animation, true, 3, &animated)
                .starts_with("--motion animation moves the scene's own camera, so --camera would be ignored")
        );
        assert_eq!(motion(Animation, false, 3, &animated), "animation");
        assert_eq!(motion(None, false, 3, &animated), "none");
        assert_eq!(motion(Dolly, false, 1, &still), "none", "one frame is still");
        assert_eq!(
            motion(Animation, false, 3, &still),
            "--motion animation: scene 'default' has no animation of its camera or meshes; use --motion dolly or \
             --motion none"
        );
    }

    /// A skinned, animated scene (Fox) moves by default, its meshes posed at each frame's time
    /// whether or not a camera is placed; a placed camera stays put meanwhile. `--motion none`
    /// (`--still`), the dolly and a single frame pose it once, at t = 0.
    #[test]
    fn moving_meshes_run_their_animation_under_a_still_or_placed_camera() {
        use MotionRequest::{Animation, Auto, Dolly, None};
        let fox =
            parallax_scene::load_gltf(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/fox/Fox.gltf")).unwrap();
        assert_eq!(motion(Auto, false, 3, &fox), "animation");
        assert_eq!(motion(Auto, true, 3, &fox), "animation");
        assert_eq!(motion(Animation, true, 3, &fox), "animation");
        assert_eq!(motion(None, false, 3, &fox), "none");
        assert_eq!(motion(Dolly, false, 3, &fox), "dolly");
        assert_eq!(motion(Auto, false, 1, &fox), "none");

        // The placed camera is not animated; the meshes' animation (Survey, 3.42 s) runs.
        let placed = Motion::resolve(Auto, true, 3, &fox).unwrap();
        assert!(placed.moves_geometry(&fox));
        let Motion::Animation { camera: Option::None, duration } = placed else { panic!("the camera was placed") };
        assert!((duration - 3.4166667).abs() < 1e-5, "{duration}");
        assert!(!Motion::resolve(None, false, 3, &fox).unwrap().moves_geometry(&fox));
    }
}
