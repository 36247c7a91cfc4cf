//! The visibility G-buffer: the G-buffer without tracing, for GPUs with little fixed-function
//! raster (H100/H200, where the raster G-buffer is the slow path) and 64-bit buffer atomics.
//!
//! * `visibility_raster` (shaders/visibility_raster.comp), per view and row band: every BVH
//!   triangle of the uploaded scene bounds the pixels it can cover (its projection through the
//!   view's camera, the path tracer's camera rays), tests their centre rays with the
//!   traversal's triangle test (alpha masks included) and keeps the nearest triangle of each
//!   pixel with a 64-bit `atomicMax` on a key of distance and triangle ([`VISIBILITY`], a row
//!   buffer of 8 bytes per pixel reset to zeros every frame). Triangles of medium boxes are
//!   shared out over their workgroup; those of large boxes are cut into 16 × 16 tiles listed in
//!   [`VISIBILITY_TILES`], which a second, indirect dispatch of the pass runs one workgroup a
//!   tile (shaders/visibility_raster.glsl says why). The triangle data every view reads is the
//!   scene's BVH-ordered triangle buffer, uploaded once for all views of the light field.
//! * `visibility_resolve` (shaders/visibility_resolve.comp), per view and row band: each
//!   pixel's triangle intersected with its centre ray (the traversal's code) and written as
//!   `gbuffer` writes a traced first hit (shaders/gbuffer_store.glsl): the same images, formats
//!   and conventions ([`crate::gbuffer::Gbuffer`], `first_hit` included), zeros on the sky.
//!
//! Where both see the same triangle the texels are the traced G-buffer's bit for bit; they see
//! different triangles only at ties (equal distances: shared edges, coplanar or duplicated
//! triangles), which the traversal breaks by its visiting order and the atomic by the larger
//! triangle index. [`choose_gbuffer`] falls back to first hits on devices without
//! `shaderBufferInt64Atomics`.

use std::sync::Arc;

use parallax_backend::{BackendError, DeviceInfo, InstanceId, KernelGraph, PassInstance, PassKernel, Recorder};
use parallax_graph::{Format, ReadSlot, Role, WriteSlot};
use parallax_scene::gpu::GpuTriangle;

use crate::gbuffer::{Gbuffer, GbufferSource};
use crate::path_trace::{NO_IMAGE, TRACE_PARAMS_BYTES};
use crate::scene_upload::scene_refs;
use crate::shaders::{self, VisibilityRasterPush, VisibilityResolvePush};

/// Pass name of the triangle pass.
pub const VISIBILITY_RASTER: &str = "visibility_raster";
/// Pass name of the resolve pass.
pub const VISIBILITY_RESOLVE: &str = "visibility_resolve";
/// The per-view row buffer of 64-bit keys (shaders/visibility.glsl).
pub const VISIBILITY: &str = "visibility";
/// Bytes of one pixel's key.
pub const KEY_BYTES: u64 = 8;
/// The per-view row buffer of large triangles' tiles: each row band's list starts at its first
/// row (shaders/visibility_raster.glsl).
pub const VISIBILITY_TILES: &str = "visibility_tiles";
/// Bytes of the tile list's header (indirect dispatch arguments) and of one tile.
const TILE_BYTES: u64 = 16;
/// Tiles one list holds at most: the tile dispatch's workgroup count, which Vulkan guarantees
/// up to 65535 (`maxComputeWorkGroupCount`).
const MAX_TILES: u64 = 65535;

/// Bytes per row of [`VISIBILITY_TILES`] for a `width`-wide view: two bytes a pixel, room for
/// the tiles of boxes covering a band 32 times over (a 16 × 16 tile is 16 bytes), at least
/// eight tiles a row. A band whose boxes need more tests the rest in its workgroups, 64
/// threads a box, which is slow: Sponza lite's atrium from the benchmark camera (768 × 432)
/// needs about 28,000 tiles in a view, and half a byte a pixel (10,367 tiles) left 3/4 of its
/// tiled pixels to the workgroups.
pub fn tile_row_bytes(width: u32) -> u64 {
    (2 * u64::from(width)).next_multiple_of(TILE_BYTES).max(8 * TILE_BYTES)
}

/// Workgroups per row of `visibility_raster`'s dispatch grid at most (one triangle per
/// invocation, 64 per workgroup; more rows beyond).
const MAX_GROUPS_X: u32 = 32768;

fn misuse(kernel: &str, index: InstanceId, detail: String) -> BackendError {
    BackendError::KernelMisuse { kernel: kernel.into(), instance: Some(index), detail }
}

/// The width of the view whose keys `buffer` holds, checked: a row buffer of 8 bytes a pixel.
fn key_row_width(
    rec: &Recorder<'_>,
    kernel: &str,
    index: InstanceId,
    buffer: parallax_backend::AllocId,
) -> parallax_backend::Result<u32> {
    let desc = rec.resource(buffer);
    if desc.kind != parallax_backend::ResourceKind::Buffer || desc.row_bytes() % KEY_BYTES != 0 {
        return Err(misuse(kernel, index, format!("`{}` must be a row buffer of {KEY_BYTES}-byte keys", desc.name)));
    }
    u32::try_from(desc.row_bytes() / KEY_BYTES).map_err(|_| misuse(kernel, index, "rows too wide".into()))
}

