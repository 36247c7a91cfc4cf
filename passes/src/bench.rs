//! The rays/s benchmark behind `parallax bench-rays`: primary rays through pixel centres of a
//! camera, one cosine-distributed diffuse bounce from every primary hit, closest and any hit,
//! each cast several times; GPU time of the `raycast` pass from the executor's timestamps.
//! Materials are made opaque and untextured and the opaque kernel is used, so the figure is
//! traversal and intersection only (as the earlier measurements in docs/RESULTS.md). Rays are
//! ordered in 8x4-pixel tiles like the path tracer's subgroups; every ray schedule asked for
//! casts the same rays, and their hits must agree bit for bit.

use std::time::Instant;

use glam::{Vec2, Vec3};
use parallax_backend::Context;
use parallax_scene::gpu::GpuScene;
use parallax_scene::{AlphaMode, BvhQuality, Camera, Scene, SceneBvh};
use rayon::prelude::*;

use crate::error::{PassError, Result};
use crate::raycast::{CastTiming, HitOut, RayIn, RaySchedule, Raycaster};

/// One measured batch.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct RayRate {
    pub rays: usize,
    pub median_ms: f64,
    pub best_ms: f64,
    /// Rays per second at the median time.
    pub rays_per_s: f64,
}

impl RayRate {
    fn new(rays: usize, t: CastTiming) -> Self {
        Self {
            rays,
            median_ms: t.median_ns / 1e6,
            best_ms: t.best_ns / 1e6,
            rays_per_s: rays as f64 / (t.median_ns * 1e-9),
        }
    }
}

/// What [`bench_rays`] measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RayBench {
    pub device: String,
    pub triangles: usize,
    pub bvh_nodes: usize,
    /// `SceneBvh::build` wall time (obvhs build plus reordering), ms.
    pub bvh_build_ms: f64,
    /// obvhs core build time, ms.
    pub bvh_core_build_ms: f64,
    pub width: u32,
    pub height: u32,
    pub repeats: usize,
    /// One entry per ray schedule, in the order asked for, measured in one run.
    pub schedules: Vec<ScheduleRates>,
}

/// Rays/s of one [`RaySchedule`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ScheduleRates {
    pub schedule: String,
    pub primary: RayRate,
    pub diffuse_bounce: RayRate,
    pub diffuse_bounce_any_hit: RayRate,
}

