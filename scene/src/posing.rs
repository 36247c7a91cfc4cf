//! Skinned and node-animated meshes posed at a time of the scene's glTF animation: every
//! animated node's translation, rotation and scale sampled at t ([`crate::animation`]'s tracks),
//! the nodes' world matrices at t, and the moving primitives' positions and normals from them —
//! a skinned vertex by its joints' world matrices times their inverse bind matrices, blended by
//! JOINTS_0/WEIGHTS_0, any other vertex by its node's world matrix.
//!
//! The importer keeps what posing needs (each moving primitive's vertices as the file has them,
//! its skin, where its vertices lie in the scene's arrays) and poses the scene once at t = 0;
//! [`crate::Scene::pose_at`] writes the positions and normals of another time in place, so a
//! renderer redoes per frame only what moves (materials, textures, UVs and triangles stay).

use std::path::PathBuf;

use glam::{Mat4, Vec3};

use crate::animation::AnimatedNode;
use crate::error::SceneError;
use crate::gltf_primitive::{SkinWeights, lay_out, pose};
use crate::limits::MAX_COORDINATE;

/// The moving geometry of a scene: its nodes with the tracks of the file's first animation and
/// the primitives they move.
#[derive(Clone, Debug)]
pub struct GeometryAnimation {
    /// The scene file, which errors name.
    pub(crate) path: PathBuf,
    /// Every node of the file, by index: its rest transform and its tracks.
    pub(crate) nodes: Vec<AnimatedNode>,
    /// The nodes of the scene, each after its parent (None for a root).
    pub(crate) order: Vec<(usize, Option<usize>)>,
    /// Time of the last keyframe, seconds.
    pub(crate) duration: f32,
    pub(crate) primitives: Vec<MovingPrimitive>,
}

/// A primitive that the animation moves: its vertices as the file has them and where their
/// posed copies lie in the scene's arrays.
#[derive(Clone, Debug)]
pub(crate) struct MovingPrimitive {
    pub(crate) mesh: usize,
    pub(crate) primitive: usize,
    /// The node whose world matrix places an unskinned primitive.
    pub(crate) node: usize,
    /// The first of its vertices in [`crate::Scene::positions`] and `normals`.
    pub(crate) first_vertex: usize,
    pub(crate) positions: Vec<Vec3>,
    pub(crate) normals: Option<Vec<Vec3>>,
    pub(crate) indices: Vec<u32>,
    /// Whether its winding was reversed at load (a mirroring node transform at t = 0).
    pub(crate) mirrored: bool,
    pub(crate) skin: Option<Skinning>,
}

/// What skins a primitive: its node's skin and the primitive's weights.
#[derive(Clone, Debug)]
pub(crate) struct Skinning {
    pub(crate) skin: Skin,
    pub(crate) weights: SkinWeights,
}

/// A glTF skin: its joints (node indices) and their inverse bind matrices.
#[derive(Clone, Debug)]
pub(crate) struct Skin {
    pub(crate) joints: Vec<usize>,
    pub(crate) inverse_bind: Vec<Mat4>,
}

impl Skin {
    /// Each joint's matrix for the node world matrices `world`: world(joint) × inverseBind(joint).
    pub(crate) fn joint_matrices(&self, world: &[Mat4]) -> Vec<Mat4> {
        self.joints.iter().zip(&self.inverse_bind).map(|(&j, ibm)| world[j] * *ibm).collect()
    }
}

impl GeometryAnimation {
    /// Time of the last keyframe of the animation, seconds: poses after it hold the last one.
    pub fn duration(&self) -> f32 {
        self.duration
    }

    /// The world matrix of every node at time `t` (the identity for a node outside the scene).
    pub fn world_matrices(&self, t: f32) -> Vec<Mat4> {
        let mut world = vec![Mat4::IDENTITY; self.nodes.len()];
        for &(i, parent) in &self.order {
            world[i] = parent.map_or(Mat4::IDENTITY, |p| world[p]) * self.nodes[i].local(t);
        }
        world
    }

    /// Writes the posed positions and normals of every moving primitive at time `t` into the
    /// scene's arrays. A pose with a coordinate that is not finite or beyond ±[`MAX_COORDINATE`]
    /// is refused (the BVH builder would panic on it), naming the vertex and the time.
    pub(crate) fn pose(&self, t: f32, positions: &mut [Vec3], normals: &mut [Vec3]) -> Result<(), SceneError> {
        let world = self.world_matrices(t);
        for prim in &self.primitives {
            let mut p = prim.positions.clone();
            let mut n = prim.normals.clone();
            let skinning = prim.skin.as_ref().map(|s| s.weights.matrices(&s.skin.joint_matrices(&world)));
            pose(&mut p, n.as_deref_mut(), skinning.as_deref(), world[prim.node]);
            if let Some((k, v)) =
                p.iter().enumerate().find(|(_, v)| !v.is_finite() || v.abs().max_element() > MAX_COORDINATE)
            {
                return Err(SceneError::CoordinateOutOfRange {
                    path: self.path.clone(),
                    what: format!(
                        "vertex {k} of mesh {} primitive {}, posed by the animation at t = {t} s",
                        prim.mesh, prim.primitive
                    ),
                    value: v.abs().max_element(),
                    limit: MAX_COORDINATE,
                });
            }
            let (p, n) = lay_out(&prim.indices, p, n, prim.mirrored);
            let range = prim.first_vertex..prim.first_vertex + p.len();
            positions[range.clone()].copy_from_slice(&p);
            normals[range].copy_from_slice(&n);
        }
        Ok(())
    }
}
