//! Subsampled hole filling (`HoleFillMode::Subsampled`, passes/src/hole_subsample.rs) in the
//! whole pipeline on lavapipe, validation on, the default scene: the traced subset is the
//! rotating 2×2 pattern it claims, with the fallback where no similar traced neighbour exists
//! (checked against a CPU twin and the lists' entries); traced pixels keep path tracing's
//! bits and reconstructed ones are the weighted mean of their traced neighbours; a still camera
//! traces every hole pixel within 4 frames; isolated holes are always traced; and under
//! `--denoise samples` a hole pixel's running mean counts its traced frames only.

mod common;

use parallax_backend::{ExecOptions, KernelGraph, KernelPlan};
use parallax_graph::{AssignStrategy, FamilyId, LayoutSpec, LightField, Partition, PartitionConfig, Scheme, compile};
use parallax_passes::LightFieldRenderer;
use parallax_passes::camera::{lightfield_views, rig_of};
use parallax_passes::firefly::FireflyMode;
use parallax_passes::hole_subsample::{
    HoleFillMode, SAMPLING_NONE, SAMPLING_RECONSTRUCTED, SAMPLING_TRACED, SUBSAMPLING_PERIOD,
};
use parallax_passes::pipeline::{Denoiser, PipelineConfig, PipelineHandles, PipelineKind, declare_pipeline};
use parallax_scene::gpu::GpuScene;
use parallax_scene::{SceneBvh, TraceSettings, default_scene};

const SIZE: u32 = 32;
/// Frames of every run: the 2×2 turns' period and one more.
const FRAMES: u32 = SUBSAMPLING_PERIOD + 1;
/// The weights' thresholds (shaders/hole_subsample.glsl).
const SIMILAR_COS: f32 = 0.9;
const PLANE_TOLERANCE: f32 = 0.02;

/// One target view of one frame, read back.
struct Target {
    /// The pipeline's output: `denoised` where it denoises, else `radiance` (Rgba32f).
    output: Vec<f32>,
    holes: Vec<u32>,
    position: Vec<f32>,
    normal: Vec<f32>,
    /// `hole_sampling` (empty under `Full`).
    sampling: Vec<u32>,
    /// The pixel indices `hole_list` and `hole_reconstruct_list` hold, sorted (`Subsampled`).
    listed: (Vec<usize>, Vec<usize>),
}

/// Per frame, the target views.
type Frames = Vec<Vec<Target>>;

