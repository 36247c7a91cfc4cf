//! The reconstruction pipeline's reprojection on lavapipe (validation on): with every view a
//! source it is plain path tracing bit for bit; sky pixels are never holes and get what path
//! tracing gives them; a view at its source's position misses nothing, and one 1 mm away on a
//! rough-glossy scene almost nothing, while mirror-like metals stay holes; the GPU's holes are
//! where the CPU twin of the view-dependence bound says; misses grow with the baseline; and
//! what is reprojected, glossy surfaces included, is an unbiased estimate of what path tracing
//! the same pixels gives.

mod common;

use glam::Vec3;
use parallax_backend::{KernelGraph, KernelPlan};
use parallax_graph::{AssignStrategy, LayoutSpec, LightField, Partition, PartitionConfig, Scheme, compile};
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_passes::firefly::FireflyMode;
use parallax_passes::hole_subsample::HoleFillMode;
use parallax_passes::pipeline::{Denoiser, GbufferSource, PipelineConfig, PipelineKind, declare_pipeline};
use parallax_passes::reproject::ReprojectionTolerances;
use parallax_passes::view_bound::{ViewBound, view_angle};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{Camera, Material, Scene, SceneBuilder, SceneBvh, Sky, Sun, TraceSettings, View, default_scene};

const SIZE: u32 = 32;

/// What one render runs: a `cols`×1 light field of `camera` over `scene`, neighbours `spacing`
/// metres apart (3 views: the middle one is the source).
#[derive(Clone, Copy)]
struct Setup<'s> {
    scene: &'s Scene,
    camera: Camera,
    cols: u32,
    spacing: f64,
    devices: u32,
    kind: PipelineKind,
    spp: u32,
    gbuffer: GbufferSource,
    tolerances: ReprojectionTolerances,
}

impl<'s> Setup<'s> {
    fn new(scene: &'s Scene, cols: u32, spacing: f64, kind: PipelineKind, spp: u32) -> Self {
        Setup {
            scene,
            camera: scene.default_camera(),
            cols,
            spacing,
            devices: 1,
            kind,
            spp,
            gbuffer: GbufferSource::FirstHits,
            tolerances: ReprojectionTolerances::default(),
        }
    }
}

/// A target's first-hit data, per pixel.
struct Gbuffer {
    position: Vec<[f32; 4]>,
    normal: Vec<[f32; 4]>,
    albedo: Vec<[f32; 4]>,
}

impl Gbuffer {
    fn surface(&self, i: usize) -> bool {
        self.position[i][3] > 0.0
    }

    /// Glossy or metal: what the diffuse gate this bound replaced never reprojected
    /// (roughness < 0.5 or metallic > 0.1).
    fn glossy(&self, i: usize) -> bool {
        self.surface(i) && (self.albedo[i][3] < 0.5 || self.normal[i][3] > 0.1)
    }

    /// A sky pixel next to a surface (8-neighbourhood; these tests reproject whole views):
    /// some of its jittered camera samples may hit that surface, so reprojection leaves it to
    /// hole filling.
    fn silhouette(&self, i: usize) -> bool {
        let (x, y, size) = ((i as u32 % SIZE) as i64, (i as u32 / SIZE) as i64, SIZE as i64);
        let neighbours = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (x + dx, y + dy)));
        !self.surface(i)
            && neighbours
                .filter(|&(qx, qy)| (0..size).contains(&qx) && (0..size).contains(&qy))
                .any(|(qx, qy)| self.surface((qy * size + qx) as usize))
    }

    /// A metal at most 0.1 rough: a mirror to within a pixel or two.
    fn mirror(&self, i: usize) -> bool {
        self.surface(i) && self.albedo[i][3] <= 0.1 && self.normal[i][3] >= 0.9
    }
}

/// One rendered light field: per view, radiance texels, and for targets of the reprojecting
/// pipeline the hole mask and the G-buffer.
struct Rendered {
    plan: Partition,
    views: Vec<View>,
    radiance: Vec<Vec<[f32; 4]>>,
    holes: Vec<Option<Vec<u32>>>,
    gbuffer: Vec<Option<Gbuffer>>,
}

