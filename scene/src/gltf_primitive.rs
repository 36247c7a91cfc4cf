//! One glTF triangle primitive, in the steps [`crate::gltf_import`] takes it through: read and
//! check its vertex attributes and skin weights, pose it (skinning or the node's transform), and
//! lay out its triangles, generating flat normals when it has none. Posing and the
//! layout of its vertices are also what [`crate::posing`] repeats for each time of an animation.

use std::path::Path;

use glam::{Mat3, Mat4, Vec2, Vec3};

use crate::error::SceneError;

/// Which primitive of which file: what its errors name.
pub(crate) struct PrimitiveAt<'a> {
    pub(crate) path: &'a Path,
    pub(crate) mesh: usize,
    pub(crate) primitive: usize,
}

impl PrimitiveAt<'_> {
    /// The primitive's data is malformed in the way `what` says.
    pub(crate) fn bad(&self, what: String) -> SceneError {
        SceneError::BadPrimitive { path: self.path.to_path_buf(), mesh: self.mesh, primitive: self.primitive, what }
    }
}

/// A primitive's vertex attributes, every one of `positions.len()` entries.
pub(crate) struct Vertices {
    pub(crate) positions: Vec<Vec3>,
    pub(crate) normals: Option<Vec<Vec3>>,
    pub(crate) uvs: Vec<Vec2>,
    /// Three per triangle, each below the vertex count.
    pub(crate) indices: Vec<u32>,
}

/// Reads the primitive's positions, normals, first texture coordinates and indices (a
/// non-indexed primitive gets `0..n`, one without UVs gets zeros) and checks that they agree.
pub(crate) fn read_vertices(
    prim: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    at: &PrimitiveAt<'_>,
) -> Result<Vertices, SceneError> {
    let bad = |what| at.bad(what);
    let reader = prim.reader(|b| Some(&buffers[b.index()].0[..]));
    let positions: Vec<Vec3> =
        reader.read_positions().ok_or_else(|| bad("no POSITION attribute".into()))?.map(Vec3::from).collect();
    let vertex_count = positions.len();
    let normals: Option<Vec<Vec3>> = reader.read_normals().map(|n| n.map(Vec3::from).collect());
    let uvs: Vec<Vec2> = match reader.read_tex_coords(0) {
        Some(t) => t.into_f32().map(Vec2::from).collect(),
        None => vec![Vec2::ZERO; vertex_count],
    };
    let indices: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..vertex_count as u32).collect(),
    };
    if indices.len() % 3 != 0 {
        return Err(bad(format!("{} indices, not a multiple of 3", indices.len())));
    }
    if let Some(&index) = indices.iter().find(|&&i| i as usize >= vertex_count) {
        return Err(SceneError::IndexOutOfRange {
            path: at.path.to_path_buf(),
            mesh: at.mesh,
            primitive: at.primitive,
            index,
            vertex_count,
        });
    }
    if normals.as_ref().is_some_and(|n| n.len() != vertex_count) || uvs.len() != vertex_count {
        return Err(bad("attribute counts differ from the POSITION count".into()));
    }
    Ok(Vertices { positions, normals, uvs, indices })
}

/// A primitive's JOINTS_0 and WEIGHTS_0: per vertex, four joints of its node's skin and their
/// weights. Every joint index is within the skin (checked on reading).
#[derive(Clone, Debug)]
pub(crate) struct SkinWeights {
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
}

/// The primitive's skin weights, when the node has a skin of `joint_count` joints and the
/// primitive JOINTS_0 and WEIGHTS_0.
pub(crate) fn read_skin_weights(
    prim: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    joint_count: Option<usize>,
    vertex_count: usize,
    at: &PrimitiveAt<'_>,
) -> Result<Option<SkinWeights>, SceneError> {
    let bad = |what| at.bad(what);
    let reader = prim.reader(|b| Some(&buffers[b.index()].0[..]));
    let (Some(joint_count), Some(j), Some(w)) = (joint_count, reader.read_joints(0), reader.read_weights(0)) else {
        return Ok(None);
    };
    let joints: Vec<[u16; 4]> = j.into_u16().collect();
    let weights: Vec<[f32; 4]> = w.into_f32().collect();
    if joints.len() != vertex_count || weights.len() != vertex_count {
        return Err(bad("JOINTS_0/WEIGHTS_0 counts differ from POSITION".into()));
    }
    if let Some(&j) = joints.iter().flatten().find(|&&j| usize::from(j) >= joint_count) {
        return Err(bad(format!("joint index {j} out of range ({joint_count} joints)")));
    }
    Ok(Some(SkinWeights { joints, weights }))
}

impl SkinWeights {
    /// Each vertex's skinning matrix: the matrices of its joints (`joint_matrices`, the skin's
    /// joint world matrices times their inverse bind matrices) blended by its weights.
    pub(crate) fn matrices(&self, joint_matrices: &[Mat4]) -> Vec<Mat4> {
        self.joints
            .iter()
            .zip(&self.weights)
            .map(|(j, w)| (0..4).fold(Mat4::ZERO, |m, k| m + joint_matrices[usize::from(j[k])] * w[k]))
            .collect()
    }
}

/// Moves positions and normals to world space: by each vertex's skinning matrix for a skinned
/// mesh (whose node transform the glTF spec says to ignore), else by the node's `world`.
pub(crate) fn pose(positions: &mut [Vec3], normals: Option<&mut [Vec3]>, skinning: Option<&[Mat4]>, world: Mat4) {
    let normal_matrix = |m: Mat4| Mat3::from_mat4(m).inverse().transpose();
    match skinning {
        Some(ms) => {
            for (k, p) in positions.iter_mut().enumerate() {
                *p = ms[k].transform_point3(*p);
            }
            if let Some(ns) = normals {
                for (k, n) in ns.iter_mut().enumerate() {
                    *n = (normal_matrix(ms[k]) * *n).normalize_or_zero();
                }
            }
        }
        None => {
            for p in positions.iter_mut() {
                *p = world.transform_point3(*p);
            }
            if let Some(ns) = normals {
                let nm = normal_matrix(world);
                for n in ns.iter_mut() {
                    *n = (nm * *n).normalize_or_zero();
                }
            }
        }
    }
}

/// The corners of each triangle, in the order that keeps counter-clockwise front-facing: a
/// `mirrored` primitive's winding is reversed.
pub(crate) fn corners(indices: &[u32], mirrored: bool) -> impl Iterator<Item = [usize; 3]> + '_ {
    let order = if mirrored { [0, 2, 1] } else { [0, 1, 2] };
    indices.chunks_exact(3).map(move |t| order.map(|k| t[k] as usize))
}

/// A primitive's posed positions and normals as the scene holds them: with the file's normals,
/// one scene vertex per file vertex; without, one per triangle corner with the triangle's face
/// normal (flat shading, recomputed for every pose).
pub(crate) fn lay_out(
    indices: &[u32],
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    mirrored: bool,
) -> (Vec<Vec3>, Vec<Vec3>) {
    if let Some(normals) = normals {
        return (positions, normals);
    }
    let mut laid = Vec::with_capacity(indices.len());
    let mut flat = Vec::with_capacity(indices.len());
    for c in corners(indices, mirrored) {
        let [a, b, d] = c.map(|i| positions[i]);
        let n = (b - a).cross(d - a).normalize_or_zero();
        laid.extend([a, b, d]);
        flat.extend([n; 3]);
    }
    (laid, flat)
}
