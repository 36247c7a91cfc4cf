//! Reading a resource back outside the frame loop (waits for every frame), copied as the frame
//! loop's readback copies ([`crate::record::record_copy_to_host_buffer`]).

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::error::{BackendError, Result};
use crate::memory::Buffer;
use crate::plan::{AllocId, DeviceId};
use crate::record;

use super::Executor;

impl Executor {
    /// Reads an image (tightly packed rows) or a buffer back from `device` (waits for all
    /// frames).
    pub fn read_resource(&mut self, device: DeviceId, resource: AllocId) -> Result<Vec<u8>> {
        self.finish()?;
        // A history allocation's halves swap by frame parity: read the half the last frame
        // wrote in `resource`'s place (and its other half for the pair's other member).
        let last_parity = self.next_frame.saturating_sub(1) % 2;
        let held = self.plan.parity_map(last_parity as usize).get(&resource).copied().unwrap_or(resource);
        let state = self
            .states
            .get(device.index())
            .filter(|state| state.images.contains_key(&held) || state.buffers.contains_key(&held))
            .ok_or(BackendError::ResourceNotOnDevice { resource, device: device.index() })?;
        let resource = held;
        let desc = self.plan.resource(resource);
        let readback = Buffer::new(
            &state.device,
            "readback",
            desc.bytes(),
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let raw = &state.device.raw;
        state.device.one_shot(|cb| {
            record::full_barrier(raw, cb);
            record::record_copy_to_host_buffer(raw, cb, (&state.images, &state.buffers), resource, desc, readback.raw);
            record::copies_to_host_barrier(raw, cb);
        })?;
        Ok(readback.mapped().expect("GpuToCpu buffers are mapped").to_vec())
    }
}
