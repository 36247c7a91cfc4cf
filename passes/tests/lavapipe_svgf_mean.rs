//! SVGF keeps the per-channel mean of what it denoises, judged against an undenoised
//! 256-spp render of the same views (lavapipe, validation on): the path-trace pipeline at 1 spp
//! (jittered, as `parallax render` traces) with SVGF, a still camera, the mean of `denoised` over
//! the frames after a short warm-up against the reference's, per channel, within 1 %. Scenes: the
//! default scene, a
//! room whose every surface has a saturated six-colour checker texture (channels of albedo 0
//! beside channels of albedo 1, cells from several pixels wide down to below a pixel on thin
//! pillars, a glTF dielectric whose specular lands in the black channels), and, with
//! `PARALLAX_SPONZA`, Sponza at 96×54 (ignored otherwise). SVGF before this test lost or gained
//! up to 13 % (Sponza) and 90 % (the checker room) of a channel.
//!
//! Each also checks why the mean holds, frame by frame and free of sampling noise: SVGF conserves
//! radiance and clamps nothing, so the mean of each frame's `denoised` is the temporal average of
//! the inputs (per pixel with a hit, the running mean of every frame of the still camera; pixels
//! without a hit are their radiance), to 1e-4.

mod common;

use glam::{Vec3, Vec4};
use parallax_backend::{ExecOptions, KernelGraph, KernelPlan};
use parallax_graph::{BandedPlacement, ViewTopology, compile};
use parallax_passes::pipeline::{PipelineKind, declare_pipeline};
use parallax_passes::{LightFieldRenderer, banded_trace_plan};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{
    Camera, Material, Scene, SceneBuilder, SceneBvh, Sky, Sun, Texture, TraceSettings, View, default_lighting,
};

/// Samples per pixel of the reference.
const REFERENCE_SPP: u32 = 256;
/// The bound on |mean(denoised) / mean(reference) − 1|, per channel.
const MEAN_TOLERANCE: f64 = 0.01;
/// The bound on |mean(denoised) / temporal average of the input means − 1|, per frame.
const CONSERVATION_TOLERANCE: f64 = 1e-4;

/// What a case renders.
struct Case {
    scene: Scene,
    views: Vec<View>,
    max_depth: u32,
    warmup: u32,
    frames: u32,
}

/// The per-channel means of a run: of `denoised` over the measured frames, and the worst
/// per-frame deviation from the temporal average of the inputs.
struct Measured {
    denoised: [f64; 3],
    worst_conservation: f64,
}

/// Six saturated colours (every channel 0 or 1) in cells of `texels` texels, `cells` a side.
fn checker(cells: u32, texels: u32) -> Texture {
    const COLOURS: [[u8; 3]; 6] = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [0, 255, 255], [255, 0, 255]];
    let size = cells * texels;
    let rgba8 = (0..size * size)
        .flat_map(|i| {
            let (x, y) = (i % size / texels, i / size / texels);
            let [r, g, b] = COLOURS[((x + 2 * y) % 6) as usize];
            [r, g, b, 255]
        })
        .collect();
    Texture { width: size, height: size, rgba8 }
}

/// A floor, two walls, pillars and boxes of Lambert and dielectric checker materials (each
/// face spans the whole texture), under a sun and a sky.
fn checker_room() -> Scene {
    let mut b = SceneBuilder::new("checker room");
    let textured = |m: Material| Material { base_color: Vec4::ONE, base_color_texture: Some(0), ..m };
    let lambert = b.material(textured(Material::diffuse("checker", Vec3::ONE)));
    let dielectric = b.material(textured(Material::glossy("glossy checker", Vec3::ONE, 0.0, 0.5)));
    b.quad(Vec3::new(-4.0, 0.0, 4.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -10.0), lambert);
    b.quad(Vec3::new(-4.0, 0.0, -6.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0), dielectric);
    b.quad(Vec3::new(-4.0, 0.0, 4.0), Vec3::new(0.0, 0.0, -10.0), Vec3::new(0.0, 4.0, 0.0), lambert);
    b.cuboid(Vec3::new(-1.2, 0.9, 1.5), Vec3::new(0.1, 0.9, 0.1), 0.0, lambert);
    b.cuboid(Vec3::new(1.4, 0.5, 0.5), Vec3::new(0.5, 0.5, 0.5), 0.4, dielectric);
    b.cuboid(Vec3::new(-0.3, 1.25, -1.5), Vec3::new(0.15, 1.25, 0.15), 0.0, lambert);
    b.cuboid(Vec3::new(2.2, 1.6, -3.0), Vec3::new(0.2, 1.6, 0.2), 0.2, dielectric);
    b.sphere(Vec3::new(0.4, 0.45, 0.2), 0.45, 2, dielectric);
    b.camera(Camera::look_at(Vec3::new(0.0, 1.4, 5.5), Vec3::new(0.0, 0.8, 0.0), Vec3::Y, 0.75));
    let mut scene = b.build();
    scene.textures.push(checker(16, 2));
    (scene.sky, scene.sun) = default_lighting();
    scene
}

