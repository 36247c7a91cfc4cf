//! The CPU reference path tracer: the ground truth for tests and accuracy figures.
//!
//! Unidirectional path tracing with next-event estimation and multiple importance sampling
//! (power heuristic) over sun, sky, punctual and emissive-triangle lights; Lambert + GGX; max
//! depth counts scattering events as in pbrt (depth 1 = direct lighting only). Every random
//! number comes from [`PathRng`] keyed by (pixel, view, frame, sample, bounce), and pixels are
//! independent, so any subset of pixels (a whole view, a band of rows, a list) traced in any
//! order on any number of threads gives bit-identical values for each pixel.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::bsdf::Bsdf;
use crate::bvh::SceneBvh;
use crate::camera::Camera;
use crate::error::SceneError;
use crate::lights::LightSet;
use crate::model::Scene;
use crate::rng::{Dim, PathRng};
use crate::shading::{SurfacePoint, surface_point};

/// What to trace and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceSettings {
    pub spp: u32,
    /// Scattering events per path (pbrt convention); the paper's default is 6.
    pub max_depth: u32,
    /// Frame index, part of the random key (different noise per frame).
    pub frame: u32,
    /// Russian roulette from this bounce on; `None` (the default) keeps every path to max depth.
    pub russian_roulette_from: Option<u32>,
    /// Jitter the sub-pixel position per sample (antialiasing); off puts every sample at the
    /// pixel centre, which keeps the first hit identical to a rasterised G-buffer.
    pub jitter: bool,
}

impl Default for TraceSettings {
    fn default() -> Self {
        Self { spp: 1, max_depth: 6, frame: 0, russian_roulette_from: None, jitter: true }
    }
}

impl TraceSettings {
    pub fn validate(&self) -> Result<(), SceneError> {
        if self.spp == 0 {
            return Err(SceneError::InvalidSettings("spp must be at least 1".into()));
        }
        if self.max_depth > 1024 {
            return Err(SceneError::InvalidSettings(format!(
                "max depth {} is beyond any useful value (at most 1024)",
                self.max_depth
            )));
        }
        Ok(())
    }
}

/// One camera view of the scene at a resolution; `index` is part of the random key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    pub index: u32,
}

impl View {
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// Which pixels of a view to trace.
#[derive(Clone, Debug, PartialEq)]
pub enum PixelSet {
    All,
    /// Rows `start..end` (a strip of the image, e.g. one device's share).
    Rows {
        start: u32,
        end: u32,
    },
    /// An explicit list of (x, y), e.g. compacted reprojection holes.
    List(Vec<(u32, u32)>),
}

impl PixelSet {
    /// The pixel coordinates in the order results are returned (row-major for All/Rows).
    pub fn coordinates(&self, view: &View) -> Vec<(u32, u32)> {
        let rows = |a: u32, b: u32| -> Vec<(u32, u32)> {
            (a..b.min(view.height)).flat_map(|y| (0..view.width).map(move |x| (x, y))).collect()
        };
        match self {
            PixelSet::All => rows(0, view.height),
            PixelSet::Rows { start, end } => rows(*start, *end),
            PixelSet::List(l) => l.clone(),
        }
    }
}

/// Radiance plus the first-hit data a denoiser and the reprojection need. Misses have zero
/// albedo, normal, depth and position, and `hit == false`. All values are finite.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSample {
    /// Mean radiance over the samples.
    pub radiance: Vec3,
    /// Base colour at the first hit (sample 0).
    pub albedo: Vec3,
    /// World-space shading normal at the first hit, facing the camera.
    pub normal: Vec3,
    /// Linear depth: distance along the camera's forward axis.
    pub depth: f32,
    pub position: Vec3,
    pub roughness: f32,
    pub metallic: f32,
    pub hit: bool,
}

/// A traced view: one [`PixelSample`] per pixel, row-major from the top-left.
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<PixelSample>,
}

/// Counts of what was thrown away; non-zero values point at numerical problems.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceStats {
    pub non_finite_samples: u64,
}

/// Power heuristic (beta = 2).
fn mis_weight(pdf_a: f32, pdf_b: f32) -> f32 {
    let (a, b) = (pdf_a * pdf_a, pdf_b * pdf_b);
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if pdf_a > 0.0 {
        1.0
    } else {
        0.0
    }
}