fn texels(bytes: &[u8]) -> Vec<[f32; 4]> {
    bytes.chunks_exact(16).map(bytemuck::pod_read_unaligned).collect()
}

fn render(cols: u32, spacing: f64, devices: u32, kind: PipelineKind, spp: u32) -> Rendered {
    let scene = default_scene();
    render_setup(Setup { devices, ..Setup::new(&scene, cols, spacing, kind, spp) })
}

fn render_setup(s: Setup<'_>) -> Rendered {
    let bvh = SceneBvh::build(s.scene);
    let rig = rig_of(&s.camera, s.scene.bounds().center(), None);
    let lf =
        LightField::new(LayoutSpec::Grid { cols: s.cols, rows: 1 }, Some(s.spacing), Some((SIZE, SIZE)), rig).unwrap();
    let config = PartitionConfig {
        devices: s.devices,
        scheme: Scheme::MultiSource,
        assign: AssignStrategy::Compact,
        sources: None,
    };
    let plan = Partition::new(&lf, &config).unwrap();
    let mut graph = KernelGraph::with_payload(plan.topology.clone());
    let config = PipelineConfig {
        kind: s.kind,
        gbuffer: s.gbuffer,
        tolerances: s.tolerances,
        fireflies: FireflyMode::Keep,
        denoise: Denoiser::None,
        hole_fill: HoleFillMode::Full,
        exposure: 1.0,
    };
    let handles = declare_pipeline(&mut graph, &config).unwrap();
    graph.export(&handles.radiance);
    let schedule = compile(&graph, &plan).unwrap();
    let exec = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(s.devices as usize);
    let views = lightfield_views(&lf);
    let mut renderer = LightFieldRenderer::new(&ctx, exec, &GpuScene::new(s.scene, &bvh)).unwrap();
    let settings = TraceSettings { spp: s.spp, max_depth: 4, ..Default::default() };
    renderer.submit(s.scene, &views, &settings).unwrap();
    renderer.finish().unwrap();
    let mut out = Rendered { plan, views: views.clone(), radiance: Vec::new(), holes: Vec::new(), gbuffer: Vec::new() };
    for v in 0..views.len() as u32 {
        out.radiance.push(texels(&renderer.read(handles.radiance.family(), v).unwrap()));
        let is_target = !out.plan.topology.is_source[v as usize] && s.kind == PipelineKind::Reproject;
        if !is_target {
            // Only reprojection reads a target's G-buffer (else it is culled).
            out.holes.push(None);
            out.gbuffer.push(None);
            continue;
        }
        let holes = handles.holes.as_ref().expect("reprojection declares hole masks").family();
        out.holes.push(Some(bytemuck::cast_slice::<u8, u32>(&renderer.read(holes, v).unwrap()).to_vec()));
        let layers = &handles.gbuffer;
        out.gbuffer.push(Some(Gbuffer {
            position: texels(&renderer.read(layers.position_depth.family(), v).unwrap()),
            normal: texels(&renderer.read(layers.normal_metallic.family(), v).unwrap()),
            albedo: texels(&renderer.read(layers.albedo_roughness.family(), v).unwrap()),
        }));
    }
    drop(renderer);
    ctx.check_validation().unwrap();
    out
}

impl Rendered {
    fn targets(&self) -> Vec<usize> {
        (0..self.radiance.len()).filter(|&v| !self.plan.topology.is_source[v]).collect()
    }

    fn holes(&self, v: usize) -> &[u32] {
        self.holes[v].as_deref().unwrap()
    }

    fn gbuffer(&self, v: usize) -> &Gbuffer {
        self.gbuffer[v].as_ref().unwrap()
    }

    /// Fraction of target `v`'s pixels that `class` selects which are holes, and how many it
    /// selects.
    fn missed(&self, v: usize, class: impl Fn(&Gbuffer, usize) -> bool) -> (f64, usize) {
        let (g, holes) = (self.gbuffer(v), self.holes(v));
        let selected: Vec<usize> = (0..holes.len()).filter(|&i| class(g, i)).collect();
        let missed = selected.iter().filter(|&&i| holes[i] == 1).count();
        (missed as f64 / selected.len().max(1) as f64, selected.len())
    }

