//! GPU traversal (the `raycast` pass, shaders/bvh_traverse.glsl) against the CPU traversal of
//! parallax-scene, for random rays: the same closest hit (hit or miss; t within 1e-4 relative;
//! a different triangle only at the same t, i.e. a ray through an edge two triangles share) and
//! the same any-hit answer. Textures and alpha masks are on on both sides.

mod common;

use parallax_passes::{Raycaster, compare_with_cpu, random_rays};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Scene, SceneBvh, default_scene, load_gltf};

fn check(scene: &Scene, rays: usize) {
    let bvh = SceneBvh::build(scene);
    let ctx = common::context(1);
    let gpu_scene = GpuScene::new(scene, &bvh);
    let mut raycaster = Raycaster::new(&ctx, &gpu_scene, rays, false).unwrap();
    let batch = random_rays(scene, rays);
    let (closest, _) = raycaster.cast(&batch, false, 1).unwrap();
    let (any, _) = raycaster.cast(&batch, true, 1).unwrap();
    raycaster.check_validation().unwrap();
    drop(raycaster);
    let c = compare_with_cpu(scene, &bvh, &batch, &closest, &any);
    println!("{}: {c:?}", scene.name);
    assert!(c.gpu_hits > rays / 10, "the rays must meet the scene: {c:?}");
    assert_eq!(c.disagreements, 0, "{c:?}");
    assert_eq!(c.any_hit_disagreements, 0, "{c:?}");
    assert!(c.max_relative_dt <= 1e-4, "{c:?}");
    ctx.check_validation().unwrap();
}

#[test]
fn default_scene_closest_and_any_hit_match_the_cpu() {
    check(&default_scene(), 100_000);
}

/// The benchmark's kernel (compiled without textures) on a scene without textures or alpha
/// masks gives exactly the textured kernel's hits.
#[test]
fn opaque_kernel_matches_the_textured_one_on_an_untextured_scene() {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let ctx = common::context(1);
    let gpu_scene = GpuScene::new(&scene, &bvh);
    let rays = random_rays(&scene, 20_000);
    let hits = |opaque: bool| {
        let mut raycaster = Raycaster::new(&ctx, &gpu_scene, rays.len(), opaque).unwrap();
        [false, true].map(|any| raycaster.cast(&rays, any, 1).unwrap().0)
    };
    assert_eq!(hits(true), hits(false));
    ctx.check_validation().unwrap();
}

#[test]
fn cornell_box_closest_and_any_hit_match_the_cpu() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/cornell_box/CornellBox-Original.gltf");
    check(&load_gltf(path).unwrap(), 20_000);
}

/// Needs `PARALLAX_SPONZA=/path/to/Sponza.gltf`; its alpha-masked leaves are sampled on both
/// sides.
#[test]
#[ignore = "needs PARALLAX_SPONZA; CI runs it with --ignored"]
fn sponza_closest_and_any_hit_match_the_cpu() {
    let path = std::env::var("PARALLAX_SPONZA").expect("set PARALLAX_SPONZA to Sponza.gltf");
    check(&load_gltf(&path).unwrap(), 100_000);
}
