//! The raster G-buffer pass on lavapipe, validation on: its depth attachment is a graph
//! resource that a later compute pass reads (checked against the CPU reference's first hits at
//! pixel centres), row bands over three logical devices give the one-device result bit for
//! bit, and alpha-masked texels are discarded.

mod common;

use std::path::Path;
use std::sync::{Arc, OnceLock};

use glam::{Vec2, Vec3, Vec4};
use parallax_backend::{
    ExecOptions, Executor, FrameClock, FrameData, InstanceId, KernelGraph, KernelPlan, PassInstance, PassKernel,
    PassParams, Recorder, ShaderLibrary,
};
use parallax_graph::{BandedPlacement, DeviceId, FamilyId, Format, ReadSlot, Role, ViewTopology, WriteSlot, compile};
use parallax_passes::{RASTER_OUTPUTS, declare_gbuffer_raster, raster_camera, upload_scene};
use parallax_scene::gpu::GpuScene;
use parallax_scene::shading::surface_point;
use parallax_scene::{AlphaMode, Camera, Material, Scene, SceneBuilder, SceneBvh, Texture, View, default_scene};

const NEAR: f32 = 0.05;
const DEPTH_COPY: &str = "depth_copy";
const DEPTH_TO_R32F: &str = "depth_to_r32f";

/// The test kernel of `tests/raster_kernels/`, compiled at run time, over the passes' shaders.
fn test_shaders() -> ShaderLibrary {
    // Compiled once per test binary: tests run in parallel, and one test reading a SPIR-V file
    // while another's glslc rewrites it can read it empty.
    static SPIRV: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    let spirv = SPIRV.get_or_init(|| {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join("raster_kernels");
        let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("raster_kernels");
        std::fs::create_dir_all(&out).unwrap();
        let includes = [parallax_glsl::parallax_include_dir()];
        let compiled = parallax_glsl::Compiler::new().compile_dir(&src, &includes, &out).unwrap();
        compiled.into_iter().map(|shader| (shader.name, std::fs::read(&shader.spirv).unwrap())).collect()
    });
    let test = spirv
        .iter()
        .fold(ShaderLibrary::new(), |library, (name, bytes)| library.with_spirv_bytes(name, bytes).unwrap());
    test.layered_over(parallax_passes::shader_library())
}

/// Reads the raster depth (Depth32f) and writes it into `depth_copy` (R32f).
struct DepthCopyKernel {
    depth: ReadSlot,
    copy: WriteSlot,
}

impl PassKernel for DepthCopyKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, _: InstanceId) -> parallax_backend::Result<()> {
        let (depth, copy) = (pass.read(self.depth)?, pass.write(self.copy)?);
        let params = PassParams { src0: rec.image(depth.alloc)?, ..rec.row_params(pass, copy.alloc)? };
        rec.dispatch_rows(DEPTH_TO_R32F, params)
    }
}

/// The raster G-buffer of every view, then the depth copied by a compute pass; the three
/// colour layers, the depth resource and its copy exported; under `bands` bands on as many
/// devices. Returns the plan and the families of the exported layers, in [`RASTER_OUTPUTS`]
/// order, then the depth and its copy.
fn raster_plan(views: u32, (width, height): (u32, u32), devices: u32) -> (KernelPlan, [FamilyId; 5]) {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(views, width, height));
    let g = declare_gbuffer_raster(&mut graph);
    let mut copy = graph.image(DEPTH_COPY, Format::R32f);
    let mut pass = graph.pass(DEPTH_TO_R32F, Role::All);
    let kernel = DepthCopyKernel { depth: pass.read_slot(&g.depth), copy: pass.write_slot(&mut copy) };
    pass.kernel(Arc::new(kernel)).add();
    let exported = [&g.albedo_roughness, &g.normal_metallic, &g.position_depth, &g.depth, &copy];
    for image in exported {
        graph.export(image);
    }
    let schedule = compile(&graph, &BandedPlacement { devices, bands: devices }).unwrap();
    assert_eq!(schedule.validate().errors, vec![]);
    (KernelPlan::from_schedule(&graph, &schedule).unwrap(), exported.map(|image| image.family()))
}

/// Every exported layer of every view after one frame, by layer name: what device 0 holds.
struct Rendered {
    layers: Vec<(String, Vec<Vec<f32>>)>,
}

impl Rendered {
    fn layer(&self, name: &str, view: usize) -> &[f32] {
        &self.layers.iter().find(|(n, _)| n == name).unwrap().1[view]
    }
}

