//! The pinhole camera that views, the CPU reference and the GPU passes look through.

use glam::{Mat4, Vec2, Vec3};

/// A pinhole camera looking down its local -Z with +Y up (glTF convention).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub forward: Vec3,
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub yfov: f32,
    /// Off-axis shift of the image window in NDC units (light-field views pan it so that the
    /// zero-disparity plane lines up); zero for an ordinary camera.
    pub shift: Vec2,
}

impl Camera {
    /// A camera at `eye` looking at `target`; `up` need not be orthogonal to the view direction.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, yfov: f32) -> Self {
        let forward = (target - eye).normalize_or(Vec3::NEG_Z);
        Self { eye, forward, up: up.normalize_or(Vec3::Y), yfov, shift: Vec2::ZERO }
    }

    /// From a glTF camera node's world matrix (camera looks down its -Z).
    pub fn from_world_matrix(world: Mat4, yfov: f32) -> Self {
        let eye = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
        let up = world.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
        Self { eye, forward, up, yfov, shift: Vec2::ZERO }
    }

    /// Orthonormal (right, up, back) basis; `back` = -forward.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let back = -self.forward.normalize_or(Vec3::NEG_Z);
        let mut right = self.up.cross(back);
        if right.length_squared() < 1e-12 {
            right = back.any_orthonormal_vector();
        }
        let right = right.normalize();
        let up = back.cross(right);
        (right, up, back)
    }

    /// World-space direction (unit) through the image point `ndc` (x right, y up, -1..1).
    pub fn ray_direction(&self, ndc: Vec2, aspect: f32) -> Vec3 {
        let (right, up, back) = self.basis();
        let tan_half = (0.5 * self.yfov).tan();
        let p = ndc + self.shift;
        (right * (p.x * tan_half * aspect) + up * (p.y * tan_half) - back).normalize()
    }

    pub fn is_finite(&self) -> bool {
        self.eye.is_finite()
            && self.forward.is_finite()
            && self.up.is_finite()
            && self.yfov.is_finite()
            && self.shift.is_finite()
    }
}
