//! The CPU reference path tracer: energy conservation, analytic direct lighting, determinism
//! across pixel subsets, finite outputs, and the EXR/PNG writers.

use std::f32::consts::PI;
use std::path::Path;

use glam::{Vec2, Vec3};
use parallax_scene::metrics::channel_stats;
use parallax_scene::output::{ExrLayers, read_exr_channels, write_contact_sheet, write_exr};
use parallax_scene::{
    Camera, CpuTracer, Material, PixelSample, PixelSet, Scene, SceneBuilder, SceneBvh, Sky, Sun, TraceSettings, View,
    default_scene, load_gltf, white_furnace_scene,
};

fn view(camera: Camera, w: u32, h: u32) -> View {
    View { camera, width: w, height: h, index: 0 }
}

fn trace_all(scene: &Scene, v: &View, s: &TraceSettings) -> Vec<PixelSample> {
    let bvh = SceneBvh::build(scene);
    let tracer = CpuTracer::new(scene, &bvh);
    let (px, stats) = tracer.trace(v, s, &PixelSet::All, &|_| {}).unwrap();
    assert_eq!(stats.non_finite_samples, 0);
    px
}

/// White furnace: closed albedo-1 Lambert objects under a uniform sky of radiance 1 reflect
/// exactly what they receive, so every pixel (object or sky) has expected value 1. Two objects
/// close together make paths bounce between them; sky NEE and BSDF sampling are combined with
/// MIS, so a wrong weight or pdf shows up as a biased mean.
#[test]
fn white_furnace_returns_the_sky_radiance() {
    let scene = white_furnace_scene();
    let v = view(Camera::look_at(Vec3::new(0.0, 0.3, 3.0), Vec3::ZERO, Vec3::Y, 0.7), 32, 24);
    let s = TraceSettings { spp: 64, max_depth: 64, ..Default::default() };
    let px = trace_all(&scene, &v, &s);
    let hits = px.iter().filter(|p| p.hit).count();
    assert!(hits > px.len() / 3, "the objects should fill much of the frame: {hits}");
    let radiance: Vec<Vec3> = px.iter().filter(|p| p.hit).map(|p| p.radiance).collect();
    let stats = channel_stats(&radiance);
    for c in 0..3 {
        assert!((stats.mean[c] - 1.0).abs() < 0.01, "channel {c}: mean {}", stats.mean[c]);
    }
    // Not merely right on average: no pixel far off either.
    for p in &radiance {
        assert!((p.x - 1.0).abs() < 0.25, "{p}");
    }
}

/// A diffuse floor under a delta sun of irradiance E at angle theta, black sky, depth 1:
/// outgoing radiance is albedo * E * cos(theta) / pi exactly, for every pixel.
#[test]
fn delta_sun_direct_lighting_is_analytic() {
    let mut b = SceneBuilder::new("floor");
    let grey = b.material(Material::diffuse("grey", Vec3::splat(0.5)));
    b.quad(Vec3::new(-50.0, 0.0, 50.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -100.0), grey);
    let mut scene = b.build();
    let to_sun = Vec3::new(0.3, 0.8, 0.2).normalize();
    scene.sun = Some(Sun { to_sun, irradiance: Vec3::new(3.0, 2.0, 1.0), angular_radius: 0.0 });
    let v = view(Camera::look_at(Vec3::new(0.0, 2.0, 2.0), Vec3::ZERO, Vec3::Y, 0.5), 8, 8);
    let px = trace_all(&scene, &v, &TraceSettings { spp: 4, max_depth: 1, ..Default::default() });
    let expected = 0.5 * Vec3::new(3.0, 2.0, 1.0) * to_sun.y / PI;
    for p in &px {
        assert!(p.hit);
        assert!((p.radiance - expected).abs().max_element() < 1e-4, "{} vs {expected}", p.radiance);
    }
}