    /// The source target `v` reprojects from (these tests use one per target).
    fn source_of(&self, v: usize) -> usize {
        let sources = &self.plan.topology.sources_of[v];
        assert_eq!(sources.len(), 1, "view {v}: one source");
        sources[0].index()
    }
}

/// A scene of rough-glossy materials only (roughness 0.25 to 0.5, dielectric and metal, none
/// of which the diffuse gate reprojected) and a mirror sphere, under a gradient sky and a sun
/// whose disc the camera sees.
fn glossy_scene() -> Scene {
    let mut b = SceneBuilder::new("glossy");
    let floor = b.material(Material::glossy("glossy floor", Vec3::new(0.5, 0.45, 0.4), 0.0, 0.3));
    let wall = b.material(Material::glossy("satin wall", Vec3::new(0.6, 0.6, 0.55), 0.0, 0.45));
    let blue = b.material(Material::glossy("blue gloss", Vec3::new(0.1, 0.2, 0.6), 0.0, 0.25));
    let gold = b.material(Material::glossy("brushed gold", Vec3::new(1.0, 0.78, 0.34), 1.0, 0.4));
    let copper = b.material(Material::glossy("copper", Vec3::new(0.95, 0.64, 0.54), 1.0, 0.3));
    let mirror = b.material(Material::glossy("mirror", Vec3::splat(0.95), 1.0, 0.0));
    b.quad(Vec3::new(-3.0, 0.0, 3.0), Vec3::new(6.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -6.0), floor);
    b.quad(Vec3::new(-3.0, 0.0, -3.0), Vec3::new(6.0, 0.0, 0.0), Vec3::new(0.0, 1.5, 0.0), wall);
    b.sphere(Vec3::new(-0.9, 0.4, 0.0), 0.4, 2, blue);
    b.sphere(Vec3::new(0.0, 0.4, -0.6), 0.4, 2, gold);
    b.sphere(Vec3::new(0.9, 0.4, 0.0), 0.4, 2, copper);
    b.sphere(Vec3::new(0.0, 0.35, 0.9), 0.35, 2, mirror);
    b.camera(Camera::look_at(Vec3::new(0.0, 1.2, 3.5), Vec3::new(0.0, 0.5, 0.0), Vec3::Y, 0.9));
    let mut scene = b.build();
    scene.sky = Some(Sky::Gradient {
        zenith: Vec3::new(0.15, 0.25, 0.5),
        horizon: Vec3::new(0.45, 0.5, 0.55),
        ground: Vec3::new(0.15, 0.13, 0.1),
    });
    scene.sun =
        Some(Sun { to_sun: Vec3::new(0.3, 0.5, -1.0).normalize(), irradiance: Vec3::splat(2.0), angular_radius: 0.04 });
    scene
}

/// A camera on `scene`'s default eye looking at its sun (disc and sky fill the view).
fn sun_camera(scene: &Scene) -> Camera {
    let eye = scene.default_camera().eye;
    Camera::look_at(eye, eye + scene.sun.unwrap().to_sun, Vec3::Y, 0.4)
}

#[test]
fn with_every_view_a_source_the_pipeline_is_path_tracing_bit_for_bit() {
    let reprojecting = render(2, 0.02, 2, PipelineKind::Reproject, 2);
    assert!(reprojecting.plan.topology.is_source.iter().all(|&s| s), "2 views on 2 devices: both are sources");
    let traced = render(2, 0.02, 1, PipelineKind::PathTrace, 2);
    assert_eq!(reprojecting.radiance, traced.radiance);
    assert!(traced.radiance[0].iter().any(|t| t[3] == 1.0), "the camera sees the scene");
}