/// Moves a ray origin off a surface by an amount that scales with the position's magnitude
/// (Waechter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection", RT Gems 2019).
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    const ORIGIN: f32 = 1.0 / 32.0;
    const FLOAT_SCALE: f32 = 1.0 / 65536.0;
    const INT_SCALE: f32 = 256.0;
    let off = |p: f32, n: f32| -> f32 {
        let of_i = (INT_SCALE * n) as i32;
        let moved = f32::from_bits((p.to_bits() as i32).wrapping_add(if p < 0.0 { -of_i } else { of_i }) as u32);
        if p.abs() < ORIGIN { p + FLOAT_SCALE * n } else { moved }
    };
    Vec3::new(off(p.x, n.x), off(p.y, n.y), off(p.z, n.z))
}

/// The CPU path tracer over one scene and its BVH.
pub struct CpuTracer<'a> {
    scene: &'a Scene,
    bvh: &'a SceneBvh,
    lights: LightSet,
}

/// State carried from one path vertex to the next for MIS on emitters found by BSDF rays.
struct PrevVertex {
    position: Vec3,
    normal: Vec3,
    bsdf_pdf: f32,
}

impl<'a> CpuTracer<'a> {
    pub fn new(scene: &'a Scene, bvh: &'a SceneBvh) -> Self {
        Self { scene, bvh, lights: LightSet::new(scene) }
    }

    pub fn lights(&self) -> &LightSet {
        &self.lights
    }

    /// Traces one pixel: deterministic in (view.index, x, y, settings).
    pub fn trace_pixel(
        &self,
        view: &View,
        settings: &TraceSettings,
        x: u32,
        y: u32,
        stats: &mut TraceStats,
    ) -> PixelSample {
        let rng = PathRng::new(x, y, view.index, settings.frame);
        let mut out = PixelSample::default();
        let mut sum = Vec3::ZERO;
        for s in 0..settings.spp {
            let jitter = if settings.jitter {
                let u = rng.uniforms(s, 0, Dim::Camera);
                Vec2::new(u[0], u[1])
            } else {
                Vec2::splat(0.5)
            };
            let ndc = Vec2::new(
                (x as f32 + jitter.x) / view.width as f32 * 2.0 - 1.0,
                1.0 - (y as f32 + jitter.y) / view.height as f32 * 2.0,
            );
            let dir = view.camera.ray_direction(ndc, view.aspect());
            let gbuffer = if s == 0 { Some(&mut out) } else { None };
            let l = self.trace_path(&rng, s, settings, view, view.camera.eye, dir, gbuffer);
            if l.is_finite() {
                sum += l;
            } else {
                stats.non_finite_samples += 1;
            }
        }
        out.radiance = sum / settings.spp as f32;
        out
    }