/// The same with a sun disc of 5 degrees radius: NEE samples the disc, BSDF rays can hit it,
/// MIS combines them; the mean over the image must match the delta-sun value within 1 %.
#[test]
fn sun_disc_with_mis_matches_the_analytic_value() {
    let mut b = SceneBuilder::new("floor");
    let grey = b.material(Material::diffuse("grey", Vec3::splat(0.5)));
    b.quad(Vec3::new(-50.0, 0.0, 50.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -100.0), grey);
    let mut scene = b.build();
    let to_sun = Vec3::new(0.0, 1.0, 0.0);
    scene.sun = Some(Sun { to_sun, irradiance: Vec3::ONE, angular_radius: 5f32.to_radians() });
    let v = view(Camera::look_at(Vec3::new(0.0, 2.0, 2.0), Vec3::ZERO, Vec3::Y, 0.5), 16, 16);
    let px = trace_all(&scene, &v, &TraceSettings { spp: 64, max_depth: 1, ..Default::default() });
    let stats = channel_stats(&px.iter().map(|p| p.radiance).collect::<Vec<_>>());
    // Uniform disc of radiance L = E / (pi sin^2 r) over a cosine-weighted floor: exactly
    // albedo * E / pi for a sun at the zenith.
    let expected = 0.5 / PI as f64;
    assert!((stats.mean[0] - expected).abs() < 0.01 * expected, "{} vs {expected}", stats.mean[0]);
}

/// An emissive quad over a white floor at depth 1 (NEE on the lamp's triangles + BSDF hits,
/// weighted by MIS) against a numerical integration of the irradiance below the lamp.
#[test]
fn emissive_quad_direct_lighting_matches_numerical_integration() {
    let mut b = SceneBuilder::new("lamp");
    let grey = b.material(Material::diffuse("grey", Vec3::ONE));
    let lamp = b.material(Material::emitter("lamp", Vec3::splat(2.0)));
    b.quad(Vec3::new(-5.0, 0.0, 5.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -10.0), grey);
    // 1 x 1 lamp at height 1, facing down.
    b.quad(Vec3::new(-0.5, 1.0, 0.5), Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 0.0), lamp);
    let scene = b.build();
    // Camera straight down at the floor from just below the lamp; centre pixel sees (0,0,0).
    let cam =
        Camera { eye: Vec3::new(0.0, 0.9, 0.0), forward: Vec3::NEG_Y, up: Vec3::NEG_Z, yfov: 0.01, shift: Vec2::ZERO };
    let v = view(cam, 3, 3);
    let px = trace_all(&scene, &v, &TraceSettings { spp: 4096, max_depth: 1, jitter: false, ..Default::default() });
    let got = px[4].radiance.x as f64;
    // Irradiance at the origin from a unit square at height 1 with radiance 2, by midpoint rule.
    let n = 400;
    let mut e = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let x = -0.5 + (i as f64 + 0.5) / n as f64;
            let z = -0.5 + (j as f64 + 0.5) / n as f64;
            let d2 = x * x + z * z + 1.0;
            // cos at floor = 1/d, cos at lamp = 1/d, dA / d^2.
            e += 2.0 / (d2 * d2) / (n * n) as f64;
        }
    }
    let expected = e / std::f64::consts::PI; // albedo 1 Lambert
    assert!((got - expected).abs() < 0.01 * expected, "{got} vs {expected}");
}