#[test]
fn sky_pixels_are_never_holes_but_on_silhouettes_and_get_what_path_tracing_gives_them() {
    // Looking at the sun over the top of the glossy scene's wall: sky, sun disc and surfaces,
    // with the raster G-buffer too. 10 cm between views, so that surfaces have holes.
    let scene = glossy_scene();
    let camera =
        Camera::look_at(Vec3::new(0.0, 1.2, 3.5), Vec3::new(0.0, 1.2, 3.5) + Vec3::new(0.1, 0.2, -1.0), Vec3::Y, 0.9);
    for (camera, sun_in_view) in [(camera, false), (sun_camera(&scene), true)] {
        for gbuffer in [GbufferSource::FirstHits, GbufferSource::Raster] {
            let setup = Setup { camera, gbuffer, ..Setup::new(&scene, 3, 0.1, PipelineKind::Reproject, 1) };
            let reprojected = render_setup(setup);
            let traced = render_setup(Setup { kind: PipelineKind::PathTrace, ..setup });
            let (mut sky, mut sun, mut silhouettes) = (0, 0, 0);
            for v in reprojected.targets() {
                let (g, holes) = (reprojected.gbuffer(v), reprojected.holes(v));
                for i in (0..holes.len()).filter(|&i| !g.surface(i)) {
                    let (ours, theirs) = (reprojected.radiance[v][i], traced.radiance[v][i]);
                    if g.silhouette(i) {
                        assert_eq!(holes[i], 1, "{gbuffer:?}: view {v}, sky pixel {i} on a silhouette");
                        assert_eq!(ours, theirs, "{gbuffer:?}: view {v}, pixel {i}: hole filling is path tracing");
                        silhouettes += 1;
                        continue;
                    }
                    assert_eq!(holes[i], 0, "{gbuffer:?}: view {v}, sky pixel {i} is a hole");
                    assert_eq!(ours[3], 0.0, "a sky pixel has no first hit");
                    // Where path tracing's (jittered) camera sample missed too, the same sum of
                    // the same sky and sun terms: equal but for the compiler's contraction of
                    // the same expressions in two shaders.
                    if theirs[3] == 0.0 {
                        for c in 0..3 {
                            assert!(
                                (ours[c] - theirs[c]).abs() <= 1e-6 * theirs[c].abs().max(1.0),
                                "{gbuffer:?}: view {v}, pixel {i}: {ours:?} against path tracing's {theirs:?}"
                            );
                        }
                        sky += 1;
                        sun += usize::from(ours[0] > 10.0);
                    }
                }
            }
            assert!(sky > 100, "{gbuffer:?}: the camera sees the sky ({sky} pixels compared)");
            if sun_in_view {
                assert!(sun > 4, "{gbuffer:?}: the sun disc is in view ({sun} pixels)");
            } else {
                assert!(silhouettes > 10, "{gbuffer:?}: and silhouettes against it ({silhouettes} pixels)");
            }
        }
    }
}

#[test]
fn a_view_at_its_sources_position_has_no_hole_but_on_silhouettes() {
    // The same eye: the view direction does not change, so the bound is 0 even on a mirror.
    let scene = glossy_scene();
    let r = render_setup(Setup::new(&scene, 2, 0.0, PipelineKind::Reproject, 1));
    let t = r.targets();
    assert_eq!(t.len(), 1);
    let g = r.gbuffer(t[0]);
    assert!((0..g.position.len()).filter(|&i| g.mirror(i)).count() > 10, "the mirror sphere is in view");
    let holes = r.holes(t[0]);
    assert!((0..holes.len()).all(|i| (holes[i] == 1) == g.silhouette(i)), "holes only on silhouettes against the sky");
    assert!(r.radiance[t[0]].iter().flatten().all(|c| c.is_finite()));
}