/// Per-channel mean of RGBA images.
fn mean_rgb<'a>(images: impl IntoIterator<Item = &'a [f32]>) -> [f64; 3] {
    let (mut sum, mut n) = ([0.0f64; 3], 0usize);
    for image in images {
        for pixel in image.chunks_exact(4) {
            for c in 0..3 {
                sum[c] += f64::from(pixel[c]);
            }
            n += 1;
        }
    }
    sum.map(|s| s / n as f64)
}

/// The reference: every view path traced at `REFERENCE_SPP`, jittered, in chunks of 64 spp.
fn reference(case: &Case) -> [f64; 3] {
    let (width, height) = (case.views[0].width, case.views[0].height);
    let ctx = common::context(1);
    let bvh = SceneBvh::build(&case.scene);
    let trace = banded_trace_plan(case.views.len() as u32, (width, height), 1, 1).unwrap();
    let mut tracer =
        LightFieldRenderer::tracing(&ctx, trace, &GpuScene::new(&case.scene, &bvh), ExecOptions::default()).unwrap();
    let chunks = REFERENCE_SPP / 64;
    let mut sum = [0.0f64; 3];
    for chunk in 0..chunks {
        let settings = TraceSettings {
            spp: 64,
            max_depth: case.max_depth,
            frame: 1_000_000 + chunk,
            jitter: true,
            ..Default::default()
        };
        let views = tracer.trace(&case.scene, &case.views, &settings).unwrap();
        let images: Vec<Vec<f32>> = views.iter().map(|v| v.iter().flat_map(|p| p.radiance).collect()).collect();
        let mean = mean_rgb(images.iter().map(Vec::as_slice));
        for c in 0..3 {
            sum[c] += mean[c] / f64::from(chunks);
        }
    }
    drop(tracer);
    ctx.check_validation().unwrap();
    sum
}

/// Running per-pixel temporal average of the inputs (what SVGF's mean must equal).
struct TemporalAverage {
    pixels: Vec<Vec<f64>>,
}

impl TemporalAverage {
    /// Adds frame `frame` (0-based) of view `view`; returns nothing, see `mean`.
    fn add(&mut self, view: usize, frame: u32, radiance: &[f32]) {
        let alpha = 1.0 / f64::from(frame + 1);
        let pixels = &mut self.pixels[view];
        pixels.resize(radiance.len(), 0.0);
        // On a still camera every pixel, sky too, is the running mean of its inputs.
        for (i, (p, &x)) in pixels.iter_mut().zip(radiance).enumerate() {
            if i % 4 != 3 {
                *p += alpha * (f64::from(x) - *p);
            }
        }
    }

    fn mean(&self) -> [f64; 3] {
        let (mut sum, mut n) = ([0.0f64; 3], 0usize);
        for pixels in &self.pixels {
            for pixel in pixels.chunks_exact(4) {
                for c in 0..3 {
                    sum[c] += pixel[c];
                }
                n += 1;
            }
        }
        sum.map(|s| s / n as f64)
    }
}

/// The path-trace pipeline with SVGF over the case's views on one device, `warmup + frames`
/// frames at 1 spp with a still camera.
fn denoise(case: &Case) -> Measured {
    let (width, height) = (case.views[0].width, case.views[0].height);
    let views = case.views.len() as u32;
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(views, width, height));
    let config = common::denoising_pipeline(PipelineKind::PathTrace);
    let handles = declare_pipeline(&mut graph, &config).unwrap();
    graph.export(handles.denoised.as_ref().unwrap());
    graph.export(&handles.radiance);
    let read_back = [&handles.radiance, handles.denoised.as_ref().unwrap()];
    let [radiance_of, denoised_of] = read_back.map(|handle| handle.family());
    let schedule = compile(&graph, &BandedPlacement { devices: 1, bands: 1 }).unwrap();
    assert_eq!(schedule.validate().errors, vec![]);
    let plan = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(1);
    let bvh = SceneBvh::build(&case.scene);
    let mut renderer = LightFieldRenderer::new(&ctx, plan, &GpuScene::new(&case.scene, &bvh)).unwrap();
    let mut average = TemporalAverage { pixels: vec![Vec::new(); views as usize] };
    let mut denoised = [0.0f64; 3];
    let mut worst_conservation = 0.0f64;
    for frame in 0..case.warmup + case.frames {
        let settings = TraceSettings { spp: 1, max_depth: case.max_depth, frame, jitter: true, ..Default::default() };
        renderer.submit(&case.scene, &case.views, &settings).unwrap();
        renderer.finish().unwrap();
        let mut outputs = Vec::new();
        for view in 0..views {
            let radiance = common::floats(&renderer.read(radiance_of, view).unwrap());
            average.add(view as usize, frame, &radiance);
            outputs.push(common::floats(&renderer.read(denoised_of, view).unwrap()));
        }
        let mean = mean_rgb(outputs.iter().map(Vec::as_slice));
        let expected = average.mean();
        for c in 0..3 {
            worst_conservation = worst_conservation.max((mean[c] / expected[c] - 1.0).abs());
        }
        if frame >= case.warmup {
            for c in 0..3 {
                denoised[c] += mean[c] / f64::from(case.frames);
            }
        }
    }
    drop(renderer);
    ctx.check_validation().unwrap();
    Measured { denoised, worst_conservation }
}

