//! The typed per-frame block every pass can read: the frame index, whether last frame's data
//! may be reused, and for every view the current and the previous camera. Declared for shaders
//! in `shaders/include/frame_block.glsl` (std430; every member is laid out as under the scalar
//! layout too, the explicit pads make sure of that); `backend/tests/lavapipe_frame.rs` holds the
//! two declarations together through the SPIR-V's member offsets.
//!
//! [`FrameClock`] turns each frame's cameras into a block, remembering last frame's; the block
//! travels as the [`FRAME_BLOCK_SECTION`] section of the per-frame data ([`crate::FrameData`]).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2, Vec3};

/// Name of the per-frame data section that holds the frame block, by convention.
pub const FRAME_BLOCK_SECTION: &str = "frame";

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

/// The block's header (the first four members of `FrameBlock` in frame_block.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct FrameHeader {
    /// Frames since the clock started (wraps at 2³²).
    pub frame_index: u32,
    /// 1 if every view's `previous` camera is last frame's, 0 on the first frame and after a
    /// camera cut (then `previous` equals `current`, and history must not be reused).
    pub history_valid: u32,
    pub view_count: u32,
    pub pad: u32,
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
/// frame's previous one.
#[derive(Clone, Debug, Default)]
pub struct FrameClock {
    frame_index: u32,
    last: Option<Vec<GpuCamera>>,
}

impl FrameClock {
    pub fn new() -> Self {
        Self::default()
    }

    /// The block of the next frame, whose views see `cameras`. History is invalid on the first
    /// frame, after [`Self::reset_history`], and when the number of views changed.
    pub fn advance(&mut self, cameras: &[GpuCamera]) -> FrameBlock {
        let previous = self.last.as_ref().filter(|last| last.len() == cameras.len());
        let views = cameras
            .iter()
            .enumerate()
            .map(|(v, &current)| ViewCameras { current, previous: previous.map_or(current, |p| p[v]) })
            .collect();
        let header = FrameHeader {
            frame_index: self.frame_index,
            history_valid: u32::from(previous.is_some()),
            view_count: u32::try_from(cameras.len()).unwrap_or(u32::MAX),
            pad: 0,
        };
        self.last = Some(cameras.to_vec());
        self.frame_index = self.frame_index.wrapping_add(1);
        FrameBlock { header, views }
    }

    /// A camera cut: the next frame has no usable history.
    pub fn reset_history(&mut self) {
        self.last = None;
    }

    /// Index the next [`Self::advance`] gives its block.
    pub fn next_frame_index(&self) -> u32 {
        self.frame_index
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(x: f32) -> GpuCamera {
        GpuCamera::new(Mat4::from_translation(Vec3::new(x, 0.0, 0.0)), Vec3::new(x, 1.0, 2.0), Vec2::new(0.25, -0.25))
    }

    #[test]
    fn previous_is_last_frames_current_until_a_cut() {
        let mut clock = FrameClock::new();
        let first = clock.advance(&[camera(1.0), camera(2.0)]);
        assert_eq!(first.header, FrameHeader { frame_index: 0, history_valid: 0, view_count: 2, pad: 0 });
        assert!(first.views.iter().all(|v| v.previous == v.current));
        let second = clock.advance(&[camera(3.0), camera(4.0)]);
        assert_eq!((second.header.frame_index, second.header.history_valid), (1, 1));
        assert_eq!(second.views[0].previous, camera(1.0));
        assert_eq!(second.views[1].previous, camera(2.0));
        clock.reset_history();
        let cut = clock.advance(&[camera(5.0), camera(6.0)]);
        assert_eq!((cut.header.frame_index, cut.header.history_valid), (2, 0));
        assert!(cut.views.iter().all(|v| v.previous == v.current));
        let fewer = clock.advance(&[camera(7.0)]);
        assert_eq!(fewer.header.history_valid, 0, "a view that did not exist last frame has no history");
        assert_eq!(clock.next_frame_index(), 4);
    }

    #[test]
    fn bytes_are_the_header_then_the_views() {
        let block = FrameClock::new().advance(&[camera(1.0)]);
        let bytes = block.to_bytes();
        assert_eq!(bytes.len(), 16 + 320);
        assert_eq!(&bytes[8..12], &1u32.to_le_bytes());
        // The inverse really is one: the translation's inverse moves back.
        let inverse = Mat4::from_cols_array_2d(&block.views[0].current.inv_view_proj);
        assert_eq!(inverse.transform_point3(Vec3::new(1.0, 0.0, 0.0)), Vec3::ZERO);
    }
}