/// Measures rays/s on device 0 of `context` for `scene` seen from `camera` at `width`×`height`
/// (median of `repeats` casts per batch), with a BVH built at `quality`, under each of
/// `schedules` (at least one) on the same rays. Fails with
/// [`PassError::ScheduleChangedHits`] if two schedules disagree on any hit bit.
pub fn bench_rays(
    context: &Context,
    mut scene: Scene,
    camera: Camera,
    (width, height): (u32, u32),
    repeats: usize,
    quality: BvhQuality,
    schedules: &[RaySchedule],
) -> Result<RayBench> {
    let schedules = if schedules.is_empty() { &[RaySchedule::PerRay][..] } else { schedules };
    for m in &mut scene.materials {
        m.alpha_mode = AlphaMode::Opaque;
        m.base_color_texture = None;
        m.metallic_roughness_texture = None;
        m.emissive_texture = None;
    }
    scene.textures.clear();
    let started = Instant::now();
    let bvh = SceneBvh::build_with(&scene, quality);
    let build = started.elapsed();
    let gpu_scene = GpuScene::new(&scene, &bvh);
    let pixels = width as usize * height as usize;
    let mut raycasters = schedules
        .iter()
        .map(|&schedule| Raycaster::new(context, &gpu_scene, pixels, true, schedule))
        .collect::<Result<Vec<_>>>()?;

    let aspect = width as f32 / height as f32;
    // Rays in 8x4-pixel tiles, 32 consecutive rays per tile: the pixels a subgroup of the
    // path tracer covers (pt_trace.comp).
    let mut pixels: Vec<(u32, u32)> = (0..height).flat_map(|y| (0..width).map(move |x| (x, y))).collect();
    pixels.sort_by_key(|&(x, y)| (y / 4, x / 8, y % 4, x % 8));
    let primary: Vec<RayIn> = pixels
        .into_iter()
        .map(|(x, y)| {
            let ndc =
                Vec2::new((x as f32 + 0.5) / width as f32 * 2.0 - 1.0, 1.0 - (y as f32 + 0.5) / height as f32 * 2.0);
            let d = camera.ray_direction(ndc, aspect);
            RayIn { origin_tmin: camera.eye.extend(0.0).into(), dir_tmax: d.extend(f32::INFINITY).into() }
        })
        .collect();
    let mut timings = vec![Vec::new(); schedules.len()];
    let hits = cast_under_every_schedule(&mut raycasters, schedules, &mut timings, &primary, false, repeats)?;

    // From each primary hit, a cosine-distributed direction about the face normal facing the ray.
    let bounce: Vec<RayIn> = primary
        .par_iter()
        .zip(&hits)
        .enumerate()
        .filter(|(_, (_, h))| h.primitive != u32::MAX)
        .map(|(i, (r, h))| {
            let tri = &gpu_scene.triangles[h.primitive as usize];
            let (a, b, c) = (Vec3::from(tri.v0), Vec3::from(tri.v1), Vec3::from(tri.v2));
            let d = Vec3::from_slice(&r.dir_tmax[..3]);
            let mut n = (b - a).cross(c - a).normalize_or_zero();
            if n.dot(d) > 0.0 {
                n = -n;
            }
            let p = Vec3::from_slice(&r.origin_tmin[..3]) + d * h.t;
            let mut s = (i as u64).wrapping_mul(0xd129_4f3b_e5a1_0c77) | 1;
            let mut next = || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 40) as f32 / (1u64 << 24) as f32
            };
            next();
            let (u0, u1) = (next(), next());
            let dir = parallax_scene::bsdf::sample_cosine_hemisphere(n, u0, u1);
            let o = parallax_scene::pt::offset_ray_origin(p, n);
            RayIn { origin_tmin: o.extend(0.0).into(), dir_tmax: dir.extend(f32::INFINITY).into() }
        })
        .collect();

    cast_under_every_schedule(&mut raycasters, schedules, &mut timings, &bounce, false, repeats)?;
    cast_under_every_schedule(&mut raycasters, schedules, &mut timings, &bounce, true, repeats)?;
    for raycaster in &raycasters {
        raycaster.check_validation()?;
    }
    Ok(RayBench {
        device: context.device_infos()[0].name.clone(),
        triangles: scene.triangle_count(),
        bvh_nodes: bvh.node_count(),
        bvh_build_ms: build.as_secs_f64() * 1e3,
        bvh_core_build_ms: bvh.core_build_time.as_secs_f64() * 1e3,
        width,
        height,
        repeats,
        schedules: schedules
            .iter()
            .zip(timings)
            .map(|(schedule, t)| ScheduleRates {
                schedule: schedule.to_string(),
                primary: t[0],
                diffuse_bounce: t[1],
                diffuse_bounce_any_hit: t[2],
            })
            .collect(),
    })
}

/// Casts `rays` under every schedule in turn (batch by batch, so that clock and thermal drift
/// fall on all), appends each one's rate to its `timings`, and returns the hits, which must
/// agree bit for bit between schedules.
fn cast_under_every_schedule(
    raycasters: &mut [Raycaster],
    schedules: &[RaySchedule],
    timings: &mut [Vec<RayRate>],
    rays: &[RayIn],
    any_hit: bool,
    repeats: usize,
) -> Result<Vec<HitOut>> {
    let mut reference: Option<Vec<HitOut>> = None;
    for (i, raycaster) in raycasters.iter_mut().enumerate() {
        let (hits, timing) = raycaster.cast(rays, any_hit, repeats)?;
        timings[i].push(RayRate::new(rays.len(), timing));
        match &reference {
            None => reference = Some(hits),
            Some(first) => {
                let differing =
                    first.iter().zip(&hits).filter(|(a, b)| bytemuck::bytes_of(*a) != bytemuck::bytes_of(*b)).count();
                if differing > 0 {
                    return Err(PassError::ScheduleChangedHits {
                        schedule: schedules[i].to_string(),
                        reference: schedules[0].to_string(),
                        differing,
                    });
                }
            }
        }
    }
    Ok(reference.expect("at least one schedule"))
}
