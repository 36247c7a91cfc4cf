//! What the host hands the devices outside the recorded frame: global buffers, textures, per-frame
//! data.

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::error::{BackendError, Result};
use crate::frame_data::FrameData;
use crate::memory::Buffer;
use crate::texture::{MAX_TEXTURES, Texture, TextureData};

use super::Executor;

impl Executor {
    /// Uploads `bytes` as the global buffer `name` on every device (scene data: BVH nodes,
    /// triangles, materials, ...), reachable from kernels through
    /// `Recorder::buffer_address(name)`. Waits for all frames in flight. Re-uploading the same
    /// size keeps the buffer (and the recorded command buffers); another size replaces it and
    /// the command buffers are recorded again before the next frame.
    pub fn upload_buffer(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        self.finish()?;
        let size = (bytes.len() as u64).max(4);
        for (d, device) in self.devices.iter().enumerate() {
            let keep = self.globals[d].get(name).is_some_and(|b| b.size == size);
            if !keep {
                let buffer = Buffer::new(
                    device,
                    name,
                    size,
                    vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::TRANSFER_DST
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                    MemoryLocation::GpuOnly,
                )?;
                self.globals[d].insert(name.to_string(), buffer);
                self.needs_record = true;
            }
            let staging = Buffer::staging(device, "upload staging", bytes)?;
            let target = self.globals[d][name].raw;
            let raw = &device.raw;
            device.one_shot(|cb| unsafe {
                crate::record::full_barrier(raw, cb);
                raw.cmd_copy_buffer(cb, staging.raw, target, &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size }]);
                crate::record::full_barrier(raw, cb);
            })?;
        }
        Ok(())
    }

    /// Uploads `textures` on every device as the sampled-texture array every kernel sees
    /// (`textures[i]` in shaders/include/bindless.glsl), replacing earlier ones. Waits for all
    /// frames in flight; command buffers are recorded again before the next frame.
    pub fn upload_textures(&mut self, textures: &[TextureData<'_>]) -> Result<()> {
        if textures.len() > MAX_TEXTURES as usize {
            return Err(BackendError::TooManyTextures { count: textures.len(), max: MAX_TEXTURES });
        }
        self.finish()?;
        for (d, device) in self.devices.iter().enumerate() {
            let uploaded = textures
                .iter()
                .enumerate()
                .map(|(i, t)| Texture::new(device, &format!("texture {i}"), t))
                .collect::<Result<Vec<_>>>()?;
            let views: Vec<vk::ImageView> = uploaded.iter().map(Texture::view).collect();
            // No frame is in flight (finish above), so the descriptor sets can change; the old
            // textures go only after the sets no longer name them.
            self.states[d].bindless.set_textures(&views);
            self.textures[d] = uploaded;
        }
        self.needs_record = true;
        Ok(())
    }

    /// Sets the per-frame data (camera matrices, sample counters, ...) that every following
    /// frame's kernels read at `Recorder::frame_data_address()`; copied into the frame's slot at
    /// each `run_frame`, so recorded command buffers stay valid. The same as
    /// `set_frame(&FrameData::whole(bytes))`.
    pub fn set_frame_data(&mut self, bytes: &[u8]) -> Result<()> {
        self.set_frame(&FrameData::whole(bytes))
    }

    /// Sets the per-frame data of every following frame, sections and frame block included
    /// (kernels find them at `Recorder::frame_section_address` and `frame_block_address`). The
    /// same sections and block at the same offsets as before only change bytes
    /// ([`FrameData::same_layout`]); another layout waits for the frames in flight and has the command
    /// buffers recorded again before the next frame.
    pub fn set_frame(&mut self, data: &FrameData) -> Result<()> {
        let bytes = data.bytes().len();
        if bytes as u64 > self.options.frame_data_bytes {
            return Err(BackendError::FrameDataTooLarge { bytes, capacity: self.options.frame_data_bytes });
        }
        if !data.same_layout(&self.frame_data) {
            self.finish()?;
            self.needs_record = true;
        }
        self.frame_data.clone_from(data);
        Ok(())
    }
}