#[test]
fn any_pixel_subset_gives_identical_values() {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let tracer = CpuTracer::new(&scene, &bvh);
    let v = View { camera: scene.default_camera(), width: 24, height: 16, index: 5 };
    let s = TraceSettings { spp: 2, frame: 3, ..Default::default() };
    let (all, _) = tracer.trace(&v, &s, &PixelSet::All, &|_| {}).unwrap();
    let (band, _) = tracer.trace(&v, &s, &PixelSet::Rows { start: 5, end: 9 }, &|_| {}).unwrap();
    assert_eq!(band.len(), 4 * 24);
    for (k, p) in band.iter().enumerate() {
        assert_eq!(*p, all[5 * 24 + k]);
    }
    // A scattered list in reverse order, as a hole-filling pass would compact it.
    let list: Vec<(u32, u32)> = (0..v.pixel_count() as u32).rev().step_by(7).map(|i| (i % 24, i / 24)).collect();
    let (picked, _) = tracer.trace(&v, &s, &PixelSet::List(list.clone()), &|_| {}).unwrap();
    for (p, (x, y)) in picked.iter().zip(&list) {
        assert_eq!(*p, all[(y * 24 + x) as usize]);
    }
    // And the view index and frame are part of the key: other values, other noise.
    let (other_frame, _) = tracer.trace(&v, &TraceSettings { frame: 4, ..s }, &PixelSet::All, &|_| {}).unwrap();
    assert_ne!(other_frame, all);
}

fn assert_all_finite(px: &[PixelSample]) {
    for p in px {
        let vals = [p.radiance, p.albedo, p.normal, p.position];
        assert!(vals.iter().all(|v| v.is_finite()), "{p:?}");
        assert!(p.depth.is_finite() && p.roughness.is_finite() && p.metallic.is_finite());
        if p.hit {
            assert!((p.normal.length() - 1.0).abs() < 1e-3);
            assert!(p.depth > 0.0);
        } else {
            assert_eq!((p.depth, p.normal), (0.0, Vec3::ZERO));
        }
    }
}

#[test]
fn default_scene_and_cornell_box_outputs_are_finite() {
    let scene = default_scene();
    let v = view(scene.default_camera(), 48, 32);
    let px = trace_all(&scene, &v, &TraceSettings { spp: 4, ..Default::default() });
    assert_all_finite(&px);
    assert!(px.iter().any(|p| p.hit) && px.iter().any(|p| !p.hit), "the default view shows sky and geometry");
    assert!(px.iter().any(|p| p.metallic > 0.5), "a metal object is in view");

    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/cornell_box/CornellBox-Original.gltf");
    let cornell = load_gltf(path).unwrap();
    let v = view(cornell.default_camera(), 32, 32);
    let px = trace_all(&cornell, &v, &TraceSettings { spp: 8, ..Default::default() });
    assert_all_finite(&px);
    let mean = channel_stats(&px.iter().map(|p| p.radiance).collect::<Vec<_>>()).mean;
    // Lit by its ceiling lamp only: clearly non-black, and warm (the lamp is orange-white).
    assert!(mean[0] > 0.1 && mean[0] > mean[2], "{mean:?}");
}