fn words(bytes: &[u8]) -> Vec<u32> {
    bytes.chunks_exact(4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

fn light_field() -> LightField {
    let scene = default_scene();
    let rig = rig_of(&scene.default_camera(), scene.bounds().center(), None);
    LightField::new(LayoutSpec::Grid { cols: 4, rows: 2 }, Some(0.02), Some((SIZE, SIZE)), rig).unwrap()
}

/// `FRAMES` still frames of the pipeline `config` declares, on one device, read back.
fn run(config: &PipelineConfig) -> Frames {
    let scene = default_scene();
    let lf = light_field();
    let partition_config =
        PartitionConfig { devices: 1, scheme: Scheme::MultiSource, assign: AssignStrategy::Compact, sources: None };
    let partition = Partition::new(&lf, &partition_config).unwrap();
    let mut graph = KernelGraph::with_payload(partition.topology.clone());
    let handles = declare_pipeline(&mut graph, config).unwrap();
    graph.export(&handles.display);
    let families = families(&handles);
    let schedule = compile(&graph, &partition).unwrap();
    let exec = KernelPlan::from_schedule(&graph, &schedule).unwrap();
    let ctx = common::context(1);
    let bvh = SceneBvh::build(&scene);
    let mut renderer =
        LightFieldRenderer::with_options(&ctx, exec, &GpuScene::new(&scene, &bvh), ExecOptions::default()).unwrap();
    let settings = TraceSettings { spp: 1, max_depth: 3, ..Default::default() };
    let views = lightfield_views(&lf);
    let mut frames = Vec::new();
    for frame in 0..FRAMES {
        renderer.submit(&scene, &views, &TraceSettings { frame, ..settings }).unwrap();
        renderer.finish().unwrap();
        let targets = (0..lf.len() as u32).filter(|&v| !partition.topology.is_source[v as usize]);
        let mut read = |family: FamilyId, v: u32| renderer.read(family, v).unwrap();
        let frame = targets
            .map(|v| {
                let layers: Vec<Vec<u8>> = families.iter().map(|&f| read(f, v)).collect();
                let listed = |i: usize| layers.get(i).map(|list| listed_pixels(list)).unwrap_or_default();
                Target {
                    output: common::floats(&layers[0]),
                    holes: words(&layers[1]),
                    position: common::floats(&layers[2]),
                    normal: common::floats(&layers[3]),
                    sampling: layers.get(4).map(|l| words(l)).unwrap_or_default(),
                    listed: (listed(5), listed(6)),
                }
            })
            .collect();
        frames.push(frame);
    }
    drop(renderer);
    ctx.check_validation().unwrap();
    frames
}

/// The pixels (y · SIZE + x) of a view's pixel list, sorted: one band per view on one device,
/// so its header (`groups_x, groups_y, groups_z, count`) is at its start.
fn listed_pixels(list: &[u8]) -> Vec<usize> {
    let words = words(list);
    let count = words[3] as usize;
    let mut pixels: Vec<usize> =
        words[4..4 + count].iter().map(|&e| ((e >> 16) * SIZE + (e & 0xffff)) as usize).collect();
    pixels.sort_unstable();
    pixels
}

/// The families [`run`] reads, in [`Target`]'s order; the subsampling's last, where declared.
fn families(h: &PipelineHandles) -> Vec<FamilyId> {
    let mut families = vec![
        h.denoised.as_ref().unwrap_or(&h.radiance).family(),
        h.holes.as_ref().unwrap().family(),
        h.gbuffer.position_depth.family(),
        h.gbuffer.normal_metallic.family(),
    ];
    if let Some(subsampled) = &h.subsampled_holes {
        families.extend([subsampled.sampling.family(), subsampled.traced.family(), subsampled.reconstructed.family()]);
    }
    families
}

/// The pipeline without a denoiser (fireflies kept): the output is the radiance as filled.
fn undenoised(hole_fill: HoleFillMode) -> PipelineConfig {
    PipelineConfig {
        denoise: Denoiser::None,
        fireflies: FireflyMode::Keep,
        hole_fill,
        ..common::denoising_pipeline(PipelineKind::Reproject)
    }
}

/// CPU twin of shaders/compact_holes_subsampled.comp and hole_subsample.glsl over one view.
struct Twin<'a>(&'a Target);

/// How a CPU similarity compares with the shader's thresholds.
#[derive(Debug, PartialEq)]
enum Similar {
    Yes(f32),
    No,
    /// Within rounding of a threshold: the GPU may decide either way.
    Borderline,
}

impl Twin<'_> {
    fn index(&self, (x, y): (i32, i32)) -> Option<usize> {
        let inside = (0..SIZE as i32).contains(&x) && (0..SIZE as i32).contains(&y);
        inside.then(|| (y as u32 * SIZE + x as u32) as usize)
    }

    fn position(&self, i: usize) -> [f32; 4] {
        self.0.position[4 * i..4 * i + 4].try_into().unwrap()
    }

    fn normal(&self, i: usize) -> [f32; 3] {
        self.0.normal[4 * i..4 * i + 3].try_into().unwrap()
    }

    fn surface_hole(&self, p: (i32, i32)) -> bool {
        self.index(p).is_some_and(|i| self.0.holes[i] != 0 && self.position(i)[3] > 0.0)
    }

    /// Whether surface hole `q` is its 2×2 block's turn in `frame`.
    fn turn_traced(&self, q: (i32, i32), frame: u32) -> bool {
        let members: Vec<(i32, i32)> =
            (0..4).map(|i| ((q.0 & !1) + (i & 1), (q.1 & !1) + (i >> 1))).filter(|&c| self.surface_hole(c)).collect();
        let rank = members.iter().position(|&c| c == q).unwrap() as u32;
        rank == frame % members.len() as u32
    }

    fn similarity(&self, p: usize, q: usize) -> Similar {
        let (pp, pq, np, nq) = (self.position(p), self.position(q), self.normal(p), self.normal(q));
        if pp[3] <= 0.0 || pq[3] <= 0.0 {
            return Similar::No;
        }
        let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let cos = dot(np, nq);
        let offset = [pq[0] - pp[0], pq[1] - pp[1], pq[2] - pp[2]];
        let tolerance = PLANE_TOLERANCE * pp[3];
        let plane = dot(np, offset).abs().max(dot(nq, offset).abs());
        let near = |a: f32, b: f32| (a - b).abs() <= 1e-5 * b.abs().max(1e-3);
        if near(cos, SIMILAR_COS) || near(plane, tolerance) {
            return Similar::Borderline;
        }
        if cos < SIMILAR_COS || plane > tolerance {
            return Similar::No;
        }
        Similar::Yes(cos.powi(8) * (1.0 - 0.5 * plane / tolerance))
    }

    /// The output's mean over the traced neighbours of `p` similar to it, weighted by their
    /// similarity (what hole_reconstruct.comp gives a reconstructed pixel); None without one.
    fn mean_of_traced_neighbours(&self, p: (i32, i32)) -> Option<[f64; 4]> {
        let i = self.index(p).unwrap();
        let (mut sum, mut weights) = ([0.0f64; 4], 0.0f64);
        for j in neighbours(p).filter_map(|q| self.index(q)).filter(|&j| self.0.sampling[j] == SAMPLING_TRACED) {
            if let Similar::Yes(w) = self.similarity(i, j) {
                for (s, value) in sum.iter_mut().zip(&self.0.output[4 * j..4 * j + 4]) {
                    *s += f64::from(w) * f64::from(*value);
                }
                weights += f64::from(w);
            }
        }
        (weights > 0.0).then(|| sum.map(|s| s / weights))
    }

    /// The sampling the shader must choose for pixel `p` in `frame`, or None where a similarity
    /// it depends on is borderline.
    fn sampling(&self, p: (i32, i32), frame: u32) -> Option<u32> {
        let i = self.index(p).unwrap();
        if self.0.holes[i] == 0 {
            return Some(SAMPLING_NONE);
        }
        if !self.surface_hole(p) || self.turn_traced(p, frame) {
            return Some(SAMPLING_TRACED);
        }
        let mut borderline = false;
        for q in neighbours(p) {
            if self.surface_hole(q) && self.turn_traced(q, frame) {
                match self.similarity(i, self.index(q).unwrap()) {
                    Similar::Yes(_) => return Some(SAMPLING_RECONSTRUCTED),
                    Similar::Borderline => borderline = true,
                    Similar::No => {}
                }
            }
        }
        (!borderline).then_some(SAMPLING_TRACED)
    }
}

