//! The `raycast` pass: a batch of rays through the scene CWBVH on the GPU
//! (shaders/bvh_raycast.glsl), closest hit or any hit. It backs the GPU-vs-CPU traversal test
//! and the rays/s benchmark, which is why [`Raycaster`] runs it alone on a one-pass plan and
//! reports the pass's GPU time from the executor's timestamps.
//!
//! Rays come from the global buffer [`RAYS`], hits go to the per-view buffer of the pass's
//! write, and the ray count and query kind come from the per-frame data, so the same recorded
//! frame casts any batch up to the plan's capacity.

use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use parallax_backend::{
    AllocId, BackendError, Compiled, Context, DeviceId, EventKind, ExecOptions, Executor, InstanceId, KernelGraph,
    KernelPlan, PassInstance, PassKernel, Recorder, ResourceKind, WriteSlot,
};
use parallax_graph::{BandedPlacement, Role, ViewTopology};
use parallax_scene::Scene;
use parallax_scene::gpu::GpuScene;

use crate::error::{PassError, Result};
use crate::scene_upload::{scene_refs, upload_scene};
use crate::shaders::{self, RaycastPush};

/// Pass name the kernel is registered under.
pub const RAYCAST: &str = "raycast";
/// Global buffer holding the rays.
pub const RAYS: &str = "rays";

/// One ray as the kernel reads it (32 bytes; `RayIn` in shaders/bvh_raycast.glsl, a test holds
/// the two layouts together).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct RayIn {
    pub origin_tmin: [f32; 4],
    pub dir_tmax: [f32; 4],
}

/// One result (16 bytes; `HitOut` in shaders/bvh_raycast.glsl, held to it like [`RayIn`]):
/// BVH-ordered triangle index (`u32::MAX` = miss), distance, weights of
/// the second and third corner.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct HitOut {
    pub primitive: u32,
    pub t: f32,
    pub barycentrics: [f32; 2],
}

/// Global buffer holding the work queue of [`RaySchedule::Persistent`] (two zeroed words).
pub const RAYCAST_WORK: &str = "raycast_work";

/// How the `raycast` kernel maps rays to invocations. Hits are the same under every schedule:
/// a ray is traced by the same code whichever invocation takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RaySchedule {
    /// One invocation per ray; a subgroup lives as long as its longest ray.
    PerRay,
    /// `workgroups` groups of 64 persistent invocations; a subgroup takes new rays for its idle
    /// lanes from a global queue once `fetch_threshold` of them are idle.
    Persistent { fetch_threshold: u32, workgroups: u32 },
}

impl std::fmt::Display for RaySchedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RaySchedule::PerRay => write!(f, "per-ray"),
            RaySchedule::Persistent { fetch_threshold, workgroups } => {
                write!(f, "persistent:{fetch_threshold}:{workgroups}")
            }
        }
    }
}

impl std::str::FromStr for RaySchedule {
    type Err = String;

    /// `per-ray`, or `persistent:THRESHOLD:WORKGROUPS` (threshold 1..=32 lanes, workgroups
    /// 1..=65535).
    fn from_str(s: &str) -> std::result::Result<Self, Self::Err> {
        let usage = || format!("ray schedule '{s}': expected `per-ray` or `persistent:THRESHOLD:WORKGROUPS`");
        if s == "per-ray" {
            return Ok(RaySchedule::PerRay);
        }
        let parts: Vec<&str> = s.split(':').collect();
        match parts.as_slice() {
            ["persistent", t, g] => {
                let fetch_threshold: u32 = t.parse().map_err(|_| usage())?;
                let workgroups: u32 = g.parse().map_err(|_| usage())?;
                if !(1..=32).contains(&fetch_threshold) || !(1..=65535).contains(&workgroups) {
                    return Err(format!(
                        "ray schedule '{s}': the threshold must be 1..=32 lanes and the workgroups 1..=65535"
                    ));
                }
                Ok(RaySchedule::Persistent { fetch_threshold, workgroups })
            }
            _ => Err(usage()),
        }
    }
}

