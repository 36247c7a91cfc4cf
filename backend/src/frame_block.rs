//! The typed per-frame block every pass can read: the frame index, whether last frame's data
//! may be reused, and for every view the current and the previous camera. Declared for shaders
//! in `shaders/include/frame_block.glsl` (std430; every member is laid out as under the scalar
//! layout too, the explicit pads make sure of that); `backend/tests/lavapipe_frame.rs` holds the
//! two declarations together through the SPIR-V's member offsets.
//!
//! [`FrameClock`] turns each frame's cameras into a block, remembering last frame's; the block
//! travels in the per-frame data ([`crate::FrameData::frame_block`]), and kernels find it with
//! [`crate::Recorder::frame_block_address`]. The frame index and the history flag are not in
//! the block: the executor alone writes them, once per frame, into the frame constants every
//! kernel sees ([`FrameConstants`]; a plan change or `Executor::reset_history` clears the flag).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2, Vec3};

/// One camera as shaders see it (`GpuCamera` in frame_block.glsl). Matrices are column-major,
/// as GLSL's `mat4`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCamera {
    /// World → clip space.
    pub view_proj: [[f32; 4]; 4],
    /// Clip → world space.
    pub inv_view_proj: [[f32; 4]; 4],
    /// Eye position in world space; `w` unused.
    pub position: [f32; 4],
    /// Sub-pixel offset applied to this frame's projection, in pixels.
    pub jitter: [f32; 2],
    pub pad: [f32; 2],
}

impl GpuCamera {
    /// The camera of `view_proj` (its inverse computed here) at `position`.
    pub fn new(view_proj: Mat4, position: Vec3, jitter: Vec2) -> Self {
        Self {
            view_proj: view_proj.to_cols_array_2d(),
            inv_view_proj: view_proj.inverse().to_cols_array_2d(),
            position: position.extend(0.0).to_array(),
            jitter: jitter.to_array(),
            pad: [0.0; 2],
        }
    }
}

/// The frame index and history flag of one frame, as the executor writes them at submission
/// into the frame constants of bindless.glsl (`frame.frame_index`, `frame.history_valid`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct FrameConstants {
    /// Frames the executor submitted before this one (wraps at 2³²).
    pub frame_index: u32,
    /// 0 on the first frame of a plan and after `Executor::reset_history` (a camera cut): what
    /// history reads and the previous cameras hold then must not be reused; 1 otherwise.
    pub history_valid: u32,
}

impl FrameConstants {
    pub fn new(frame: u64, history_valid: bool) -> Self {
        Self { frame_index: frame as u32, history_valid: u32::from(history_valid) }
    }

    /// Writes these constants over the first 8 bytes of `header` (the frame constants buffer),
    /// if it is that long.
    pub(crate) fn write_into(&self, header: &mut [u8]) {
        if let Some(words) = header.get_mut(..size_of::<Self>()) {
            words.copy_from_slice(bytemuck::bytes_of(self));
        }
    }
}

/// The block's header (`view_count` and `pad` of `FrameBlock` in frame_block.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct FrameHeader {
    pub view_count: u32,
    /// Keeps the views 16-byte aligned, as their matrices are in GLSL.
    pub pad: [u32; 3],
}

/// The cameras of one view (`ViewCameras` in frame_block.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ViewCameras {
    pub current: GpuCamera,
    pub previous: GpuCamera,
}

/// A whole frame block: the header, then one [`ViewCameras`] per view.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameBlock {
    pub header: FrameHeader,
    pub views: Vec<ViewCameras>,
}

impl FrameBlock {
    /// The bytes shaders read: the header followed by the views, tightly packed.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = bytemuck::bytes_of(&self.header).to_vec();
        bytes.extend_from_slice(bytemuck::cast_slice(&self.views));
        bytes
    }
}

/// Camera history from frame to frame: last frame's current camera of each view becomes this
/// frame's previous one. Whether kernels may use it is the executor's history flag
/// ([`FrameConstants::history_valid`]).
#[derive(Clone, Debug, Default)]
pub struct FrameClock {
    last: Option<Vec<GpuCamera>>,
}

impl FrameClock {
    pub fn new() -> Self {
        Self::default()
    }

    /// The block of the next frame, whose views see `cameras`. A view's previous camera is its
    /// current one on the first frame and when the number of views changed.
    pub fn advance(&mut self, cameras: &[GpuCamera]) -> FrameBlock {
        let previous = self.last.as_ref().filter(|last| last.len() == cameras.len());
        let views = cameras
            .iter()
            .enumerate()
            .map(|(v, &current)| ViewCameras { current, previous: previous.map_or(current, |p| p[v]) })
            .collect();
        let header = FrameHeader { view_count: u32::try_from(cameras.len()).unwrap_or(u32::MAX), pad: [0; 3] };
        self.last = Some(cameras.to_vec());
        FrameBlock { header, views }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(x: f32) -> GpuCamera {
        GpuCamera::new(Mat4::from_translation(Vec3::new(x, 0.0, 0.0)), Vec3::new(x, 1.0, 2.0), Vec2::new(0.25, -0.25))
    }

    #[test]
    fn previous_is_last_frames_current_while_the_views_stay() {
        let mut clock = FrameClock::new();
        let first = clock.advance(&[camera(1.0), camera(2.0)]);
        assert_eq!(first.header, FrameHeader { view_count: 2, pad: [0; 3] });
        assert!(first.views.iter().all(|v| v.previous == v.current));
        let second = clock.advance(&[camera(3.0), camera(4.0)]);
        assert_eq!(second.views[0].previous, camera(1.0));
        assert_eq!(second.views[1].previous, camera(2.0));
        let fewer = clock.advance(&[camera(7.0)]);
        assert_eq!(fewer.views[0].previous, camera(7.0), "a view that did not exist last frame has no history");
    }

    #[test]
    fn the_executors_constants_are_the_frame_index_modulo_two_to_the_32_then_the_flag() {
        let mut bytes = [0xffu8; 12];
        FrameConstants::new(u64::from(u32::MAX) + 3, true).write_into(&mut bytes);
        assert_eq!(bytes.to_vec(), [2u32.to_le_bytes(), 1u32.to_le_bytes(), [0xff; 4]].concat());
        let mut short = [0u8; 4];
        FrameConstants::new(1, true).write_into(&mut short);
        assert_eq!(short, [0; 4], "too short to hold them: left alone");
    }

    #[test]
    fn bytes_are_the_header_then_the_views() {
        let block = FrameClock::new().advance(&[camera(1.0)]);
        let bytes = block.to_bytes();
        assert_eq!(bytes.len(), 16 + 320);
        assert_eq!(&bytes[..4], &1u32.to_le_bytes());
        // The inverse really is one: the translation's inverse moves back.
        let inverse = Mat4::from_cols_array_2d(&block.views[0].current.inv_view_proj);
        assert_eq!(inverse.transform_point3(Vec3::new(1.0, 0.0, 0.0)), Vec3::ZERO);
    }
}