/// Renders `views` of `scene` with [`raster_plan`] on `devices` logical devices.
fn render(scene: &Scene, views: &[View], devices: u32) -> Rendered {
    let (width, height) = (views[0].width, views[0].height);
    let ctx = common::context(devices as usize);
    let (plan, families) = raster_plan(views.len() as u32, (width, height), devices);
    let options = ExecOptions { shaders: test_shaders(), ..ExecOptions::default() };
    let mut exec = Executor::new(&ctx, plan.clone(), options).unwrap();
    let bvh = SceneBvh::build(scene);
    upload_scene(&mut exec, &GpuScene::new(scene, &bvh)).unwrap();
    let cameras: Vec<_> = views.iter().map(|v| raster_camera(v, NEAR).unwrap()).collect();
    let mut frame = FrameData::new();
    frame.frame_block(&FrameClock::new().advance(&cameras)).unwrap();
    exec.set_frame(&frame).unwrap();
    exec.run_frame().unwrap();
    let mut layers = Vec::new();
    for (name, family) in RASTER_OUTPUTS.iter().chain(&["depth", DEPTH_COPY]).zip(families) {
        let per_view = (0..views.len() as u32)
            .map(|v| {
                let (device, resource) = plan.final_output(family, v).unwrap();
                assert_eq!(device, DeviceId(0), "finished views are gathered on device 0");
                let bytes = exec.read_resource(device, resource).unwrap();
                bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
            })
            .collect();
        layers.push((name.to_string(), per_view));
    }
    drop(exec);
    ctx.check_validation().unwrap();
    Rendered { layers }
}

/// The CPU reference's first hit through the centre of every pixel (the ray the raster
/// camera's pixel centre lies on): (linear depth, position, normal, albedo), `None` on a miss.
fn cpu_first_hits(scene: &Scene, view: &View) -> Vec<Option<(f32, Vec3, Vec3, Vec3)>> {
    let bvh = SceneBvh::build(scene);
    let camera = &view.camera;
    let forward = camera.forward.normalize();
    (0..view.height)
        .flat_map(|y| (0..view.width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let ndc = Vec2::new(
                (x as f32 + 0.5) / view.width as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + 0.5) / view.height as f32 * 2.0,
            );
            let dir = camera.ray_direction(ndc, view.aspect());
            let hit = bvh.closest_hit(scene, camera.eye, dir, 0.0, f32::INFINITY)?;
            let sp = surface_point(scene, &hit, camera.eye, dir);
            Some(((sp.position - camera.eye).dot(forward), sp.position, sp.normal, sp.base_color))
        })
        .collect()
}

/// Pixels whose centre sits on a silhouette or crease of the CPU's first hits: a 4-neighbour
/// differs in hit/miss, its hit point leaves this pixel's tangent plane (by more than 5 % of the
/// step between the two: another surface), or its normal turns by more than ~25°. There the
/// raster's coverage rule and the ray's edge test may pick different triangles.
fn edges(hits: &[Option<(f32, Vec3, Vec3, Vec3)>], width: usize, height: usize) -> Vec<bool> {
    let differs = |a: &Option<(f32, Vec3, Vec3, Vec3)>, b: &Option<(f32, Vec3, Vec3, Vec3)>| match (a, b) {
        (Some(a), Some(b)) => {
            let step = b.1 - a.1;
            step.dot(a.2).abs() > 0.05 * step.length() || a.2.dot(b.2) < 0.9
        }
        (None, None) => false,
        _ => true,
    };
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let neighbours = [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)];
            neighbours.iter().any(|&(nx, ny)| nx < width && ny < height && differs(&hits[i], &hits[ny * width + nx]))
        })
        .collect()
}

#[test]
fn a_compute_pass_reads_the_raster_depth_resource_which_matches_a_cpu_projection() {
    let scene = default_scene();
    let (width, height) = (96u32, 72u32);
    let view = View { camera: scene.default_camera(), width, height, index: 0 };
    let gpu = render(&scene, &[view], 1);
    let hits = cpu_first_hits(&scene, &view);
    let edge = edges(&hits, width as usize, height as usize);
    let depth = gpu.layer("depth", 0);
    let copy = gpu.layer(DEPTH_COPY, 0);
    assert_eq!(depth, copy, "the compute pass read exactly what the raster pass wrote");
    let position_depth = gpu.layer("position_depth", 0);
    let normal = gpu.layer("normal_metallic", 0);
    let albedo = gpu.layer("albedo_roughness", 0);
    let diagonal = scene.bounds().diagonal();
    let (mut checked, mut worst_depth) = (0, 0f32);
    for (i, hit) in hits.iter().enumerate() {
        if edge[i] {
            continue;
        }
        let texel = |layer: &[f32]| Vec4::from_slice(&layer[4 * i..4 * i + 4]);
        match hit {
            None => {
                assert_eq!(depth[i], 1.0, "pixel {i}: a miss keeps the cleared far depth");
                assert_eq!(texel(position_depth), Vec4::ZERO, "pixel {i}: a miss keeps zeros");
            }
            Some((linear, position, n, base)) => {
                // The attachment holds 1 - near / linear depth: back to linear depth, within
                // 0.01 % (the rasteriser interpolates depth in screen space, the ray intersects).
                let from_attachment = NEAR / (1.0 - depth[i]);
                let error = (from_attachment - linear).abs() / linear;
                worst_depth = worst_depth.max(error);
                assert!(error < 1e-4, "pixel {i}: depth {} is linear {from_attachment}, CPU {linear}", depth[i]);
                let pd = texel(position_depth);
                assert!((pd.w - linear).abs() < 1e-4 * linear, "pixel {i}: linear depth {} vs {linear}", pd.w);
                assert!((pd.truncate() - *position).length() < 1e-4 * diagonal, "pixel {i}: position");
                assert!(texel(normal).truncate().dot(*n) > 0.999, "pixel {i}: normal");
                assert!((texel(albedo).truncate() - *base).abs().max_element() < 1e-3, "pixel {i}: albedo");
                checked += 1;
            }
        }
    }
    let edges = edge.iter().filter(|&&e| e).count();
    eprintln!("{checked} hit pixels checked, {edges} silhouette pixels skipped, worst depth error {worst_depth:e}");
    // The default scene at 96×72: about 70 % of the pixels are hits off silhouettes, about
    // 21 % sit next to one (both sides of every edge are skipped).
    let pixels = (width * height) as usize;
    assert!(checked * 10 > pixels * 6, "{checked} of {pixels} pixels are hits away from silhouettes");
    assert!(edges * 4 < pixels, "{edges} of {pixels} pixels next to a silhouette");
}

