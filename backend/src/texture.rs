//! Sampled textures: read-only RGBA8 images (a scene's base-colour, metallic-roughness and
//! emissive maps) that every kernel can sample through the `textures[]` array of set 0
//! (binding 3, see shader_pipelines.rs and shaders/include/bindless.glsl).
//!
//! They are global like [`crate::Executor::upload_buffer`]'s buffers: uploaded once per device,
//! kept over plan changes, and unlike plan images they stay in `SHADER_READ_ONLY_OPTIMAL`.

use std::sync::Arc;

use ash::vk;

use crate::device::Device;
use crate::error::{BackendError, Result, VkContext};
use crate::memory::{Buffer, Image, color_layers, color_range};

/// Capacity of the texture array of set 0. Fixed so that the descriptor layout (and every
/// pipeline) does not depend on the scene; Sponza needs 69.
pub const MAX_TEXTURES: u32 = 1024;

/// One texture to upload: `width`×`height` RGBA8 texels, rows from the top, tightly packed.
/// The shader decides the colour space (the scene decodes sRGB itself), so it is stored UNORM.
#[derive(Clone, Copy, Debug)]
pub struct TextureData<'a> {
    pub width: u32,
    pub height: u32,
    pub rgba8: &'a [u8],
}

/// A sampled RGBA8 image on one device, in `SHADER_READ_ONLY_OPTIMAL` layout.
pub(crate) struct Texture {
    image: Image,
}

impl Texture {
    /// Creates the image and uploads `data` into it (waits for the upload).
    pub(crate) fn new(device: &Arc<Device>, name: &str, data: &TextureData<'_>) -> Result<Self> {
        let expected = u64::from(data.width) * u64::from(data.height) * 4;
        if data.width == 0 || data.height == 0 || data.rgba8.len() as u64 != expected {
            return Err(BackendError::TextureData {
                name: name.to_string(),
                width: data.width,
                height: data.height,
                bytes: data.rgba8.len(),
            });
        }
        let image = Image::new_sampled_rgba8(device, name, data.width, data.height)?;
        let raw = image.raw;
        let extent = vk::Extent3D { width: data.width, height: data.height, depth: 1 };
        let staging = Buffer::staging(device, "texture staging", data.rgba8)?;
        let raw_device = &device.raw;
        device.one_shot(|cb| unsafe {
            let to_dst = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::NONE)
                .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .old_layout(vk::ImageLayout::UNDEFINED)
                .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .image(raw)
                .subresource_range(color_range())];
            raw_device.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().image_memory_barriers(&to_dst));
            let region = vk::BufferImageCopy::default().image_subresource(color_layers()).image_extent(extent);
            raw_device.cmd_copy_buffer_to_image(
                cb,
                staging.raw(),
                raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            );
            let to_read = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COPY)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .dst_access_mask(vk::AccessFlags2::SHADER_SAMPLED_READ)
                .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .new_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)
                .image(raw)
                .subresource_range(color_range())];
            raw_device.cmd_pipeline_barrier2(cb, &vk::DependencyInfo::default().image_memory_barriers(&to_read));
        })?;
        Ok(Self { image })
    }

    pub(crate) fn view(&self) -> vk::ImageView {
        self.image.view
    }
}

/// The sampler of the texture array: bilinear, level 0, repeat, as the CPU reference's
/// `Texture::sample_bilinear` (scene crate) filters.
pub(crate) fn create_sampler(device: &Device) -> Result<vk::Sampler> {
    let info = vk::SamplerCreateInfo::default()
        .mag_filter(vk::Filter::LINEAR)
        .min_filter(vk::Filter::LINEAR)
        .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
        .address_mode_u(vk::SamplerAddressMode::REPEAT)
        .address_mode_v(vk::SamplerAddressMode::REPEAT)
        .address_mode_w(vk::SamplerAddressMode::REPEAT)
        .max_lod(0.0);
    unsafe { device.raw.create_sampler(&info, None) }.vk("vkCreateSampler")
}
