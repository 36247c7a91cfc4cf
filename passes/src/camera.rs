//! Cameras as the GPU projects with them: the clip-space matrix of a view that inverts the path
//! tracer's ray generation exactly (pt_trace.glsl: direction = right · p.x + up · p.y +
//! forward with p = ndc + shift), so a world point projects to the pixel whose centre ray hits
//! it. Reprojection, motion vectors and raster passes all use this one matrix.
//!
//! With d = P − eye, R = right · tan(yfov/2) · aspect, U = up · tan(yfov/2), F = forward:
//! clip = (d·R/|R|² − shift.x · d·F, d·U/|U|² − shift.y · d·F, d·F − near, d·F), so
//! ndc = clip.xy / clip.w recovers p − shift and clip.w is the path tracer's linear depth.
//! Depth (clip.z / clip.w = 1 − near / depth) grows with distance: a LESS depth test works.

use glam::{Mat4, Vec2, Vec3, Vec4};
use parallax_backend::{FrameBlock, FrameClock, GpuCamera};
use parallax_graph::{LightField, Rig, ViewId};
use parallax_scene::{Camera, View};

/// Distance of the depth range's near end, in scene units.
pub const NEAR: f32 = 1e-3;

/// The light-field rig of `camera`: the zero-disparity plane `focus` in front of it, or through
/// the point `centre` when no focus is given (1 when that lies behind the camera).
pub fn rig_of(camera: &Camera, centre: Vec3, focus: Option<f64>) -> Rig {
    let to_centre = (centre - camera.eye).dot(camera.forward.normalize()) as f64;
    Rig {
        eye: camera.eye.as_dvec3(),
        forward: camera.forward.as_dvec3(),
        up: camera.up.as_dvec3(),
        yfov: camera.yfov as f64,
        focus_distance: focus.unwrap_or(if to_centre > 0.0 { to_centre } else { 1.0 }),
    }
}

/// View `v` of `lf` as the renderer sees it. The scene camera adds its shift to the NDC point
/// (the planner's camera subtracts it), hence the sign.
pub fn lightfield_view(lf: &LightField, v: ViewId) -> View {
    let c = lf.camera(v);
    let camera = Camera {
        eye: c.eye.as_vec3(),
        forward: c.forward.as_vec3(),
        up: c.up.as_vec3(),
        yfov: c.yfov as f32,
        shift: -Vec2::new(c.ndc_shift.x as f32, c.ndc_shift.y as f32),
    };
    View { camera, width: lf.width, height: lf.height, index: v.0 }
}

/// Every view of `lf`, in view order.
pub fn lightfield_views(lf: &LightField) -> Vec<View> {
    lf.views().map(|v| lightfield_view(lf, v)).collect()
}

/// World → clip of `view` (see the module docs), the depth range starting at [`NEAR`].
pub fn view_projection(view: &View) -> Mat4 {
    view_projection_near(view, NEAR)
}

/// [`view_projection`] with the depth range starting at `near` (> 0).
pub fn view_projection_near(view: &View, near: f32) -> Mat4 {
    let camera = &view.camera;
    let (right, up, back) = camera.basis();
    let tan_half = (0.5 * camera.yfov).tan();
    let r = right * (tan_half * view.aspect());
    let u = up * tan_half;
    let f = -back;
    let x = r / r.length_squared() - camera.shift.x * f;
    let y = u / u.length_squared() - camera.shift.y * f;
    let row = |axis: Vec3, offset: f32| axis.extend(offset - axis.dot(camera.eye));
    Mat4::from_cols(row(x, 0.0), row(y, 0.0), row(f, -near), row(f, 0.0)).transpose()
}

/// The pixel position (pixel centre = i + 0.5) and linear depth of world point `p` in `view`,
/// or `None` behind the camera.
pub fn project(view: &View, p: Vec3) -> Option<(Vec2, f32)> {
    let clip: Vec4 = view_projection(view) * p.extend(1.0);
    if clip.w <= 0.0 {
        return None;
    }
    let ndc = Vec2::new(clip.x, clip.y) / clip.w;
    Some((Vec2::new((ndc.x + 1.0) * 0.5 * view.width as f32, (1.0 - ndc.y) * 0.5 * view.height as f32), clip.w))
}

/// The frame block of one frame of `views` (current cameras; `clock` keeps last frame's as
/// previous and says when history is invalid).
pub fn frame_block(clock: &mut FrameClock, views: &[View]) -> FrameBlock {
    let cameras: Vec<GpuCamera> =
        views.iter().map(|v| GpuCamera::new(view_projection(v), v.camera.eye, Vec2::ZERO)).collect();
    clock.advance(&cameras)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn views() -> Vec<View> {
        let mut shifted = Camera::look_at(Vec3::new(0.3, 1.0, 4.0), Vec3::new(0.0, 0.5, 0.0), Vec3::Y, 0.9);
        shifted.shift = Vec2::new(0.07, -0.03);
        vec![
            View {
                camera: Camera::look_at(Vec3::new(0.0, 1.0, 3.0), Vec3::ZERO, Vec3::Y, 0.8),
                width: 64,
                height: 48,
                index: 0,
            },
            View { camera: shifted, width: 40, height: 40, index: 1 },
        ]
    }

    #[test]
    fn a_point_on_a_pixels_centre_ray_projects_back_to_that_pixel() {
        for view in views() {
            for (x, y) in [(0u32, 0u32), (17, 5), (view.width - 1, view.height - 1), (view.width / 2, view.height / 3)]
            {
                let ndc = Vec2::new(
                    (x as f32 + 0.5) / view.width as f32 * 2.0 - 1.0,
                    1.0 - (y as f32 + 0.5) / view.height as f32 * 2.0,
                );
                let dir = view.camera.ray_direction(ndc, view.aspect());
                for t in [0.5, 2.0, 10.0] {
                    let p = view.camera.eye + dir * t;
                    let (pixel, depth) = project(&view, p).unwrap();
                    assert!((pixel - Vec2::new(x as f32 + 0.5, y as f32 + 0.5)).abs().max_element() < 1e-3, "{pixel}");
                    assert!((depth - dir.dot(view.camera.forward.normalize()) * t).abs() < 1e-4 * t);
                }
            }
        }
    }

    #[test]
    fn points_behind_the_camera_do_not_project() {
        let view = &views()[0];
        assert!(project(view, view.camera.eye - view.camera.forward).is_none());
    }

    #[test]
    fn the_clock_gives_last_frames_camera_as_previous() {
        let mut clock = FrameClock::new();
        let mut vs = views();
        let first = frame_block(&mut clock, &vs);
        assert_eq!(first.views[0].previous, first.views[0].current);
        vs[0].camera.eye.x += 0.1;
        let second = frame_block(&mut clock, &vs);
        assert_eq!(second.views[0].previous, first.views[0].current);
        assert_ne!(second.views[0].current, first.views[0].current);
    }
}
