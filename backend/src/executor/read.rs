//! Reading a resource back outside the frame loop (waits for every frame).

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::error::{BackendError, Result};
use crate::memory::Buffer;
use crate::plan::{AllocId, DeviceId};

use super::Executor;

impl Executor {
    /// Reads an image (tightly packed rows) or a buffer back from `device` (waits for all
    /// frames).
    pub fn read_resource(&mut self, device: DeviceId, resource: AllocId) -> Result<Vec<u8>> {
        self.finish()?;
        // A history allocation's halves swap by frame parity: read the half the last frame
        // wrote in `resource`'s place (and its other half for the pair's other member).
        let last_parity = self.next_frame.saturating_sub(1) % 2;
        let resource = self.plan.parity_map(last_parity as usize).get(&resource).copied().unwrap_or(resource);
        let state = &self.states[device.index()];
        let image = state.images.get(&resource);
        let buffer = state.buffers.get(&resource);
        if image.is_none() && buffer.is_none() {
            return Err(BackendError::ResourceNotOnDevice { resource, device: device.index() });
        }
        let size = self.plan.resource(resource).bytes();
        let readback =
            Buffer::new(&state.device, "readback", size, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)?;
        let raw = &state.device.raw;
        state.device.one_shot(|cb| unsafe {
            crate::record::full_barrier(raw, cb);
            if let Some(image) = image {
                let region = vk::BufferImageCopy::default()
                    .image_subresource(image.layers())
                    .image_extent(vk::Extent3D { width: image.width, height: image.height, depth: 1 });
                raw.cmd_copy_image_to_buffer(cb, image.raw, vk::ImageLayout::GENERAL, readback.raw, &[region]);
            } else if let Some(buffer) = buffer {
                raw.cmd_copy_buffer(
                    cb,
                    buffer.raw,
                    readback.raw,
                    &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size }],
                );
            }
            let to_host = [vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COPY)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::HOST)
                .dst_access_mask(vk::AccessFlags2::HOST_READ)];
            raw.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().memory_barriers(&to_host));
        })?;
        Ok(readback.mapped().expect("GpuToCpu buffers are mapped").to_vec())
    }
}