#[test]
fn a_view_1mm_from_its_source_misses_almost_no_rough_glossy_pixel_and_every_mirror_pixel() {
    // 1 mm at 2.5 to 4.5 m: theta <= 4e-4 rad. On these materials' lobes (alpha >= 0.0625)
    // the bound is then at most ~3 % up to 60° off the normal, so with the default 20 %
    // tolerance almost no surface pixel is a hole (grazing floor pixels may be). The mirror
    // (alpha = MIN_ALPHA, 2.7 m away) has a bound above 60 % there: every pixel a hole.
    let scene = glossy_scene();
    let r = render_setup(Setup::new(&scene, 3, 0.001, PipelineKind::Reproject, 1));
    for v in r.targets() {
        let (glossy, n) = r.missed(v, |g, i| g.glossy(i) && !g.mirror(i));
        assert!(n > 500, "view {v}: {n} rough-glossy pixels (the diffuse gate reprojected none of them)");
        assert!(glossy < 0.01, "view {v}: {:.2} % of the rough-glossy pixels are holes", 100.0 * glossy);
        let (mirror, n) = r.missed(v, |g, i| g.mirror(i));
        assert!(n > 10, "view {v}: {n} mirror pixels");
        assert_eq!(mirror, 1.0, "view {v}: every mirror pixel is a hole");
    }
}

#[test]
fn the_gpus_holes_are_where_the_cpu_twin_of_the_bound_puts_them() {
    // 2 cm between views: some glossy pixels pass, some do not. A pixel the bound rejects (by
    // more than float rounding) must be a hole; a reprojected one must pass the bound.
    let scene = glossy_scene();
    let tolerance = ReprojectionTolerances::default().view_dependence;
    let r = render_setup(Setup::new(&scene, 3, 0.02, PipelineKind::Reproject, 1));
    let (mut passed, mut rejected) = (0, 0);
    for v in r.targets() {
        let (g, holes) = (r.gbuffer(v), r.holes(v));
        let (eye, source_eye) = (r.views[v].camera.eye, r.views[r.source_of(v)].camera.eye);
        for i in (0..holes.len()).filter(|&i| g.surface(i)) {
            let p = Vec3::from_slice(&g.position[i][..3]);
            let (to_eye, to_source) = ((eye - p).normalize(), (source_eye - p).normalize());
            let bound = ViewBound::new(
                Vec3::from_slice(&g.normal[i][..3]),
                to_eye,
                Vec3::from_slice(&g.albedo[i][..3]),
                g.normal[i][3],
                g.albedo[i][3],
            );
            let error = bound.error(view_angle(to_eye, to_source));
            if error > tolerance * 1.001 {
                assert_eq!(holes[i], 1, "view {v}, pixel {i}: bound {error} > {tolerance} but reprojected");
                rejected += 1;
            } else if holes[i] == 0 {
                assert!(error <= tolerance * 1.001, "view {v}, pixel {i}");
                passed += 1;
            }
        }
    }
    assert!(
        passed > 300 && rejected > 30,
        "both sides of the tolerance are tested: {passed} passed, {rejected} rejected"
    );
}

#[test]
fn missing_pixels_grow_with_the_baseline() {
    // Three views, the middle one the source: the outer targets sit one spacing away. Counted
    // over surfaces that are not mirrors (which are holes at any baseline but 0).
    let ratios: Vec<f64> = [0.001, 0.005, 0.02, 0.1]
        .iter()
        .map(|&spacing| {
            let r = render(3, spacing, 1, PipelineKind::Reproject, 1);
            let t = r.targets();
            t.iter().map(|&v| r.missed(v, |g, i| g.surface(i) && !g.mirror(i)).0).sum::<f64>() / t.len() as f64
        })
        .collect();
    assert!(ratios.windows(2).all(|w| w[0] <= w[1]), "non-decreasing with spacing: {ratios:?}");
    assert!(ratios[0] < 0.02, "1 mm misses under 2 % of the surface pixels: {ratios:?}");
    assert!(ratios[3] > ratios[0], "100 mm misses more than 1 mm: {ratios:?}");
}