/// Records `raycast` instances into their `hits` write, a buffer. `opaque` selects the kernel
/// compiled without textures (bvh_raycast_opaque.comp): what the rays/s benchmark measures on
/// opaque geometry. A persistent `schedule` needs the global buffer [`RAYCAST_WORK`] (zeroed
/// once; the kernel leaves it zeroed). Instances on one device may share it: the executor puts a
/// barrier between ops, so one dispatch has reset the queue before the next starts.
pub struct RaycastKernel {
    pub opaque: bool,
    pub schedule: RaySchedule,
    pub hits: WriteSlot,
}

impl PassKernel for RaycastKernel {
    /// The persistent schedule's work queue is a global buffer every instance resets and
    /// consumes.
    fn touches_undeclared_memory(&self) -> bool {
        true
    }

    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let hits = pass.write(self.hits)?.alloc;
        if rec.resource(hits).kind != ResourceKind::Buffer {
            return Err(BackendError::KernelMisuse {
                kernel: RAYCAST.into(),
                instance: Some(index),
                detail: "its hits write must be a buffer".into(),
            });
        }
        let capacity = rec.resource(hits).width / 4;
        let (work, fetch_threshold, groups) = match self.schedule {
            RaySchedule::PerRay => {
                let groups = capacity.div_ceil(64).max(1);
                (0, 0, [groups.min(65535), groups.div_ceil(65535), 1])
            }
            RaySchedule::Persistent { fetch_threshold, workgroups } => {
                (rec.buffer_address(RAYCAST_WORK)?, fetch_threshold, [workgroups, 1, 1])
            }
        };
        let push = RaycastPush {
            scene: scene_refs(rec)?,
            rays: rec.buffer_address(RAYS)?,
            hits: rec.buffer_of(hits)?,
            frame: rec.frame_data_address(),
            work,
            fetch_threshold,
            pad: 0,
        };
        let shader = if self.opaque { shaders::BVH_RAYCAST_OPAQUE } else { shaders::BVH_RAYCAST };
        rec.dispatch(shader, &push, groups)
    }
}

/// GPU time of one cast, from the pass's timestamps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CastTiming {
    pub median_ns: f64,
    pub best_ns: f64,
}

/// An executor running nothing but the `raycast` pass on device 0, with the scene uploaded.
pub struct Raycaster {
    executor: Executor,
    capacity: usize,
}

impl Raycaster {
    /// Uploads `scene` and plans one `raycast` pass for up to `capacity` rays on device 0 of
    /// `context` (other devices stay idle).
    pub fn new(
        context: &Context,
        scene: &GpuScene<'_>,
        capacity: usize,
        opaque: bool,
        schedule: RaySchedule,
    ) -> Result<Self> {
        let capacity = capacity.max(1);
        let plan = raycast_plan(capacity, opaque, schedule, context.devices().len() as u32)?;
        let mut executor =
            Executor::new(context, plan, ExecOptions { shaders: crate::shader_library(), ..ExecOptions::default() })?;
        upload_scene(&mut executor, scene)?;
        executor.upload_buffer(RAYCAST_WORK, &[0u8; 8])?;
        Ok(Self { executor, capacity })
    }