fn assert_mean_within_tolerance(name: &str, case: &Case) {
    let reference = reference(case);
    let measured = denoise(case);
    let ratio = [0, 1, 2].map(|c| measured.denoised[c] / reference[c]);
    eprintln!(
        "{name}: mean(denoised) / mean({REFERENCE_SPP} spp) = {ratio:.4?}; worst frame against the temporal average of the input: {:.1e}",
        measured.worst_conservation
    );
    assert!(
        ratio.iter().all(|r| (r - 1.0).abs() <= MEAN_TOLERANCE),
        "{name}: per-channel mean / reference {ratio:?}, allowed 1 ± {MEAN_TOLERANCE}"
    );
    assert!(
        measured.worst_conservation <= CONSERVATION_TOLERANCE,
        "{name}: a frame's mean is {} off the temporal average of its inputs",
        measured.worst_conservation
    );
}

#[test]
fn svgf_keeps_the_per_channel_mean_of_the_default_scene_within_1_percent() {
    let scene = parallax_scene::default_scene();
    let views = common::views(&scene, 2, 64, 48);
    let case = Case { scene, views, max_depth: 4, warmup: 2, frames: 30 };
    assert_mean_within_tolerance("default scene", &case);
}

#[test]
fn svgf_keeps_the_per_channel_mean_of_a_saturated_checker_room_within_1_percent() {
    let scene = checker_room();
    let views = common::views(&scene, 2, 64, 48);
    // Jittered 1-spp frames of this room: a frame's mean is ±4 % per channel; 30 frames bring
    // the measured mean to about ±0.3 %.
    let case = Case { scene, views, max_depth: 4, warmup: 2, frames: 30 };
    assert_mean_within_tolerance("checker room", &case);
}

#[test]
#[ignore = "needs PARALLAX_SPONZA (the sponza_lite glTF); about 4 minutes on lavapipe"]
fn svgf_keeps_the_per_channel_mean_of_sponza_at_96x54_within_1_percent() {
    let Ok(path) = std::env::var("PARALLAX_SPONZA") else {
        panic!("set PARALLAX_SPONZA to sponza_lite/Sponza.gltf");
    };
    let mut scene = parallax_scene::load_scene(&path).unwrap();
    // docs/RESULTS.md's $SP: --camera 9,1.6,-0.4,-8,3.5,-0.4,0,1,0,65 --sun 0.3,1,0.2,4,0.5
    // --sky 0.5,0.6,0.8 --max-depth 6; two views 1 mm apart (the multiscopic spacing).
    scene.sun = Some(Sun {
        to_sun: Vec3::new(0.3, 1.0, 0.2).normalize(),
        irradiance: Vec3::splat(4.0),
        angular_radius: 0.5f32.to_radians(),
    });
    scene.sky = Some(Sky::Constant(Vec3::new(0.5, 0.6, 0.8)));
    let camera = Camera::look_at(Vec3::new(9.0, 1.6, -0.4), Vec3::new(-8.0, 3.5, -0.4), Vec3::Y, 65f32.to_radians());
    let (right, _, _) = camera.basis();
    let views = (0..2)
        .map(|index| View {
            camera: Camera { eye: camera.eye + right * 0.001 * index as f32, ..camera },
            width: 96,
            height: 54,
            index,
        })
        .collect();
    // A 1-spp frame's mean is ±3.4 % per channel here (sun through the arcades); 40 frames
    // bring the measured mean to about ±0.5 %.
    let case = Case { scene, views, max_depth: 6, warmup: 2, frames: 40 };
    assert_mean_within_tolerance("Sponza 96x54", &case);
}