    #[allow(clippy::too_many_arguments)]
    fn trace_path(
        &self,
        rng: &PathRng,
        sample: u32,
        settings: &TraceSettings,
        view: &View,
        origin: Vec3,
        dir: Vec3,
        mut gbuffer: Option<&mut PixelSample>,
    ) -> Vec3 {
        let scene = self.scene;
        let mut radiance = Vec3::ZERO;
        let mut throughput = Vec3::ONE;
        let (mut ro, mut rd) = (origin, dir);
        let mut prev: Option<PrevVertex> = None;
        for depth in 0..=settings.max_depth {
            let Some(hit) = self.bvh.closest_hit(scene, ro, rd, 0.0, f32::INFINITY) else {
                let sky = scene.sky().radiance(rd);
                let sun = self.lights.sun_radiance(rd);
                radiance += throughput
                    * match &prev {
                        None => sky + sun,
                        Some(p) => {
                            sky * mis_weight(p.bsdf_pdf, self.lights.pdf_sky(p.normal, rd))
                                + sun * mis_weight(p.bsdf_pdf, self.lights.pdf_sun(rd))
                        }
                    };
                break;
            };
            let sp = surface_point(scene, &hit, ro, rd);
            if let Some(g) = gbuffer.take() {
                write_gbuffer(g, &sp, &view.camera);
            }
            if sp.emission.max_element() > 0.0 {
                let w = match &prev {
                    None => 1.0,
                    Some(p) => {
                        let light_pdf =
                            self.lights.pdf_emissive(hit.triangle, p.position, sp.position, sp.geometric_normal);
                        mis_weight(p.bsdf_pdf, light_pdf)
                    }
                };
                radiance += throughput * sp.emission * w;
            }
            if depth == settings.max_depth {
                break;
            }
            let wo = -rd;
            let bsdf = Bsdf::new(&sp, wo);
            let origin = offset_ray_origin(sp.position, sp.geometric_normal);

            let lu = rng.uniforms(sample, depth + 1, Dim::Light);
            if let Some(ls) = self.lights.sample(scene, sp.position, sp.normal, lu) {
                let (fcos, bsdf_pdf) = bsdf.eval(wo, ls.wi);
                if fcos.max_element() > 0.0 {
                    let tmax = if ls.distance.is_finite() {
                        // Stop short of the light's own surface.
                        (ls.distance * (1.0 - 1e-4)).max(0.0)
                    } else {
                        f32::INFINITY
                    };
                    if !self.bvh.occluded(scene, origin, ls.wi, 0.0, tmax) {
                        let w = if ls.is_delta { 1.0 } else { mis_weight(ls.pdf, bsdf_pdf) };
                        radiance += throughput * fcos * ls.radiance * (w / ls.pdf);
                    }
                }
            }

            let bu = rng.uniforms(sample, depth + 1, Dim::Bsdf);
            let Some(bs) = bsdf.sample(wo, [bu[0], bu[1], bu[2]]) else {
                break;
            };
            throughput *= bs.weight;
            if let Some(from) = settings.russian_roulette_from {
                if depth + 1 >= from {
                    let survive = throughput.max_element().clamp(0.05, 0.95);
                    if rng.uniforms(sample, depth + 1, Dim::Roulette)[0] >= survive {
                        break;
                    }
                    throughput /= survive;
                }
            }
            if throughput.max_element() <= 0.0 {
                break;
            }
            prev = Some(PrevVertex { position: sp.position, normal: sp.normal, bsdf_pdf: bs.pdf });
            ro = origin;
            rd = bs.wi;
        }
        radiance
    }

    /// Traces `pixels` of `view` in parallel; results in [`PixelSet::coordinates`] order.
    /// `progress` is called with the number of pixels finished since its last call.
    pub fn trace(
        &self,
        view: &View,
        settings: &TraceSettings,
        pixels: &PixelSet,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(Vec<PixelSample>, TraceStats), SceneError> {
        settings.validate()?;
        if view.width == 0 || view.height == 0 {
            return Err(SceneError::InvalidSettings("view has zero pixels".into()));
        }
        if !view.camera.is_finite() {
            return Err(SceneError::InvalidSettings("camera has non-finite values".into()));
        }
        let coords = pixels.coordinates(view);
        if let Some(&(x, y)) = coords.iter().find(|&&(x, y)| x >= view.width || y >= view.height) {
            return Err(SceneError::InvalidSettings(format!(
                "pixel ({x}, {y}) outside the {}x{} view",
                view.width, view.height
            )));
        }
        let chunk = view.width.max(1) as usize;
        let results: Vec<(Vec<PixelSample>, TraceStats)> = coords
            .par_chunks(chunk)
            .map(|c| {
                let mut stats = TraceStats::default();
                let px = c.iter().map(|&(x, y)| self.trace_pixel(view, settings, x, y, &mut stats)).collect();
                progress(c.len() as u64);
                (px, stats)
            })
            .collect();
        let mut stats = TraceStats::default();
        let mut out = Vec::with_capacity(coords.len());
        for (px, s) in results {
            out.extend(px);
            stats.non_finite_samples += s.non_finite_samples;
        }
        Ok((out, stats))
    }

    /// Traces a whole view.
    pub fn render(
        &self,
        view: &View,
        settings: &TraceSettings,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(Frame, TraceStats), SceneError> {
        let (pixels, stats) = self.trace(view, settings, &PixelSet::All, progress)?;
        Ok((Frame { width: view.width, height: view.height, pixels }, stats))
    }
}

fn write_gbuffer(g: &mut PixelSample, sp: &SurfacePoint, camera: &Camera) {
    g.hit = true;
    g.albedo = sp.base_color;
    g.normal = sp.normal;
    g.position = sp.position;
    g.depth = (sp.position - camera.eye).dot(camera.forward.normalize_or_zero());
    g.roughness = sp.roughness;
    g.metallic = sp.metallic;
}
