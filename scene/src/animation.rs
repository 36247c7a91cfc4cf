//! glTF animation: keyframe tracks of a node's translation, rotation and scale (glTF samplers:
//! STEP, LINEAR — slerp for rotations — and CUBICSPLINE) and a node's transform at time t. The
//! camera's animation is the world transform of the scene's camera node at time t, from its
//! node and every node above it; `parallax render` follows it frame by frame when a scene has
//! one. Skinned and node-animated meshes are posed from the same nodes ([`crate::posing`]).

use glam::{Mat4, Quat, Vec3};

use crate::camera::Camera;

/// How a sampler interpolates between keyframes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    /// Values come as (in-tangent, value, out-tangent) triplets.
    CubicSpline,
}

/// One animated property: keyframe times (seconds, increasing) and values.
#[derive(Clone, Debug, PartialEq)]
pub struct Track<T> {
    pub times: Vec<f32>,
    pub values: Vec<T>,
    pub interpolation: Interpolation,
}

/// What interpolation needs of a value type.
pub trait Animatable: Copy {
    fn lerp(a: Self, b: Self, t: f32) -> Self;
    fn hermite(p0: Self, m0: Self, p1: Self, m1: Self, t: f32, dt: f32) -> Self;
}

impl Animatable for Vec3 {
    fn lerp(a: Self, b: Self, t: f32) -> Self {
        a.lerp(b, t)
    }
    fn hermite(p0: Self, m0: Self, p1: Self, m1: Self, t: f32, dt: f32) -> Self {
        let (t2, t3) = (t * t, t * t * t);
        p0 * (2.0 * t3 - 3.0 * t2 + 1.0)
            + m0 * (dt * (t3 - 2.0 * t2 + t))
            + p1 * (3.0 * t2 - 2.0 * t3)
            + m1 * (dt * (t3 - t2))
    }
}

impl Animatable for Quat {
    fn lerp(a: Self, b: Self, t: f32) -> Self {
        a.slerp(b, t)
    }
    fn hermite(p0: Self, m0: Self, p1: Self, m1: Self, t: f32, dt: f32) -> Self {
        let v = |q: Quat| glam::Vec4::from(q);
        let (t2, t3) = (t * t, t * t * t);
        let r = v(p0) * (2.0 * t3 - 3.0 * t2 + 1.0)
            + v(m0) * (dt * (t3 - 2.0 * t2 + t))
            + v(p1) * (3.0 * t2 - 2.0 * t3)
            + v(m1) * (dt * (t3 - t2));
        Quat::from_vec4(r).normalize()
    }
}

impl<T: Animatable> Track<T> {
    /// The value at time `t`, clamped to the first and last keyframes.
    pub fn sample(&self, t: f32) -> T {
        let key = |i: usize| match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * i + 1],
            _ => self.values[i],
        };
        let n = self.times.len();
        if t <= self.times[0] || n == 1 {
            return key(0);
        }
        if t >= self.times[n - 1] {
            return key(n - 1);
        }
        let i = self.times.partition_point(|&k| k <= t) - 1;
        let dt = self.times[i + 1] - self.times[i];
        let s = if dt > 0.0 { (t - self.times[i]) / dt } else { 0.0 };
        match self.interpolation {
            Interpolation::Step => key(i),
            Interpolation::Linear => T::lerp(key(i), key(i + 1), s),
            Interpolation::CubicSpline => {
                T::hermite(key(i), self.values[3 * i + 2], key(i + 1), self.values[3 * (i + 1)], s, dt)
            }
        }
    }

    /// Whether the track has keyframes and, per the sampler, the values to go with them.
    pub fn is_well_formed(&self) -> bool {
        let per_key = if self.interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        !self.times.is_empty()
            && self.values.len() == per_key * self.times.len()
            && self.times.windows(2).all(|w| w[0] <= w[1])
            && self.times.iter().all(|t| t.is_finite())
    }
}