/// Records `visibility_raster` instances: every scene triangle against the instance's band,
/// into the keys it modifies, then the tiles of its large triangles that the first dispatch
/// listed.
struct VisibilityRasterKernel {
    keys: WriteSlot,
    tiles: WriteSlot,
}

impl PassKernel for VisibilityRasterKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let keys = pass.write(self.keys)?;
        let tiles = pass.write(self.tiles)?;
        let width = key_row_width(rec, VISIBILITY_RASTER, index, keys.alloc)?;
        if keys.region.is_empty() {
            return Ok(());
        }
        let tiles_desc = rec.resource(tiles.alloc);
        if tiles_desc.kind != parallax_backend::ResourceKind::Buffer || tiles_desc.row_bytes() < tile_row_bytes(width) {
            return Err(misuse(
                VISIBILITY_RASTER,
                index,
                format!("`{}` must be a row buffer of at least {} bytes a row", tiles_desc.name, tile_row_bytes(width)),
            ));
        }
        let list_offset = u64::from(tiles.region.y0) * tiles_desc.row_bytes();
        let list_bytes = u64::from(tiles.region.len()) * tiles_desc.row_bytes();
        let tile_capacity = ((list_bytes - TILE_BYTES) / TILE_BYTES).min(MAX_TILES) as u32;
        let triangle_bytes = rec.buffer_bytes(crate::SCENE_BUFFERS[1])?;
        let triangles = u32::try_from(triangle_bytes / std::mem::size_of::<GpuTriangle>() as u64)
            .map_err(|_| misuse(VISIBILITY_RASTER, index, "more than 2^32 triangles".into()))?;
        let groups = triangles.div_ceil(64).max(1);
        let groups_x = groups.min(MAX_GROUPS_X);
        let push = VisibilityRasterPush {
            scene: scene_refs(rec)?,
            trace: rec.frame_data_address() + u64::from(pass.view.0) * TRACE_PARAMS_BYTES,
            keys: rec.buffer_of(keys.alloc)?,
            tiles: rec.buffer_of(tiles.alloc)? + list_offset,
            y0: keys.region.y0,
            y1: keys.region.y1,
            width,
            triangles,
            groups_x,
            tile_capacity,
        };
        rec.dispatch(shaders::VISIBILITY_RASTER, &push, [groups_x, groups.div_ceil(groups_x), 1])?;
        rec.dispatch_indirect(shaders::VISIBILITY_RASTER_TILES, &push, tiles.alloc, list_offset)
    }
}

/// Records `visibility_resolve` instances: the keys of the band turned into the G-buffer.
struct VisibilityResolveKernel {
    keys: ReadSlot,
    position_depth: WriteSlot,
    normal_metallic: WriteSlot,
    albedo_roughness: WriteSlot,
    motion: WriteSlot,
    first_hit: Option<WriteSlot>,
}

impl PassKernel for VisibilityResolveKernel {
    fn record(&self, rec: &mut Recorder<'_>, pass: &PassInstance, index: InstanceId) -> parallax_backend::Result<()> {
        let image = |rec: &Recorder<'_>, slot| rec.image(pass.write(slot)?.alloc);
        let keys = pass.read(self.keys)?.alloc;
        let position_depth = pass.write(self.position_depth)?.alloc;
        let width = rec.resource(position_depth).width;
        if key_row_width(rec, VISIBILITY_RESOLVE, index, keys)? != width {
            return Err(misuse(VISIBILITY_RESOLVE, index, "the keys' rows are not the G-buffer's".into()));
        }
        let push = VisibilityResolvePush {
            scene: scene_refs(rec)?,
            trace: rec.frame_data_address() + u64::from(pass.view.0) * TRACE_PARAMS_BYTES,
            block: rec.frame_block_address()?,
            keys: rec.buffer_of(keys)?,
            position_depth: rec.image(position_depth)?,
            normal_metallic: image(rec, self.normal_metallic)?,
            albedo_roughness: image(rec, self.albedo_roughness)?,
            motion: image(rec, self.motion)?,
            view: pass.view.0,
            y0: pass.region.y0,
            y1: pass.region.y1,
            width,
            first_hit: self.first_hit.map_or(Ok(NO_IMAGE), |slot| image(rec, slot))?,
            pad: 0,
        };
        rec.dispatch(shaders::VISIBILITY_RESOLVE, &push, [width.div_ceil(8), pass.region.len().div_ceil(8).max(1), 1])
    }
}