#[test]
fn row_bands_over_three_devices_equal_one_device_bit_for_bit() {
    let scene = default_scene();
    let views = common::views(&scene, 2, 40, 30);
    let one = render(&scene, &views, 1);
    let three = render(&scene, &views, 3);
    for ((name, a), (_, b)) in one.layers.iter().zip(&three.layers) {
        for (view, (a, b)) in a.iter().zip(b).enumerate() {
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<u32>>();
            assert_eq!(bits(a), bits(b), "{name} of view {view}");
        }
    }
    assert!(one.layer("depth", 1).iter().any(|&d| d < 1.0), "the views see geometry");
}

/// A far opaque wall at z = -3 behind a near quad at z = -2 whose base-colour texture has alpha
/// 1 and 0 in a checkerboard of 4×4-texel blocks, masked at 0.5.
fn alpha_scene() -> (Scene, f32) {
    let mut builder = SceneBuilder::new("alpha mask");
    let wall = builder.material(Material::diffuse("wall", Vec3::splat(0.5)));
    let masked = builder.material(Material {
        alpha_mode: AlphaMode::Mask(0.5),
        base_color_texture: Some(0),
        ..Material::diffuse("mask", Vec3::new(0.8, 0.2, 0.1))
    });
    builder.quad(Vec3::new(-4.0, -4.0, -3.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 8.0, 0.0), wall);
    builder.quad(Vec3::new(-1.0, -1.0, -2.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), masked);
    let mut scene = builder.build();
    let rgba8 = (0..8u32 * 8)
        .flat_map(|i| {
            let opaque = (i % 8 / 4 + i / 8 / 4) % 2 == 0;
            [255, 255, 255, if opaque { 255 } else { 0 }]
        })
        .collect();
    scene.textures.push(Texture { width: 8, height: 8, rgba8 });
    (scene, 0.5)
}

#[test]
fn alpha_masked_texels_are_discarded_in_the_fragment_shader() {
    let (scene, cutoff) = alpha_scene();
    scene.check().unwrap();
    let (width, height) = (48u32, 48u32);
    let camera = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 1.2);
    let view = View { camera, width, height, index: 0 };
    let gpu = render(&scene, &[view], 1);
    let position_depth = gpu.layer("position_depth", 0);
    let bvh = SceneBvh::build(&scene);
    let masked = &scene.materials[1];
    let (mut kept, mut discarded) = (0, 0);
    for y in 0..height {
        for x in 0..width {
            let i = (y * width + x) as usize;
            let ndc =
                Vec2::new((x as f32 + 0.5) / width as f32 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / height as f32 * 2.0);
            let dir = camera.ray_direction(ndc, view.aspect());
            // Where the ray meets the masked quad's plane, if inside the quad.
            let p = dir * (2.0 / -dir.z);
            if p.x.abs() >= 0.98 || p.y.abs() >= 0.98 {
                continue;
            }
            let uv = Vec2::new((p.x + 1.0) / 2.0, 1.0 - (p.y + 1.0) / 2.0);
            let alpha = scene.base_color_alpha(masked, uv);
            // Bilinear filtering blends the blocks over one texel: texels near the cutoff may
            // round either way on the GPU, so they are not judged.
            if (alpha - cutoff).abs() < 0.1 {
                continue;
            }
            let depth = position_depth[4 * i + 3];
            let cpu = bvh.closest_hit(&scene, camera.eye, dir, 0.0, f32::INFINITY).unwrap();
            let cpu_depth = (cpu.t * dir).dot(camera.forward);
            if alpha >= cutoff {
                assert!((depth - 2.0).abs() < 1e-4, "pixel ({x}, {y}), alpha {alpha}: the quad, not {depth}");
                kept += 1;
            } else {
                assert!(
                    (depth - 3.0).abs() < 1e-4,
                    "pixel ({x}, {y}), alpha {alpha}: discarded, the wall behind, not {depth}"
                );
                discarded += 1;
            }
            assert!((cpu_depth - depth).abs() < 1e-4, "pixel ({x}, {y}): the CPU's alpha-aware ray agrees");
        }
    }
    eprintln!("{kept} masked-quad pixels kept, {discarded} discarded");
    assert!(kept > 200 && discarded > 200, "{kept} kept, {discarded} discarded");
}