fn neighbours((x, y): (i32, i32)) -> impl Iterator<Item = (i32, i32)> {
    (-1..=1).flat_map(move |dy| (-1..=1).map(move |dx| (x + dx, y + dy))).filter(move |&q| q != (x, y))
}

fn pixels() -> impl Iterator<Item = (i32, i32)> {
    (0..SIZE as i32).flat_map(|y| (0..SIZE as i32).map(move |x| (x, y)))
}

#[test]
fn the_traced_hole_pixels_are_the_rotating_pattern_and_the_rest_their_neighbours_weighted_mean() {
    let subsampled = run(&undenoised(HoleFillMode::Subsampled));
    let full = run(&undenoised(HoleFillMode::Full));
    let (mut holes, mut traced, mut borderline) = (0usize, 0usize, 0usize);
    for (frame, (views, full_views)) in subsampled.iter().zip(&full).enumerate() {
        for (view, (t, f)) in views.iter().zip(full_views).enumerate() {
            let at = format!("frame {frame}, target {view}");
            assert_eq!(t.holes, f.holes, "{at}: both runs find the same holes");
            let flagged = |s: u32| (0..t.sampling.len()).filter(|&i| t.sampling[i] == s).collect::<Vec<_>>();
            let lists = (flagged(SAMPLING_TRACED), flagged(SAMPLING_RECONSTRUCTED));
            assert_eq!(t.listed, lists, "{at}: the lists hold the pixels flagged, each once");
            let twin = Twin(t);
            for p in pixels() {
                let i = twin.index(p).unwrap();
                let got = t.sampling[i];
                match twin.sampling(p, frame as u32) {
                    Some(expected) => assert_eq!(got, expected, "{at}: pixel {p:?}"),
                    None => borderline += 1,
                }
                let (rgba, full_rgba) = (&t.output[4 * i..4 * i + 4], &f.output[4 * i..4 * i + 4]);
                assert!(rgba.iter().all(|v| v.is_finite()), "{at}: pixel {p:?} is {rgba:?}");
                holes += usize::from(got != SAMPLING_NONE);
                traced += usize::from(got == SAMPLING_TRACED);
                if got != SAMPLING_RECONSTRUCTED {
                    // Traced holes keep hole_fill's bits, and the other pixels reprojection's.
                    let bits = |v: &[f32]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(rgba), bits(full_rgba), "{at}: pixel {p:?}");
                    continue;
                }
                let mean = twin.mean_of_traced_neighbours(p);
                assert!(mean.is_some(), "{at}: pixel {p:?} has a similar traced neighbour");
                for (&got, expected) in rgba.iter().zip(mean.unwrap()) {
                    let error = (f64::from(got) - expected).abs() / expected.abs().max(1e-3);
                    assert!(error <= 1e-5, "{at}: pixel {p:?}: {rgba:?} against {expected}");
                }
            }
        }
    }
    let fraction = traced as f64 / holes as f64;
    eprintln!("{holes} hole pixels over {FRAMES} frames, {traced} traced ({fraction:.3}), {borderline} borderline");
    assert!(borderline * 100 < holes, "few decisions are within rounding of a threshold");
    // Dense enough for the pattern to save paths, so the test can fail.
    assert!(holes > 0 && fraction < 0.75, "{traced} of {holes}");
}