/// Per target, the mean radiance over the reprojected pixels `class` selects, reprojected and
/// path traced, and how many pixels that is.
fn reprojected_means(
    reprojected: &Rendered,
    traced: &Rendered,
    class: impl Fn(&Gbuffer, usize) -> bool,
) -> Vec<(usize, f64, f64, usize)> {
    reprojected
        .targets()
        .into_iter()
        .map(|v| {
            let (g, holes) = (reprojected.gbuffer(v), reprojected.holes(v));
            let (mut a, mut b, mut n) = (0.0f64, 0.0f64, 0usize);
            for i in (0..holes.len()).filter(|&i| holes[i] == 0 && class(g, i)) {
                a += reprojected.radiance[v][i][..3].iter().map(|&c| c as f64).sum::<f64>();
                b += traced.radiance[v][i][..3].iter().map(|&c| c as f64).sum::<f64>();
                n += 1;
            }
            (v, a, b, n)
        })
        .collect()
}

#[test]
fn reprojected_pixels_match_path_tracing_the_same_pixels_on_average() {
    // Enough spp that a 2 % bound separates a bias from noise: the default scene at 2 cm
    // (mostly diffuse; every reprojected pixel) at 64 spp, and the glossy scene at 5 mm, where
    // the bound lets most of its rough-glossy pixels through, over those pixels only, at 256
    // spp (its sun's highlights make the mean over ~700 pixels scatter by ~2 % at 64 spp).
    let scene = default_scene();
    let glossy = glossy_scene();
    let cases = [(&scene, 0.02, 64, 300, false), (&glossy, 0.005, 256, 500, true)];
    for (scene, spacing, spp, least, only_glossy) in cases {
        let setup = Setup::new(scene, 3, spacing, PipelineKind::Reproject, spp);
        let reprojected = render_setup(setup);
        let traced = render_setup(Setup { kind: PipelineKind::PathTrace, ..setup });
        let class = |g: &Gbuffer, i: usize| !only_glossy || g.glossy(i);
        for (v, a, b, n) in reprojected_means(&reprojected, &traced, class) {
            assert!(n > least, "{}: view {v}: {n} reprojected pixels", scene.name);
            let relative = (a - b).abs() / b;
            assert!(
                relative < 0.02,
                "{}: view {v}: reprojected mean {a} vs traced {b} over {n} pixels ({relative:.4})",
                scene.name
            );
        }
    }
}

#[test]
fn a_wide_baseline_leaves_no_unfilled_pixel_after_hole_filling() {
    // 10 cm between neighbours: the outer targets see plenty the source does not.
    let reprojected = render(3, 0.1, 1, PipelineKind::Reproject, 1);
    let traced = render(3, 0.1, 1, PipelineKind::PathTrace, 1);
    for v in reprojected.targets() {
        let holes = reprojected.holes(v);
        let filled: Vec<usize> = (0..holes.len()).filter(|&i| holes[i] == 1).collect();
        assert!(filled.len() > 50, "view {v}: a wide baseline makes holes ({})", filled.len());
        for i in filled {
            // Hole filling path traces exactly the pixel path tracing would: same bits.
            assert_eq!(reprojected.radiance[v][i], traced.radiance[v][i], "view {v}, pixel {i}");
        }
        assert!(reprojected.radiance[v].iter().flatten().all(|c| c.is_finite()));
    }
}

#[test]
fn the_raster_gbuffer_reprojects_like_first_hits() {
    // A view at its source's position: with either G-buffer no surface pixel is missed, and
    // the raster one's hole pixels are path traced to the same bits as path tracing them.
    let scene = default_scene();
    let at_source = Setup { gbuffer: GbufferSource::Raster, ..Setup::new(&scene, 2, 0.0, PipelineKind::Reproject, 1) };
    let raster = render_setup(at_source);
    let t = raster.targets();
    let (missed, surfaces) = raster.missed(t[0], |g, i| g.surface(i));
    assert!(surfaces > 100);
    assert!(missed < 0.01, "{missed}");
    let wide = render_setup(Setup { spacing: 0.1, cols: 3, ..at_source });
    let traced = render(3, 0.1, 1, PipelineKind::PathTrace, 1);
    for v in wide.targets() {
        let holes = wide.holes(v);
        for i in (0..holes.len()).filter(|&i| holes[i] == 1) {
            assert_eq!(wide.radiance[v][i], traced.radiance[v][i], "view {v}, pixel {i}");
        }
        assert!(wide.radiance[v].iter().flatten().all(|c| c.is_finite()));
    }
}
