//! A scene whose meshes move (Fox, skinned and animated) re-posed between frames through
//! [`LightFieldRenderer::upload_geometry`]: the whole pipeline gives the same bits on three
//! devices as the same plan on one (every device gets each new pose before the frame that
//! shows it), and the posed frames differ from frames that keep the first pose.

mod common;

use glam::Vec3;
use parallax_backend::{KernelGraph, KernelPlan};
use parallax_graph::{
    AssignStrategy, DeviceId, LayoutSpec, LightField, Partition, PartitionConfig, PassPlacementInfo, Placement, Region,
    Scheme, ViewId, compile,
};
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_passes::pipeline::{PipelineKind, declare_pipeline};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Camera, Scene, SceneBvh, Sky, Sun, TraceSettings, load_gltf};

const SIZE: u32 = 16;
/// Animation times of the frames (Fox's Survey lasts 3.42 s).
const TIMES: [f32; 3] = [0.0, 1.0, 2.0];

/// A plan's placement with every instance moved to device 0.
struct OnOneDevice<'p>(&'p Partition);

impl Placement for OnOneDevice<'_> {
    fn devices(&self) -> u32 {
        1
    }

    fn place(&self, pass: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        self.0.place(pass, view, height).into_iter().map(|(_, rows)| (DeviceId(0), rows)).collect()
    }
}

fn lit_fox() -> Scene {
    let mut scene = load_gltf(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/fox/Fox.gltf")).unwrap();
    scene.sky = Some(Sky::Constant(Vec3::new(0.5, 0.6, 0.8)));
    scene.sun =
        Some(Sun { to_sun: Vec3::new(0.3, 1.0, 0.2).normalize(), irradiance: Vec3::splat(4.0), angular_radius: 0.01 });
    scene
}

/// The denoised radiance of every view of every frame, the scene posed at `TIMES` (or kept in
/// its first pose, `pose: false`) before each frame.
fn run(lf: &LightField, plan: &Partition, placement: &dyn Placement, pose: bool) -> Vec<Vec<Vec<u8>>> {
    let mut scene = lit_fox();
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let config = common::denoising_pipeline(PipelineKind::Reproject);
    let handles = declare_pipeline(&mut graph, &config).unwrap();
    graph.export(&handles.display);
    let denoised = handles.denoised.expect("the pipeline denoises").family();
    let exec = KernelPlan::from_schedule(&graph, &compile(&graph, placement).unwrap()).unwrap();
    let ctx = common::context(placement.devices() as usize);
    let bvh = SceneBvh::build(&scene);
    let mut renderer = LightFieldRenderer::new(&ctx, exec, &GpuScene::new(&scene, &bvh)).unwrap();
    let settings = TraceSettings { spp: 1, max_depth: 3, ..Default::default() };
    let mut frames = Vec::new();
    for (f, &t) in TIMES.iter().enumerate() {
        if pose && f > 0 {
            scene.pose_at(t).unwrap();
            renderer.upload_geometry(&GpuScene::new(&scene, &SceneBvh::build(&scene))).unwrap();
        }
        renderer.submit(&scene, &lightfield_views(lf), &TraceSettings { frame: f as u32, ..settings }).unwrap();
        renderer.finish().unwrap();
        frames.push((0..lf.len() as u32).map(|v| renderer.read(denoised, v).unwrap()).collect());
    }
    drop(renderer);
    ctx.check_validation().unwrap();
    frames
}

#[test]
fn posed_geometry_gives_the_same_bits_on_one_and_three_devices() {
    let scene = lit_fox();
    let camera = Camera::look_at(Vec3::new(0.0, 40.0, 250.0), Vec3::new(0.0, 40.0, 0.0), Vec3::Y, 0.7);
    let rig = rig_of(&camera, scene.bounds().center(), None);
    let lf = LightField::new(LayoutSpec::Grid { cols: 3, rows: 1 }, Some(2.0), Some((SIZE, SIZE)), rig).unwrap();
    let config =
        PartitionConfig { devices: 3, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(&lf, &config).unwrap();
    let three = run(&lf, &plan, &plan, true);
    let one = run(&lf, &plan, &OnOneDevice(&plan), true);
    assert!(three == one, "3 devices and 1 device differ on posed frames");
    let unposed = run(&lf, &plan, &OnOneDevice(&plan), false);
    assert_eq!(unposed[0], one[0], "frame 0 shows the loaded pose either way");
    assert!(unposed[2] != one[2], "the posed fox of t = 2 s is not the fox of t = 0");
}