    /// Casts `rays` `repeats` times (at least once); returns the hits and the GPU time of the
    /// pass (median and best over the repeats).
    pub fn cast(&mut self, rays: &[RayIn], any_hit: bool, repeats: usize) -> Result<(Vec<HitOut>, CastTiming)> {
        if rays.len() > self.capacity {
            return Err(PassError::TooManyRays { rays: rays.len(), capacity: self.capacity });
        }
        self.executor.upload_buffer(RAYS, bytemuck::cast_slice(rays))?;
        let frame: [u32; 2] = [rays.len() as u32, u32::from(any_hit)];
        self.executor.set_frame_data(bytemuck::bytes_of(&frame))?;
        // The first dispatch pays for pipeline creation and cold caches: run it untimed, so
        // even one repeat measures the steady state.
        self.executor.run_frame()?;
        self.executor.finish()?;
        self.executor.take_reports();
        for _ in 0..repeats.max(1) {
            self.executor.run_frame()?;
        }
        self.executor.finish()?;
        let mut times: Vec<f64> = self
            .executor
            .take_reports()
            .iter()
            .flat_map(|r| &r.events)
            .filter(|e| e.kind == EventKind::Pass && e.name == RAYCAST)
            .map(|e| e.end_ns.saturating_sub(e.start_ns) as f64)
            .collect();
        times.sort_by(f64::total_cmp);
        let timing = CastTiming { median_ns: times[times.len() / 2], best_ns: times[0] };
        let bytes = self.executor.read_resource(DeviceId(0), AllocId(0))?;
        let hits = bytemuck::pod_collect_to_vec(&bytes[..rays.len() * std::mem::size_of::<HitOut>()]);
        Ok((hits, timing))
    }

    /// Fails if the validation layer reported anything.
    pub fn check_validation(&self) -> Result<()> {
        Ok(self.executor.check_validation()?)
    }
}

/// One `raycast` instance on device 0 (the others idle) writing the hits of up to `capacity` rays
/// to `hits`, the plan's only resource (0).
fn raycast_plan(capacity: usize, opaque: bool, schedule: RaySchedule, devices: u32) -> Result<KernelPlan> {
    let mut graph = KernelGraph::with_payload(ViewTopology::all_sources(1, 1, 1));
    let mut hits = graph.buffer("hits", (capacity * std::mem::size_of::<HitOut>()) as u64);
    let mut pass = graph.pass(RAYCAST, Role::All);
    let kernel = RaycastKernel { opaque, schedule, hits: pass.write_slot(&mut hits) };
    // Nothing in the plan reads the hits: the host does.
    pass.side_effect().kernel(Arc::new(kernel)).add();
    Ok(Compiled::compile(&graph, &BandedPlacement { devices, bands: 1 })?.plan)
}

fn xorshift(s: &mut u64) -> f32 {
    *s ^= *s << 13;
    *s ^= *s >> 7;
    *s ^= *s << 17;
    (*s >> 40) as f32 / (1u64 << 24) as f32
}

/// `n` reproducible random rays: origins uniform in the scene bounds enlarged by 10 % on each
/// side, directions uniform on the sphere, tmin 1e-4, tmax infinite.
pub fn random_rays(scene: &Scene, n: usize) -> Vec<RayIn> {
    let b = scene.bounds();
    let lo = b.min - 0.1 * (b.max - b.min);
    let hi = b.max + 0.1 * (b.max - b.min);
    (0..n)
        .map(|i| {
            let mut s = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
            for _ in 0..4 {
                xorshift(&mut s);
            }
            let o = lo + (hi - lo) * Vec3::new(xorshift(&mut s), xorshift(&mut s), xorshift(&mut s));
            let z = 2.0 * xorshift(&mut s) - 1.0;
            let phi = std::f32::consts::TAU * xorshift(&mut s);
            let r = (1.0 - z * z).max(0.0).sqrt();
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            RayIn { origin_tmin: [o.x, o.y, o.z, 1e-4], dir_tmax: [d.x, d.y, d.z, f32::INFINITY] }
        })
        .collect()
}

/// Outcome of comparing GPU hits with the CPU traversal (see [`compare_with_cpu`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraversalComparison {
    pub rays: usize,
    pub gpu_hits: usize,
    /// Hit/miss disagreements, or t beyond 1e-4 relative.
    pub disagreements: usize,
    /// Same t (within 1e-4 relative) on another triangle: a ray through a shared edge.
    pub same_t_other_triangle: usize,
    pub max_relative_dt: f32,
    /// Any-hit queries whose hit/miss differs from the CPU's closest hit.
    pub any_hit_disagreements: usize,
}