/// Declares the visibility G-buffer for every view: the [`VISIBILITY`] keys and the
/// [`VISIBILITY_TILES`] lists (both reset each frame), `visibility_raster` into them and `visibility_resolve` from them into the images of
/// [`crate::gbuffer::declare_gbuffer`] (with `first_hit` when `with_first_hit`).
pub fn declare_gbuffer_visibility(graph: &mut KernelGraph, with_first_hit: bool) -> Gbuffer {
    let mut keys = graph.row_buffer(VISIBILITY, KEY_BYTES * u64::from(graph.topology().width));
    graph.reset_each_frame(&keys, Vec::new());
    let mut tiles = graph.row_buffer(VISIBILITY_TILES, tile_row_bytes(graph.topology().width));
    graph.reset_each_frame(&tiles, Vec::new());
    let mut pass = graph.pass(VISIBILITY_RASTER, Role::All);
    let (_, keys_written) = pass.modify_slot(&mut keys);
    let (_, tiles_written) = pass.modify_slot(&mut tiles);
    pass.kernel(Arc::new(VisibilityRasterKernel { keys: keys_written, tiles: tiles_written })).add();
    let mut g = Gbuffer {
        position_depth: graph.image("position_depth", Format::Rgba32f),
        normal_metallic: graph.image("normal_metallic", Format::Rgba32f),
        albedo_roughness: graph.image("albedo_roughness", Format::Rgba32f),
        motion: graph.image("motion", Format::Rg32f),
        first_hit: with_first_hit.then(|| graph.image(crate::gbuffer::FIRST_HIT, Format::R32u)),
    };
    let mut pass = graph.pass(VISIBILITY_RESOLVE, Role::All);
    let kernel = VisibilityResolveKernel {
        keys: pass.read_slot(&keys),
        position_depth: pass.write_slot(&mut g.position_depth),
        normal_metallic: pass.write_slot(&mut g.normal_metallic),
        albedo_roughness: pass.write_slot(&mut g.albedo_roughness),
        motion: pass.write_slot(&mut g.motion),
        first_hit: g.first_hit.as_mut().map(|first_hit| pass.write_slot(first_hit)),
    };
    pass.kernel(Arc::new(kernel)).add();
    g
}

/// The G-buffer a run asked for, the one that runs on its devices, and why they differ.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct GbufferChoice {
    pub requested: GbufferSource,
    pub runs: GbufferSource,
    /// Why `runs` is not `requested` (None: it is).
    pub fallback: Option<String>,
}

/// What runs of `requested` on `devices`: [`GbufferSource::Visibility`] needs 64-bit buffer
/// atomics ([`DeviceInfo::buffer_int64_atomics`]) on every device, else first hits are traced
/// instead (the same G-buffer images, by traversal), with the first device that lacks them
/// named. Other sources run as asked.
pub fn choose_gbuffer(requested: GbufferSource, devices: &[DeviceInfo]) -> GbufferChoice {
    let lacking = devices.iter().find(|d| !d.buffer_int64_atomics);
    match (requested, lacking) {
        (GbufferSource::Visibility, Some(device)) => GbufferChoice {
            requested,
            runs: GbufferSource::FirstHits,
            fallback: Some(format!(
                "device {} ({}) lacks shaderBufferInt64Atomics (VkPhysicalDeviceShaderAtomicInt64Features): first \
                 hits traced instead",
                device.index, device.name
            )),
        },
        _ => GbufferChoice { requested, runs: requested, fallback: None },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn device(index: usize, atomics: bool) -> DeviceInfo {
        DeviceInfo {
            index,
            physical_index: 0,
            name: format!("gpu{index}"),
            driver: String::new(),
            driver_info: String::new(),
            api_version: "1.3.0".into(),
            device_type: "DISCRETE_GPU".into(),
            runs_on_host_cpu: false,
            calibrated_timestamps: false,
            max_image_dimension_2d: 16384,
            device_local_heap_bytes: 1 << 30,
            buffer_int64_atomics: atomics,
            shared_int64_atomics: atomics,
            image_int64_atomics: false,
        }
    }

    #[test]
    fn visibility_runs_where_every_device_has_64_bit_buffer_atomics_and_falls_back_to_first_hits_elsewhere() {
        let all = [device(0, true), device(1, true)];
        let choice = choose_gbuffer(GbufferSource::Visibility, &all);
        assert_eq!(
            choice,
            GbufferChoice { requested: GbufferSource::Visibility, runs: GbufferSource::Visibility, fallback: None }
        );
        let one_lacks = [device(0, true), device(1, false), device(2, false)];
        let choice = choose_gbuffer(GbufferSource::Visibility, &one_lacks);
        assert_eq!((choice.requested, choice.runs), (GbufferSource::Visibility, GbufferSource::FirstHits));
        let reason = choice.fallback.expect("the reason is recorded");
        assert!(reason.starts_with("device 1 (gpu1) lacks shaderBufferInt64Atomics"), "{reason}");
        // The other sources need no atomics.
        for source in [GbufferSource::FirstHits, GbufferSource::Raster] {
            assert_eq!(
                choose_gbuffer(source, &one_lacks),
                GbufferChoice { requested: source, runs: source, fallback: None }
            );
        }
    }
}