#[test]
fn a_still_camera_traces_every_hole_pixel_within_four_frames_and_isolated_ones_always() {
    let frames = run(&undenoised(HoleFillMode::Subsampled));
    let (mut holes, mut isolated) = (0usize, 0usize);
    for view in 0..frames[0].len() {
        let first = &frames[0][view];
        let twin = Twin(first);
        for p in pixels() {
            let i = twin.index(p).unwrap();
            if first.holes[i] == 0 {
                continue;
            }
            holes += 1;
            let sampling: Vec<u32> = frames.iter().map(|f| f[view].sampling[i]).collect();
            assert!(frames.iter().all(|f| f[view].holes[i] != 0), "target {view}, {p:?}: a still camera's holes stay");
            let within_period = &sampling[..SUBSAMPLING_PERIOD as usize];
            assert!(within_period.contains(&SAMPLING_TRACED), "target {view}, {p:?}: {sampling:?}");
            let alone = neighbours(p).all(|q| twin.index(q).is_none_or(|j| first.holes[j] == 0));
            if alone {
                isolated += 1;
                assert!(sampling.iter().all(|&s| s == SAMPLING_TRACED), "target {view}, {p:?}: {sampling:?}");
            }
        }
    }
    eprintln!("{holes} hole pixels, {isolated} isolated");
    assert!(isolated > 0, "the light field has isolated holes, so the test can fail");
}

#[test]
fn denoising_the_samples_accumulates_only_the_traced_frames_of_a_hole_pixel() {
    // The same holes and the same pattern in both runs (both are functions of the geometry and
    // the frame); without a denoiser a traced hole pixel shows its frame's sample.
    let samples = PipelineConfig {
        denoise: Denoiser::Samples,
        hole_fill: HoleFillMode::Subsampled,
        ..common::denoising_pipeline(PipelineKind::Reproject)
    };
    let accumulated = run(&samples);
    let traced = run(&undenoised(HoleFillMode::Subsampled));
    let (mut checked, mut skipped_frames, mut worst) = (0usize, 0usize, 0.0f64);
    for view in 0..accumulated[0].len() {
        for i in 0..(SIZE * SIZE) as usize {
            if accumulated[0][view].holes[i] == 0 {
                continue;
            }
            let mut sum = [0.0f64; 3];
            let mut frames_traced = 0u32;
            for (a, t) in accumulated.iter().zip(&traced) {
                let (a, t) = (&a[view], &t[view]);
                assert_eq!(a.sampling[i], t.sampling[i], "target {view}, pixel {i}: the same pattern");
                if a.sampling[i] == SAMPLING_TRACED {
                    frames_traced += 1;
                    for (c, s) in sum.iter_mut().enumerate() {
                        *s += f64::from(t.output[4 * i + c].clamp(0.0, 1e8));
                    }
                }
                if frames_traced == 0 {
                    // Not traced yet: its neighbours' value, no mean of its own.
                    skipped_frames += 1;
                    continue;
                }
                checked += 1;
                for (c, s) in sum.iter().enumerate() {
                    let mean = s / f64::from(frames_traced);
                    worst = worst.max((f64::from(a.output[4 * i + c]) - mean).abs() / mean.abs().max(1e-3));
                }
            }
        }
    }
    eprintln!("{checked} pixel frames checked ({skipped_frames} before a first trace); worst {worst:.2e}");
    assert!(checked > 0 && skipped_frames > 0, "the pattern leaves pixels untraced, so the test can fail");
    assert!(worst <= 1e-5, "a hole pixel is {worst:.2e} (relative) off the mean of its traced samples");
}