/// One glTF node: its rest transform and what animates it.
#[derive(Clone, Debug, PartialEq)]
pub struct AnimatedNode {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
    /// A node given by a matrix cannot be animated (glTF): its matrix, used as is.
    pub matrix: Option<Mat4>,
    pub translation_track: Option<Track<Vec3>>,
    pub rotation_track: Option<Track<Quat>>,
    pub scale_track: Option<Track<Vec3>>,
}

impl AnimatedNode {
    /// Whether a track moves the node.
    pub fn is_animated(&self) -> bool {
        self.translation_track.is_some() || self.rotation_track.is_some() || self.scale_track.is_some()
    }

    /// The node's transform relative to its parent at time `t`.
    pub(crate) fn local(&self, t: f32) -> Mat4 {
        if let Some(m) = self.matrix {
            return m;
        }
        let tr = self.translation_track.as_ref().map_or(self.translation, |k| k.sample(t));
        let rot = self.rotation_track.as_ref().map_or(self.rotation, |k| k.sample(t).normalize());
        let sc = self.scale_track.as_ref().map_or(self.scale, |k| k.sample(t));
        Mat4::from_scale_rotation_translation(sc, rot, tr)
    }
}

/// The scene camera's animation.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraAnimation {
    /// Root first, the camera's node last.
    pub nodes: Vec<AnimatedNode>,
    pub yfov: f32,
    /// Time of the last keyframe, seconds.
    pub duration: f32,
}

impl CameraAnimation {
    /// The camera at time `t` seconds (held at the ends).
    pub fn camera_at(&self, t: f32) -> Camera {
        let world = self.nodes.iter().fold(Mat4::IDENTITY, |world, node| world * node.local(t));
        Camera::from_world_matrix(world, self.yfov)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(track: Option<Track<Vec3>>) -> AnimatedNode {
        AnimatedNode {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
            matrix: None,
            translation_track: track,
            rotation_track: None,
            scale_track: None,
        }
    }

    #[test]
    fn linear_tracks_interpolate_and_hold_at_the_ends() {
        let track = Track {
            times: vec![0.0, 2.0],
            values: vec![Vec3::ZERO, Vec3::new(4.0, 0.0, 0.0)],
            interpolation: Interpolation::Linear,
        };
        assert!(track.is_well_formed());
        assert_eq!(track.sample(-1.0), Vec3::ZERO);
        assert_eq!(track.sample(0.5), Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(track.sample(9.0), Vec3::new(4.0, 0.0, 0.0));
        let step = Track { interpolation: Interpolation::Step, ..track };
        assert_eq!(step.sample(1.9), Vec3::ZERO);
    }

    #[test]
    fn cubic_splines_pass_through_their_keys_and_use_the_tangents() {
        let z = Vec3::ZERO;
        let one = Vec3::X;
        // Flat tangents: a smoothstep from 0 to 1.
        let track = Track {
            times: vec![0.0, 1.0],
            values: vec![z, z, z, z, one, z],
            interpolation: Interpolation::CubicSpline,
        };
        assert!(track.is_well_formed());
        assert_eq!(track.sample(0.0), z);
        assert_eq!(track.sample(1.0), one);
        assert!((track.sample(0.5).x - 0.5).abs() < 1e-6);
        assert!((track.sample(0.25).x - 0.15625).abs() < 1e-6);
    }

    #[test]
    fn a_parent_moves_its_camera() {
        let mut parent = node(Some(Track {
            times: vec![0.0, 1.0],
            values: vec![Vec3::ZERO, Vec3::new(0.0, 0.0, 10.0)],
            interpolation: Interpolation::Linear,
        }));
        parent.rotation = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        let animation = CameraAnimation { nodes: vec![parent, node(None)], yfov: 0.8, duration: 1.0 };
        let camera = animation.camera_at(0.5);
        assert!((camera.eye - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-5);
        // Rotated a quarter turn about y: the camera's -z looks along -x.
        assert!((camera.forward - Vec3::NEG_X).length() < 1e-5);
    }
}
