//! `render`'s plan room: everything decided before a device is touched. The flags are checked
//! together, the outputs can be written, the work fits the host, the pipeline (with a user
//! crate's stages) is compiled as `plan` compiles it, the scene is loaded and the camera of
//! every frame is known.

use std::path::PathBuf;

use anyhow::Result;
use glam::Vec3;
use parallax_graph::{LightField, Rig};
use parallax_passes::pipeline::PipelineBuilder;
use parallax_scene::animation::CameraAnimation;
use parallax_scene::{Camera, Scene, TraceSettings};

use super::report::{check_outputs, extra_layers, view_file_name};
use super::{RenderArgs, dolly};
use crate::budget::TraceWork;
use crate::disk_space::{RenderOutputs, free_bytes};
use crate::pipeline_args::PipelineSchedule;
use crate::render_pictures::gpu_exposure;

/// A render, planned: what the frame loop runs and the report describes.
pub(super) struct RenderJob {
    pub sheet: PathBuf,
    pub render_json: PathBuf,
    pub settings: TraceSettings,
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
    animation: Option<CameraAnimation>,
    centre: Vec3,
}

impl RenderJob {
    /// Checks `args` and plans the run, the pipeline extended by `extend`.
    pub fn prepare(args: &RenderArgs, extend: &dyn Fn(PipelineBuilder) -> PipelineBuilder) -> Result<RenderJob> {
        args.pipeline.check()?;
        let sheet = args.out_dir.join("lightfield.png");
        let render_json = args.out_dir.join("render.json");
        let (trace, dot) = (args.trace.as_ref(), args.dot.dot.as_ref());
        check_outputs(&args.out_dir, &sheet, &render_json, trace, dot, args.wiggle.as_deref())?;
        let settings = TraceSettings { spp: args.spp, max_depth: args.depth.max_depth, ..Default::default() };
        settings.validate()?;
        let total_frames = args.warmup + args.frames;
        let sized = args.light_field.with_rig(Rig::default())?;
        crate::outputs::check_targets_in(&args.out_dir, (0..sized.len() as u32).map(view_file_name), "--out-dir")?;
        let devices = args.devices.selection().count() as u32;
        let one_frame = TraceWork {
            views: sized.len() as u64,
            frames: u64::from(total_frames),
            width: sized.width,
            height: sized.height,
            spp: args.spp,
            devices: u64::from(devices),
            views_flag: "--lf",
            frames_flag: "--frames, --warmup",
        };
        one_frame.check_duration()?;
        one_frame.check_host()?;
        let (layers, holes) = extra_layers(args, args.pipeline.pipeline.into());
        let outputs = RenderOutputs {
            views: sized.len() as u64,
            width: sized.width,
            height: sized.height,
            channels: 3 + if layers { 7 } else { 0 } + u64::from(holes),
            frames: args.frames,
            save_every: args.save_every,
            quilt: args.quilt,
        };
        if let Some(free) = free_bytes(&args.out_dir) {
            outputs.check_fits(&args.out_dir, free)?;
        }
        // Planned from the layout alone, as `plan` plans it: the schedule depends on the views'
        // positions in the rig plane, not on where the rig stands.
        let compiled = args.pipeline.compile_with(&sized, devices, gpu_exposure(args.exposure), extend)?;
        let dot = args.dot.render(&compiled.schedule);

        let scene = args.scene.load()?;
        let mut written = vec![("--out-dir", render_json.as_path()), ("--out-dir", sheet.as_path())];
        if let Some(crate::outputs::Sink::File(trace)) = &args.trace {
            written.push(("--trace", trace.as_path()));
        }
        crate::outputs::check_inputs(&written, &args.scene.inputs(&scene))?;
        let camera = args.scene.camera_or_default(&scene);
        let centre = scene.bounds().center();
        // The scene's own camera animation, spread over the measured frames; else a dolly (an
        // explicit --camera is a rig the user placed: it dollies too).
        let animation = if args.scene.camera.is_none() { scene.camera_animation.clone() } else { None };
        Ok(RenderJob {
            sheet,
            render_json,
            settings,
            total_frames,
            one_frame,
            compiled,
            dot,
            scene,
            camera,
            animation,
            centre,
        })
    }

    /// The camera of frame `f`. Warm-up frames see the first measured frame's camera, so one
    /// measured frame is a still camera whatever the warm-up.
    pub fn camera_at(&self, args: &RenderArgs, f: u32) -> Camera {
        let m = f.saturating_sub(args.warmup);
        match &self.animation {
            _ if args.still => self.camera,
            Some(a) => a.camera_at(a.duration * m as f32 / args.frames.saturating_sub(1).max(1) as f32),
            None => dolly(&self.camera, &self.scene, m, args.frames),
        }
    }

    /// The light field of frame `f`.
    pub fn lf_of(&self, args: &RenderArgs, f: u32) -> Result<LightField> {
        args.light_field.around(&self.camera_at(args, f), self.centre)
    }
}