#[test]
fn exr_round_trip_and_contact_sheet() {
    let scene = default_scene();
    let bvh = SceneBvh::build(&scene);
    let tracer = CpuTracer::new(&scene, &bvh);
    let mut frames = Vec::new();
    for i in 0..3 {
        let mut camera = scene.default_camera();
        camera.eye.x += 0.2 * i as f32;
        let v = View { camera, width: 20, height: 12, index: i };
        frames.push(tracer.render(&v, &TraceSettings::default(), &|_| {}).unwrap().0);
    }
    let dir = std::env::temp_dir().join(format!("parallax-scene-{}-exr", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("view0.exr");
    write_exr(&exr, &frames[0], ExrLayers::ALL).unwrap();
    let (w, h, ch) = read_exr_channels(&exr, &["R", "G", "B", "albedo.G", "normal.Y", "depth.Z"]).unwrap();
    assert_eq!((w, h), (20, 12));
    for (i, p) in frames[0].pixels.iter().enumerate() {
        assert_eq!(ch[0][i], p.radiance.x);
        assert_eq!(ch[2][i], p.radiance.z);
        assert_eq!(ch[3][i], p.albedo.y);
        assert_eq!(ch[4][i], p.normal.y);
        assert_eq!(ch[5][i], p.depth);
    }
    let png = dir.join("sheet.png");
    let refs: Vec<_> = frames.iter().collect();
    write_contact_sheet(&png, &refs, 2, 1.0).unwrap();
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (2 * 20 + 2, 2 * 12 + 2));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A point light of intensity I at height h over a white Lambert floor: the radiance of the
/// point straight below is I / h^2 / pi (depth 1, black sky), and a spot light aimed away
/// contributes nothing.
#[test]
fn point_light_direct_lighting_is_analytic() {
    use parallax_scene::{PunctualKind, PunctualLight};
    let mut b = SceneBuilder::new("floor");
    let white = b.material(Material::diffuse("white", Vec3::ONE));
    b.quad(Vec3::new(-50.0, 0.0, 50.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -100.0), white);
    let mut scene = b.build();
    scene.lights.push(PunctualLight {
        kind: PunctualKind::Point,
        position: Vec3::new(0.0, 2.0, 0.0),
        direction: Vec3::NEG_Y,
        color: Vec3::new(1.0, 0.5, 0.25),
        intensity: 8.0,
    });
    scene.lights.push(PunctualLight {
        kind: PunctualKind::Spot { inner_cone: 0.1, outer_cone: 0.2 },
        position: Vec3::new(0.0, 1.0, 0.0),
        direction: Vec3::Y,
        color: Vec3::ONE,
        intensity: 1000.0,
    });
    let cam =
        Camera { eye: Vec3::new(0.0, 1.0, 0.0), forward: Vec3::NEG_Y, up: Vec3::NEG_Z, yfov: 0.001, shift: Vec2::ZERO };
    let v = view(cam, 1, 1);
    let px = trace_all(&scene, &v, &TraceSettings { spp: 4096, max_depth: 1, jitter: false, ..Default::default() });
    // One light of two is chosen per sample: the estimate is exact on average, and with 4096
    // samples the binomial noise of the choice is about 1.6 %; compare to 5 %.
    let expected = Vec3::new(1.0, 0.5, 0.25) * 8.0 / 4.0 / PI;
    let got = px[0].radiance;
    assert!(((got - expected) / expected).abs().max_element() < 0.05, "{got} vs {expected}");
}

/// Alpha MASK: a quad whose texture is transparent on its left half lets camera rays through
/// there (showing the sky) and blocks them on the right.
#[test]
fn alpha_mask_cuts_holes_for_camera_and_shadow_rays() {
    use parallax_scene::{AlphaMode, Texture};
    let mut b = SceneBuilder::new("mask");
    let mut leaf = Material::diffuse("leaf", Vec3::splat(0.5));
    leaf.alpha_mode = AlphaMode::Mask(0.5);
    leaf.base_color_texture = Some(0);
    let m = b.material(leaf);
    // Facing +Z at z = 0, x in -1..1, y in -1..1; uv u runs left to right.
    b.quad(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), m);
    let mut scene = b.build();
    // 4x1 texture: two transparent texels on the left, two opaque on the right.
    let mut rgba8 = Vec::new();
    for a in [0u8, 0, 255, 255] {
        rgba8.extend_from_slice(&[255, 255, 255, a]);
    }
    scene.textures.push(Texture { width: 4, height: 1, rgba8 });
    scene.sky = Some(Sky::Constant(Vec3::splat(2.0)));
    scene.check().unwrap();
    let bvh = SceneBvh::build(&scene);
    let left = bvh.closest_hit(&scene, Vec3::new(-0.6, 0.0, 1.0), Vec3::NEG_Z, 0.0, f32::INFINITY);
    let right = bvh.closest_hit(&scene, Vec3::new(0.6, 0.0, 1.0), Vec3::NEG_Z, 0.0, f32::INFINITY);
    assert!(left.is_none(), "transparent half must be a hole");
    assert!(right.is_some(), "opaque half must be hit");
    assert!(!bvh.occluded(&scene, Vec3::new(-0.6, 0.0, 1.0), Vec3::NEG_Z, 0.0, 10.0));
    assert!(bvh.occluded(&scene, Vec3::new(0.6, 0.0, 1.0), Vec3::NEG_Z, 0.0, 10.0));
}