/// Compares `closest` and `any` (GPU results for `rays`) with `SceneBvh::closest_hit`.
pub fn compare_with_cpu(
    scene: &Scene,
    bvh: &parallax_scene::SceneBvh,
    rays: &[RayIn],
    closest: &[HitOut],
    any: &[HitOut],
) -> TraversalComparison {
    use rayon::prelude::*;
    let per_ray: Vec<(usize, usize, usize, f32)> = rays
        .par_iter()
        .zip(closest)
        .zip(any)
        .map(|((r, g), a)| {
            let o = Vec3::from_slice(&r.origin_tmin[..3]);
            let d = Vec3::from_slice(&r.dir_tmax[..3]);
            let cpu = bvh.closest_hit(scene, o, d, r.origin_tmin[3], r.dir_tmax[3]);
            let any_wrong = usize::from((a.primitive != u32::MAX) != cpu.is_some());
            match cpu {
                None => (usize::from(g.primitive != u32::MAX), 0, any_wrong, 0.0),
                Some(_) if g.primitive == u32::MAX => (1, 0, any_wrong, 0.0),
                Some(c) => {
                    let rel = (g.t - c.t).abs() / c.t.max(1e-6);
                    let wrong = rel > 1e-4;
                    let other = usize::from(!wrong && g.primitive != c.bvh_primitive);
                    (usize::from(wrong), other, any_wrong, rel)
                }
            }
        })
        .collect();
    TraversalComparison {
        rays: rays.len(),
        gpu_hits: closest.iter().filter(|h| h.primitive != u32::MAX).count(),
        disagreements: per_ray.iter().map(|r| r.0).sum(),
        same_t_other_triangle: per_ray.iter().map(|r| r.1).sum(),
        max_relative_dt: per_ray.iter().map(|r| r.3).fold(0.0, f32::max),
        any_hit_disagreements: per_ray.iter().map(|r| r.2).sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::{HitOut, RayIn, RaySchedule};
    use parallax_backend::reflect::member_offsets;
    use parallax_backend::rust_layout;

    #[test]
    fn the_structs_match_bvh_raycast_glsl() {
        let ray = rust_layout!(RayIn { origin_tmin, dir_tmax });
        let hit = rust_layout!(HitOut { primitive, t, barycentrics });
        for shader in ["bvh_raycast", "bvh_raycast_opaque"] {
            let spirv = crate::shaders::spirv(shader).unwrap();
            assert_eq!(member_offsets(&spirv, "RayIn").unwrap(), ray, "{shader}");
            assert_eq!(member_offsets(&spirv, "HitOut").unwrap(), hit, "{shader}");
        }
        assert_eq!((std::mem::size_of::<RayIn>(), std::mem::size_of::<HitOut>()), (32, 16));
    }

    #[test]
    fn ray_schedules_parse_and_print_back() {
        for text in ["per-ray", "persistent:4:2112", "persistent:32:1", "persistent:1:65535"] {
            let schedule: RaySchedule = text.parse().unwrap();
            assert_eq!(schedule.to_string(), text);
        }
        assert_eq!("persistent:8:64".parse(), Ok(RaySchedule::Persistent { fetch_threshold: 8, workgroups: 64 }));
    }

    #[test]
    fn bad_ray_schedules_name_the_input_and_the_form() {
        for text in ["", "persistent", "persistent:4", "persistent:x:2", "per_ray", "persistent:4:2:1"] {
            let err = text.parse::<RaySchedule>().unwrap_err();
            assert!(err.contains(&format!("'{text}'")) && err.contains("persistent:THRESHOLD:WORKGROUPS"), "{err}");
        }
        for text in ["persistent:0:8", "persistent:33:8", "persistent:4:0", "persistent:4:65536"] {
            let err = text.parse::<RaySchedule>().unwrap_err();
            assert!(err.contains("1..=32") && err.contains("1..=65535"), "{err}");
        }
    }
}
